"""The drift End of Life (``ea_gym.phm.prognosis.drift_end_of_life``) element by element, in one compiled loop.

The arithmetic is that function's numpy expressions, operation for operation and in their order (its
``where``, ``minimum`` and ``maximum`` as the conditionals numpy evaluates), so each result is the
same to the bit: a step's handful of systems costs one call instead of some thirty array operations.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ea_gym._kernels.numpy_forms import numpy_maximum, numpy_minimum


@numba.njit(cache=True, error_model="numpy")
def drift_ends(
    value: np.ndarray, drift: np.ndarray, v_tt: np.ndarray, v_td: np.ndarray, v_dd: np.ndarray, lower: np.ndarray,
    upper: np.ndarray, t: np.ndarray, diffusion: np.ndarray, z2: float, out: np.ndarray,
) -> None:
    """End of Life, its low and high end (s) of every element of the 1-d inputs into ``out`` (M, 3).

    Args:
        value, drift: the parameter and its drift (unit/s); v_tt, v_td, v_dd: their covariance's
            entries; lower, upper: the safe limits; t: when the values hold (s); diffusion: theta's
            random walk (unit^2/s); z2: the square (Python's z**2) of the confidence's normal quantile z.
    """
    for m in range(value.shape[0]):
        upward = drift[m] >= 0
        limit = upper[m] if upward else lower[m]
        sign = 1.0 if upward else -1.0
        margin = sign * (limit - value[m])
        rate = sign * drift[m]
        cross = v_td[m] + 0.5 * diffusion[m]
        tau = 0.0 if margin <= 0 else (margin / rate if rate > 0 else math.inf)
        a = rate * rate - z2 * v_dd[m]
        b = -2.0 * rate * margin - 2.0 * z2 * cross
        c = margin * margin - z2 * v_tt[m]
        root = math.sqrt(numpy_maximum(b * b - 4.0 * a * c, 0.0))
        linear = -c / b
        r1, r2 = (-b - root) / (2.0 * a), (-b + root) / (2.0 * a)
        small, large = numpy_minimum(r1, r2), numpy_maximum(r1, r2)
        low = small if a > 0 else (large if a < 0 else linear)
        low = 0.0 if c <= 0 else numpy_maximum(low, 0.0)
        high = numpy_maximum(large, 0.0) if a > 0 else math.inf
        if margin < 0 and c > 0:
            high = 0.0
        out[m, 0], out[m, 1], out[m, 2] = t[m] + tau, t[m] + low, t[m] + high
