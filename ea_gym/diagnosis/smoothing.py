"""Savitzky-Golay smoothing and differentiation for many short signals at once.

``scipy.signal.savgol_filter`` with ``mode="interp"`` fits the edge polynomials row by row with a
least-squares solve, which dominates when thousands of short rows are filtered per step. The filter is
linear, so its edge rows are fixed matrices: they are taken once from ``savgol_filter`` itself
applied to the identity, and the interior is a correlation with ``savgol_coeffs``. A compiled loop
applies both row by row. The result equals ``savgol_filter(..., mode="interp")`` to round-off.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.signal import savgol_coeffs, savgol_filter


# reassociation lets each dot product run as SIMD partial sums (2x faster); the order of the sums
# still depends only on the window, so every row gives the same result in any batch
@numba.njit(cache=True, fastmath={"reassoc", "contract"})
def filter_into(xr: np.ndarray, yr: np.ndarray, interior: np.ndarray, head: np.ndarray, tail: np.ndarray) -> None:
    """The filter on one signal xr (L,), written to yr (L,).

    Args:
        interior: correlation coefficients (window,) for the outputs at least ``half`` samples from an end.
        head, tail: (half, window) maps from the first (last) ``window`` samples to the first (last) ``half`` outputs.
    """
    length = len(xr)
    half, window = head.shape
    x_tail = xr[length - window :]
    for i in range(half):
        first = 0.0
        last = 0.0
        for j in range(window):
            first += head[i, j] * xr[j]
            last += tail[i, j] * x_tail[j]
        yr[i] = first
        yr[length - half + i] = last
    for i in range(length - 2 * half):
        acc = 0.0
        for j in range(window):
            acc += interior[j] * xr[i + j]
        yr[half + i] = acc


@numba.njit(cache=True)
def _filter_rows(x: np.ndarray, interior: np.ndarray, head: np.ndarray, tail: np.ndarray) -> np.ndarray:
    """The filter on every row of x (rows, L); coefficients as in ``filter_into``."""
    out = np.empty_like(x)
    for r in range(x.shape[0]):
        filter_into(x[r], out[r], interior, head, tail)
    return out


class SavitzkyGolay:
    """Smooths (``deriv=0``) or differentiates (``deriv=1``) along the last axis.

    Args:
        window: filter length (samples, odd).
        polyorder: polynomial order.
        sample_period: seconds between samples (scales the derivative).
    """

    def __init__(self, window: int, polyorder: int, sample_period: float):
        if window % 2 == 0 or window <= polyorder:
            raise ValueError(f"window must be odd and above polyorder, got window={window}, polyorder={polyorder}")
        self.window = window
        self.half = window // 2
        self._coefficients = {}
        identity = np.eye(window)
        for deriv in (0, 1):
            # use="dot" gives the coefficients in signal order, as the correlation takes them
            interior = savgol_coeffs(window, polyorder, deriv=deriv, delta=sample_period, use="dot")
            edges = savgol_filter(identity, window, polyorder, deriv=deriv, delta=sample_period, axis=0)
            head, tail = np.ascontiguousarray(edges[: self.half]), np.ascontiguousarray(edges[-self.half :])
            self._coefficients[deriv] = (interior, head, tail)

    def coefficients(self, deriv: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(interior, head, tail) of ``filter_into`` for the smoother (0) or the derivative (1)."""
        return self._coefficients[deriv]

    def __call__(self, x: np.ndarray, deriv: int = 0) -> np.ndarray:
        if x.shape[-1] < self.window:
            raise ValueError(f"signals of {x.shape[-1]} samples are shorter than the filter ({self.window})")
        rows = np.ascontiguousarray(x, dtype=float).reshape(-1, x.shape[-1])
        return _filter_rows(rows, *self._coefficients[deriv]).reshape(x.shape)
