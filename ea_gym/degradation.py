"""Fault profiles and degradation processes."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


class ProfileError(ValueError):
    """An invalid profile point; ``index`` is the culprit point's index (None for the whole profile)."""

    def __init__(self, index: int | None, reason: str) -> None:
        where = "profile" if index is None else f"profile point {index}"
        super().__init__(f"{where}: {reason}")
        self.index = index
        self.reason = reason

    def __reduce__(self):  # keep the two-argument constructor picklable (multiprocessing)
        return (type(self), (self.index, self.reason))


@dataclass(frozen=True)
class PiecewiseLinearProfile:
    """A parameter's value over time: piecewise linear between the points (``times`` in s,
    ``values`` in the parameter's SI unit), held constant before the first and after the last.

    ``times`` must be finite, >= 0 and strictly increasing; ``values`` finite and as many.
    """

    times: tuple[float, ...]
    values: tuple[float, ...]

    def __post_init__(self) -> None:
        times = tuple(float(t) for t in self.times)
        values = tuple(float(v) for v in self.values)
        if not times:
            raise ProfileError(None, "needs at least one point")
        if len(times) != len(values):
            raise ProfileError(None, f"{len(times)} times but {len(values)} values")
        for i, (t, v) in enumerate(zip(times, values)):
            if not math.isfinite(t):
                raise ProfileError(i, f"time {t!r} s is not finite")
            if t < 0:
                raise ProfileError(i, f"time {t!r} s is negative; times must be >= 0")
            if i > 0 and not t > times[i - 1]:
                raise ProfileError(
                    i,
                    f"time {t!r} s is not above the previous time {times[i - 1]!r} s; "
                    "times must be strictly increasing",
                )
            if not math.isfinite(v):
                raise ProfileError(i, f"value {v!r} is not finite")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "values", values)

    def value(self, t: np.ndarray) -> np.ndarray:
        """The profile at times t (s), elementwise over any shape of t."""
        return np.interp(np.asarray(t, dtype=float), self.times, self.values)
