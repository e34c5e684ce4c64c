"""The benchmark's progress lines and the wall time of each stage."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


class Stopwatch:
    """Times labelled stages (``timings``, s, in the order run) and prints one line per stage when ``progress``."""

    def __init__(self, progress: bool):
        self.progress = progress
        self.timings: dict[str, float] = {}

    def say(self, text: str) -> None:
        if self.progress:
            print(text, flush=True)

    def timed(self, label: str, fn: Callable[[], T]) -> T:
        """``fn()``, its wall time recorded under ``label``."""
        t = time.perf_counter()
        value = fn()
        self.timings[label] = time.perf_counter() - t
        self.say(f"  {label}: {self.timings[label]:.1f} s")
        return value


__all__ = ["Stopwatch"]
