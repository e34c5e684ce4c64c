"""The wear processes of N systems' parts over a step, and their mean trends' RUL (``ea_gym.degradation``'s
``Wear`` and ``PartsWear``), in compiled loops: the arithmetic of their numpy form, element by element in the
same order, so to the bit.

A wear process m wears one part, ``parts[m]``, of one system, ``systems[m]``: the single-fault world has one
process per system, the world where every part ages one per system and part.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.wear``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ea_gym._kernels.numpy_forms import numpy_maximum


@numba.njit(cache=True)
def steady_wear(
    values: np.ndarray, systems: np.ndarray, columns: np.ndarray, running: np.ndarray, parts: np.ndarray, arrival: np.ndarray,
    velocity: np.ndarray, clock: np.ndarray, dt: float, linear: np.ndarray, active: np.ndarray,
) -> np.ndarray:
    """Each process's seconds of wear in [clock, clock + dt] of its system (after the process's ``arrival``) into
    ``active`` (M,); the mean drift velocity x active added to its part's value (in place: part d of system i in
    ``values[i, columns[d]]``, ``values`` (N, ...)) where the system is ``running`` and the part's wear is
    ``linear`` or the mean is 0. Returns the processes whose increment is random instead, in order (left to the
    caller, which draws it from the system's generator). ``systems``, ``parts``, ``arrival``, ``velocity`` (M,);
    ``clock``, ``running`` (N,); ``linear`` per part."""
    drawn = np.empty(parts.shape[0], dtype=np.intp)
    count = 0
    for m in range(parts.shape[0]):
        i = systems[m]
        start = numpy_maximum(arrival[m], clock[i])
        seconds = clock[i] + dt - start
        seconds = seconds if (seconds > 0.0 or math.isnan(seconds)) else 0.0  # np.clip(., 0, dt), NaN kept
        seconds = seconds if (seconds < dt or math.isnan(seconds)) else dt
        active[m] = seconds
        if seconds > 0:
            mean = velocity[m] * seconds
            if not linear[parts[m]] and mean != 0:
                drawn[count] = m
                count += 1
            elif running[i]:
                values[i, columns[parts[m]]] += mean
    return drawn[:count]


@numba.njit(cache=True, error_model="numpy")
def mean_trend_rul(
    values: np.ndarray, systems: np.ndarray, columns: np.ndarray, parts: np.ndarray, limits: np.ndarray, velocity: np.ndarray,
    arrival: np.ndarray, clock: np.ndarray, out: np.ndarray,
) -> None:
    """Seconds (M,) until each process's part, moving at ``velocity`` (its mean trend), reaches the limit it
    heads for, 0 past it, inf before the process's ``arrival`` or without drift; part d of system i in
    ``values[i, columns[d]]``, ``limits`` (D, 2), ``clock`` (N,)."""
    for m in range(parts.shape[0]):
        i, d = systems[m], parts[m]
        limit = limits[d, 1] if velocity[m] > 0 else limits[d, 0]
        rul = (limit - values[i, columns[d]]) / velocity[m] if velocity[m] != 0 else math.inf
        rul = numpy_maximum(rul, 0.0)
        out[m] = rul if clock[i] >= arrival[m] else math.inf
