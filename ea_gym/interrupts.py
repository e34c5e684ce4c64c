"""SIGINT and SIGTERM as exceptions in the main thread, and the short sections they wait for.

Under ``interrupts_raised`` (the ``ea-gym`` command) SIGINT raises KeyboardInterrupt and SIGTERM ``Terminated`` (a
KeyboardInterrupt), so that the cleanup written for Ctrl-C (a staged output removed, a temporary file deleted) runs for
a ``kill`` too. A later signal is ignored: it does not cut the first one's cleanup short. A signal that arrives inside
``interruptions_held`` (a temporary file made but not yet known to its cleanup, outputs being moved into place) is raised
as the section ends.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from types import FrameType

__all__ = ["Terminated", "interrupts_raised", "interruptions_held"]

INTERRUPTS = (signal.SIGINT, signal.SIGTERM)


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread."""


class _Interrupts:
    """What the handler has seen: the first signal (later ones are ignored), whether it still waits for a held section to
    end, and how many held sections are open."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.received: int | None = None
        self.pending = False
        self.holding = 0


_STATE = _Interrupts()


def _exception(number: int) -> KeyboardInterrupt:
    return Terminated() if number == signal.SIGTERM else KeyboardInterrupt()


def _on_signal(number: int, frame: FrameType | None) -> None:
    if _STATE.received is not None:  # the first interruption's cleanup runs to its end
        return
    _STATE.received = number
    if _STATE.holding:
        _STATE.pending = True
        return
    raise _exception(number)


@contextlib.contextmanager
def interrupts_raised() -> Iterator[None]:
    """SIGINT and SIGTERM raised as exceptions in the main thread while inside; the previous handlers come back on
    leaving. Elsewhere than in the main thread (where no handler can be set) nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {number: signal.getsignal(number) for number in INTERRUPTS}
    for number in INTERRUPTS:
        signal.signal(number, _on_signal)
    try:
        yield
    except Exception as error:
        if _STATE.received is None:
            raise
        # the interruption turned into another error on its way out: a C extension being imported (pybind11's init
        # reports any exception as "ImportError: initialization failed") or a library that wraps what it catches
        raise _exception(_STATE.received) from error
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
        _STATE.reset()


@contextlib.contextmanager
def interruptions_held() -> Iterator[None]:
    """An interruption arriving inside waits for the section to end, and is raised there (when it ends without an
    exception of its own)."""
    _STATE.holding += 1
    try:
        yield
    finally:
        _STATE.holding -= 1
    if not _STATE.holding and _STATE.pending:
        _STATE.pending = False
        raise _exception(_STATE.received or signal.SIGINT)
