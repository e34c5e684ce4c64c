"""The Energy Activity trapezoid (paper eq 4/7): EA = int |P| dt by the trapezoidal rule over the samples.

Every EA in ea_gym is made of ``trapezoid_area``: the batch and streaming EA of ``ea_gym.energy`` from
``interval_activities``, the estimator's window sums from ``trapezoid_activity``, and the monitor's
sub-window sums from ``trapezoid_area`` itself, in the loop that also sums the signed energy. The
Energy Activity Index (eq 5) of components, their shares of their summed EA: ``component_shares``; of
a step's sub-window EAs summed first: ``summed_shares``.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.activity``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ea_gym._kernels.summation import numpy_sum, summation_scratch


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


@numba.njit(cache=True)
def component_shares(ea: np.ndarray, columns: np.ndarray, out: np.ndarray) -> int:
    """EAI of every row of ``ea`` (rows, E) in J over its components' ``columns`` (C,) into ``out`` (rows, C):
    each one's EA over their sum (as ``activity_shares`` adds them), 1 / C each where the sum is 0.

    Returns -1, or (nothing written) the first component whose EA is not finite and >= 0 in some row.
    """
    rows, components = ea.shape[0], len(columns)
    for k in range(components):
        for r in range(rows):
            value = ea[r, columns[k]]
            if not (math.isfinite(value) and value >= 0.0):
                return k
    values, scratch = np.empty(components), summation_scratch()
    for r in range(rows):
        for k in range(components):
            values[k] = ea[r, columns[k]]
        # numpy sums a single row's shares pairwise (np.sum's order), several rows' row after row
        total = numpy_sum(values, 0, components, scratch) if rows == 1 else 0.0
        if rows > 1:
            for k in range(components):
                total += values[k]
        for k in range(components):
            out[r, k] = ea[r, columns[k]] / total if total > 0.0 else 1.0 / components
    return -1


@numba.njit(cache=True)
def summed_shares(sub_ea: np.ndarray, sub_ea_reference: np.ndarray, columns: np.ndarray, ea: np.ndarray, out: np.ndarray) -> int:
    """Every element's EA (J) over a step of N systems into ``ea`` (2N, E): the rows of ``sub_ea`` then those of
    ``sub_ea_reference`` (N, E, S) summed over their S sub-windows as ``np.sum(axis=-1)`` adds them; then the
    ``component_shares`` of its rows into ``out`` (2N, C), and what those return."""
    n, elements, subs = sub_ea.shape
    scratch = summation_scratch()
    for i in range(n):
        for j in range(elements):
            ea[i, j] = numpy_sum(sub_ea[i, j], 0, subs, scratch)
            ea[n + i, j] = numpy_sum(sub_ea_reference[i, j], 0, subs, scratch)
    return component_shares(ea, columns, out)
