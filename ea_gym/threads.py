"""BLAS threading for the many small matrix products of the simulation.

Batches of tiny matrices (2x2 to 10x10) run slower on several BLAS threads than on one, and far slower
when another process holds a core (threads wait on each other). The hot paths run under
``single_threaded_blas()``; torch keeps its own threads.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from functools import cache

import scipy.linalg  # noqa: F401 - loads scipy's BLAS so that the controller sees it
from threadpoolctl import LibController, ThreadpoolController


@cache
def _blas_controllers() -> tuple[LibController, ...]:
    """The BLAS libraries loaded (numpy's and scipy's), found once."""
    return tuple(ThreadpoolController().select(user_api="blas").lib_controllers)


#: how deep each thread is in ``single_threaded_blas`` contexts
_blas_depth = threading.local()


@contextmanager
def single_threaded_blas() -> Iterator[None]:
    """A context in which numpy's and scipy's BLAS use one thread (a few us to enter: each library's
    count is set directly, as ``threadpoolctl``'s limit sets it, without its bookkeeping; nothing to
    enter within another, as the simulation's within an environment step)."""
    depth = getattr(_blas_depth, "value", 0)
    _blas_depth.value = depth + 1
    try:
        if depth:
            yield
        else:
            libraries = _blas_controllers()
            previous = [library.num_threads for library in libraries]
            for library in libraries:
                library.set_num_threads(1)
            try:
                yield
            finally:
                for library, threads in zip(libraries, previous):
                    library.set_num_threads(threads)
    finally:
        _blas_depth.value = depth


@contextmanager
def single_threaded_torch() -> Iterator[None]:
    """Run torch on one thread, then restore its setting.

    The isolation network is small: a second torch thread gains nothing and, right after numpy work,
    competes with BLAS threads that are still spinning, which made training ten times slower here.
    """
    import torch

    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(previous)
