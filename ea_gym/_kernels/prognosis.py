"""The drift End of Life (``ea_gym.phm.prognosis.drift_end_of_life``) element by element, in one compiled loop.

The arithmetic is that function's numpy expressions, operation for operation and in their order (its
``where``, ``minimum`` and ``maximum`` as the conditionals numpy evaluates), so each result is the
same to the bit: a step's handful of systems costs one call instead of some thirty array operations.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.prognosis``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ea_gym._kernels.numpy_forms import numpy_maximum, numpy_minimum


@numba.njit(cache=True, error_model="numpy", inline="always")
def drift_end(
    value: float, drift: float, v_tt: float, v_td: float, v_dd: float, lower: float, upper: float, t: float, diffusion: float, z2: float,
) -> tuple[float, float, float]:
    """End of Life, its low and high end (s) of one parameter: its ``value`` and ``drift`` (unit/s), their
    covariance's entries v_tt, v_td, v_dd, its safe limits, when the values hold ``t`` (s), theta's random
    walk ``diffusion`` (unit^2/s); z2: the square (Python's z**2) of the confidence's normal quantile z."""
    upward = drift >= 0
    limit = upper if upward else lower
    sign = 1.0 if upward else -1.0
    margin = sign * (limit - value)
    rate = sign * drift
    cross = v_td + 0.5 * diffusion
    tau = 0.0 if margin <= 0 else (margin / rate if rate > 0 else math.inf)
    a = rate * rate - z2 * v_dd
    b = -2.0 * rate * margin - 2.0 * z2 * cross
    c = margin * margin - z2 * v_tt
    root = math.sqrt(numpy_maximum(b * b - 4.0 * a * c, 0.0))
    linear = -c / b
    r1, r2 = (-b - root) / (2.0 * a), (-b + root) / (2.0 * a)
    small, large = numpy_minimum(r1, r2), numpy_maximum(r1, r2)
    low = small if a > 0 else (large if a < 0 else linear)
    low = 0.0 if c <= 0 else numpy_maximum(low, 0.0)
    high = numpy_maximum(large, 0.0) if a > 0 else math.inf
    if margin < 0 and c > 0:
        high = 0.0
    return t + tau, t + low, t + high


@numba.njit(cache=True, error_model="numpy")
def drift_ends(
    value: np.ndarray, drift: np.ndarray, v_tt: np.ndarray, v_td: np.ndarray, v_dd: np.ndarray, lower: np.ndarray,
    upper: np.ndarray, t: np.ndarray, diffusion: np.ndarray, z2: float, out: np.ndarray,
) -> None:
    """``drift_end`` of every element of the 1-d inputs into ``out`` (M, 3)."""
    for m in range(value.shape[0]):
        out[m, 0], out[m, 1], out[m, 2] = drift_end(value[m], drift[m], v_tt[m], v_td[m], v_dd[m], lower[m], upper[m], t[m], diffusion[m], z2)


@numba.njit(cache=True, error_model="numpy")
def drift_prognosis(
    value: np.ndarray, drift: np.ndarray, variance: np.ndarray, covariance: np.ndarray, drift_variance: np.ndarray, stamps: np.ndarray,
    isolated: np.ndarray, confident: np.ndarray, lower: np.ndarray, upper: np.ndarray, diffusion: np.ndarray, t: np.ndarray, z2: float,
    horizon: float, out: np.ndarray,
) -> None:
    """``DriftPrognosis.update`` of N systems: for every ``confident`` one, its suspect d = isolated - 1's
    ``drift_end`` (from the estimator's (N, D) value, drift, variance, covariance, drift_variance, at its
    ``stamps``; safe limits, diffusion per parameter (D,)), each end more than ``horizon`` s after ``t``
    (N,) inf. Into out (7, N): the suspect's estimate, the End of Life, its low and high end, the
    suspect's drift and its variance, NaN (the ends inf) where not confident; then ``t``."""
    for m in range(value.shape[0]):
        out[6, m] = t[m]
        if not confident[m]:
            out[0, m], out[4, m], out[5, m] = math.nan, math.nan, math.nan
            out[1, m], out[2, m], out[3, m] = math.inf, math.inf, math.inf
            continue
        d = isolated[m] - 1
        end = drift_end(
            value[m, d], drift[m, d], variance[m, d], covariance[m, d], drift_variance[m, d], lower[d], upper[d], stamps[m, d], diffusion[d], z2
        )
        for k in range(3):
            out[1 + k, m] = math.inf if end[k] - t[m] > horizon else end[k]
        out[0, m], out[4, m], out[5, m] = value[m, d], drift[m, d], drift_variance[m, d]
