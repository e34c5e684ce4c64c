"""The Energy Activity trapezoid (paper eq 4/7): EA = int |P| dt by the trapezoidal rule over the samples.

Every EA in ea_gym is made of ``trapezoid_area``: the batch and streaming EA of ``ea_gym.energy`` from
``interval_activities``, the estimator's window sums from ``trapezoid_activity``, and the monitor's
sub-window sums from ``trapezoid_area`` itself, in the loop that also sums the signed energy.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, inline="always")
def trapezoid_area(p0: float, p1: float, h: float) -> float:
    """|P| integrated over one sample interval of ``h`` s between powers p0 and p1 (W): J."""
    return 0.5 * (abs(p0) + abs(p1)) * h


@numba.njit(cache=True, inline="always")
def trapezoid_activity(power: np.ndarray, start: int, stop: int, h: float) -> float:
    """EA (J) of ``power`` (T,) in W over the sample intervals [start, stop), summed in time order."""
    activity = 0.0
    for t in range(start, stop):
        activity += trapezoid_area(power[t], power[t + 1], h)
    return activity


@numba.njit(cache=True)
def interval_activities(power: np.ndarray, h: float) -> np.ndarray:
    """EA (J) of every sample interval of every row of ``power`` (M, T) in W: (M, T - 1)."""
    rows, samples = power.shape
    out = np.empty((rows, max(samples - 1, 0)))
    for m in range(rows):
        for t in range(samples - 1):
            out[m, t] = trapezoid_area(power[m, t], power[m, t + 1], h)
    return out
