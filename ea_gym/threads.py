"""Threads: one BLAS thread for the many small matrix products, and the compiled kernels' rows split over
the cores.

Batches of tiny matrices (2x2 to 10x10) run slower on several BLAS threads than on one, and far slower
when another process holds a core (threads wait on each other). The hot paths run under
``single_threaded_blas()``; torch keeps its own threads.

The batched environment's kernels work system by system, so a batch's rows split into contiguous parts
that run at once on ``kernel_threads()`` threads (``over_rows``): each system's arithmetic is the same
whichever part holds it, so the results are the same bits on any number of threads. The kernels release
the GIL (``nogil``); the waiting threads block on a queue, they do not spin.
"""

from __future__ import annotations

import ctypes
import itertools
import os
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import AbstractContextManager, contextmanager
from functools import cache
from typing import NamedTuple

import scipy.linalg  # noqa: F401 - loads scipy's BLAS so that the controller sees it
from threadpoolctl import ThreadpoolController

#: how OpenBLAS names its C functions in the builds numpy's and scipy's wheels ship (prefix, suffix)
_OPENBLAS_AFFIXES = tuple(itertools.product(("", "scipy_"), ("", "64_", "_64")))


class _ThreadCount(NamedTuple):
    """A BLAS library's thread count: read, and set."""

    get: Callable[[], int]
    set: Callable[[int], object]


@cache
def _blas_thread_counts() -> tuple[_ThreadCount, ...]:
    """The thread count of each BLAS library loaded (numpy's and scipy's), found once: an OpenBLAS with its own
    thread pool through its C functions (about 0.1 us a call; threadpoolctl's wrappers take several times that,
    more again between the step's other work), any other library through threadpoolctl."""
    counts = []
    for library in ThreadpoolController().select(user_api="blas").lib_controllers:
        own = _openblas_thread_count(library.dynlib) if library.internal_api == "openblas" and library.threading_layer == "pthreads" else None
        counts.append(own or _ThreadCount(library.get_num_threads, library.set_num_threads))
    return tuple(counts)


def _openblas_thread_count(dynlib: ctypes.CDLL) -> _ThreadCount | None:
    """OpenBLAS's own C functions for its thread count, under the names of the library's build (None: none found)."""
    for prefix, suffix in _OPENBLAS_AFFIXES:
        get, set_ = (f"{prefix}openblas_{verb}_num_threads{suffix}" for verb in ("get", "set"))
        if hasattr(dynlib, get) and hasattr(dynlib, set_):
            return _ThreadCount(dynlib[get], dynlib[set_])  # fresh function objects: threadpoolctl's stay as they are
    return None


class _OneBlasThread:
    """The context of ``single_threaded_blas``: its outermost entry on a thread sets each BLAS library that
    runs on more than one thread to one (read afresh at every entry: the user may have changed it), and its
    exit gives those back their count. A class rather than a generator: entered at every environment step."""

    def __init__(self) -> None:
        self.local = threading.local()  # per thread: how deep in the contexts, and what the outermost changed

    def __enter__(self) -> None:
        local = self.local
        depth = getattr(local, "depth", 0)
        if depth == 0:
            changed = [(count, threads) for count in _blas_thread_counts() if (threads := count.get()) != 1]
            for count, _ in changed:
                count.set(1)
            local.changed = changed
        local.depth = depth + 1

    def __exit__(self, *exc_info: object) -> None:
        local = self.local
        local.depth -= 1
        if local.depth == 0:
            for count, threads in local.changed:
                count.set(threads)


_one_blas_thread = _OneBlasThread()


def single_threaded_blas() -> AbstractContextManager[None]:
    """A context in which numpy's and scipy's BLAS use one thread (2 us to enter and leave in a tight loop, 6
    within an environment step, half of them OpenBLAS's own: each library's count is set directly, without
    ``threadpoolctl``'s bookkeeping, and only where it is not one already; nothing to do within another, as
    the simulation's within an environment step)."""
    return _one_blas_thread


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


#: the fewest rows each thread of ``over_rows`` gets: handing rows to a thread costs 30-50 us before they
#: start (waking it, the GIL between the parts' Python), so a batch splits only where each thread gets this
#: many (here, in alarm: N = 64 ran 15 % slower on two threads than on one, N = 128 12 % faster)
MIN_ROWS_PER_THREAD = 64
#: the fewest rows a part gets
MIN_ROWS_PER_PART = 32
#: parts per thread: the threads take the parts in turn until none is left, so that a thread that
#: starts late (woken) or whose systems cost more (in alarm) leaves the rest to the others
PARTS_PER_THREAD = 4


def available_cores() -> int:
    """The cores this process may run on, no more than OMP_NUM_THREADS where set (as Ray sets it to a
    worker's CPUs)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    limit = os.environ.get("OMP_NUM_THREADS", "")
    return max(1, min(cores, int(limit))) if limit.isdigit() and int(limit) > 0 else cores


class _KernelPool:
    """The worker threads of ``over_rows`` (threads - 1 of them: the caller runs a part too), started on first use."""

    def __init__(self) -> None:
        self.threads = available_cores()
        self.executor: ThreadPoolExecutor | None = None
        self.lock = threading.Lock()
        self.worker = threading.local()  # set in the workers: a kernel they run splits no further

    def submit(self, call: Callable[[], None]) -> None:
        """Offer ``call`` to the workers (its outcome is the caller's to collect: ``_Parts`` keeps it)."""
        with self.lock:
            if self.executor is None:
                self.executor = ThreadPoolExecutor(self.threads - 1, "ea-gym-kernel", initializer=self.mark_worker)
            self.executor.submit(call)

    def mark_worker(self) -> None:
        self.worker.active = True

    def resize(self, threads: int) -> None:
        with self.lock:
            if self.executor is not None:
                self.executor.shutdown(wait=True)
            self.executor, self.threads = None, threads

    def forget_workers(self) -> None:
        """In a forked child: the parent's worker threads are not there; new ones start on first use."""
        self.executor, self.lock = None, threading.Lock()


_pool = _KernelPool()
if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_pool.forget_workers)


def kernel_threads() -> int:
    """How many threads ``over_rows`` runs the kernels on (default: ``available_cores()``)."""
    return _pool.threads


def set_kernel_threads(threads: int) -> None:
    """Run the kernels' rows on ``threads`` threads from now on (1: on the calling thread alone), as
    ``torch.set_num_threads`` sets torch's."""
    if not isinstance(threads, int) or isinstance(threads, bool) or threads < 1:
        raise ValueError(f"threads must be a positive integer, got {threads!r}")
    _pool.resize(threads)


class _Parts:
    """The parts of one ``over_rows`` call, taken in turn by whichever kernel thread asks next; done
    when every part is, whether or not every thread it was offered to got to it (a busy worker that
    finds none left returns at once, and nobody waits for it)."""

    def __init__(self, call: Callable[[int, int], None], cuts: list[int]):
        self.call = call
        self.queue = iter(list(zip(cuts[:-1], cuts[1:])))  # a list iterator: each next() is atomic under the GIL
        self.left = len(cuts) - 1
        self.lock = threading.Lock()
        self.done = threading.Event()
        self.errors: list[BaseException] = []

    def take(self) -> None:
        for start, stop in self.queue:
            try:
                self.call(start, stop)
            except BaseException as error:  # raised in the caller's thread, by ``over_rows``
                self.errors.append(error)
            with self.lock:
                self.left -= 1
                if self.left == 0:
                    self.done.set()


def over_rows(call: Callable[[int, int], None], rows: int) -> None:
    """``call(start, stop)`` over rows [0, rows) in contiguous parts of at least ``MIN_ROWS_PER_PART``
    (one part where the threads would get fewer than ``MIN_ROWS_PER_THREAD`` each), which the kernel
    threads (the caller's among them) take in turn until none is left. ``call`` must write only its own
    rows and release the GIL for its work (a ``nogil`` kernel). Returns when every part is done; a
    part's exception is raised here."""
    threads = min(_pool.threads, rows // MIN_ROWS_PER_THREAD)
    if threads <= 1 or getattr(_pool.worker, "active", False):
        call(0, rows)
        return
    parts = min(rows // MIN_ROWS_PER_PART, threads * PARTS_PER_THREAD)
    work = _Parts(call, [rows * part // parts for part in range(parts + 1)])
    for _ in range(threads - 1):
        _pool.submit(work.take)
    work.take()
    work.done.wait()
    if work.errors:
        raise work.errors[0]
