"""The wear of N systems' faulty components over a step, and their true RUL (``ea_gym.degradation.Wear``), in
compiled loops: the arithmetic of its numpy form, element by element in the same order, so to the bit.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.wear``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ea_gym._kernels.numpy_forms import numpy_maximum


@numba.njit(cache=True)
def steady_wear(
    values: np.ndarray, columns: np.ndarray, running: np.ndarray, faulty: np.ndarray, arrival: np.ndarray, velocity: np.ndarray,
    clock: np.ndarray, dt: float, linear: np.ndarray, active: np.ndarray,
) -> np.ndarray:
    """Each system's seconds of wear in [clock, clock + dt] (after its fault's ``arrival``) into ``active``
    (N,); the mean drift velocity x active added to its faulty component's value (in place, component d in
    column ``columns[d]`` of ``values`` (N, ...)) where the system is ``running`` and the wear is linear or the
    mean is 0. Returns the systems whose increment is random instead, in order (left to the caller, which
    draws it from the system's generator)."""
    drawn = np.empty(values.shape[0], dtype=np.intp)
    count = 0
    for m in range(values.shape[0]):
        start = numpy_maximum(arrival[m], clock[m])
        seconds = clock[m] + dt - start
        seconds = seconds if (seconds > 0.0 or math.isnan(seconds)) else 0.0  # np.clip(., 0, dt), NaN kept
        seconds = seconds if (seconds < dt or math.isnan(seconds)) else dt
        active[m] = seconds
        if seconds > 0:
            mean = velocity[m] * seconds
            if not linear[faulty[m]] and mean != 0:
                drawn[count] = m
                count += 1
            elif running[m]:
                values[m, columns[faulty[m]]] += mean
    return drawn[:count]


@numba.njit(cache=True, error_model="numpy")
def mean_trend_rul(
    values: np.ndarray, columns: np.ndarray, faulty: np.ndarray, limits: np.ndarray, velocity: np.ndarray, arrival: np.ndarray,
    clock: np.ndarray, out: np.ndarray,
) -> None:
    """Seconds (N,) until each faulty component's mean trend reaches the limit it heads for, 0 past it,
    inf before its fault arrives or without drift; component d in column ``columns[d]`` of ``values`` (N, ...),
    ``limits`` (D, 2)."""
    for m in range(values.shape[0]):
        d = faulty[m]
        limit = limits[d, 1] if velocity[m] > 0 else limits[d, 0]
        rul = (limit - values[m, columns[d]]) / velocity[m] if velocity[m] != 0 else math.inf
        rul = numpy_maximum(rul, 0.0)
        out[m] = rul if clock[m] >= arrival[m] else math.inf
