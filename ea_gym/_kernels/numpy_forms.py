"""numpy's arithmetic, scalar by scalar, for compiled kernels that must give numpy's results to the bit:
``np.minimum`` and ``np.maximum`` (NaN propagated, the first argument where they compare equal). The sum
over a contiguous axis is ``ea_gym._kernels.summation.numpy_sum``; reductions along any other axis add in
order from 0.0, which a plain loop does.
"""

from __future__ import annotations

import math

import numba


@numba.njit(cache=True, inline="always")
def numpy_minimum(a: float, b: float) -> float:
    """``np.minimum(a, b)``: NaN if either is, otherwise the smaller (a where they compare equal)."""
    return a if (a <= b or math.isnan(a)) else b


@numba.njit(cache=True, inline="always")
def numpy_maximum(a: float, b: float) -> float:
    """``np.maximum(a, b)``: NaN if either is, otherwise the larger (a where they compare equal)."""
    return a if (a >= b or math.isnan(a)) else b
