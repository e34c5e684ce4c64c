"""Savitzky-Golay smoothing and differentiation for many short signals at once.

``scipy.signal.savgol_filter`` with ``mode="interp"`` fits the edge polynomials row by row with a
least-squares solve, which dominates when thousands of short rows are filtered per step. The filter is
linear, so its edge rows are fixed matrices: they are taken once from ``savgol_filter`` itself
applied to the identity, and the interior is a correlation with ``savgol_coeffs`` (both kept in the
cache of :mod:`ea_gym.cache`, so that a later process need not import ``scipy.signal``). A compiled loop
applies both row by row. The result equals ``savgol_filter(..., mode="interp")`` to round-off.

``filter_lanes`` runs many signals side by side and gets the interior from running polynomial
moments instead: the interior coefficients are a polynomial of order p in the tap offset k, so an
output is sum_j a_j M_j(t) with M_j(t) = sum_k (k / half)^j x[t + k], and the M_j move from t to
t + 1 in O(p) (drop one sample, add one, re-centre with binomial weights). A round-off error
carried n steps grows like (n / half)^p, so the recursion restarts from a direct sum every window
length: for window 51 and p <= 3 the outputs stay within 8e-14 x max|x| x sum|c_k| of
``savgol_filter`` (measured; tests/test_smoothing.py asserts 2e-13). Orders above 3 are not taken:
their moments' round-off grows past 1e-10.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import scipy

from ea_gym._kernels.smoothing import MOMENTS, filter_rows
from ea_gym.cache import cache_key, read_arrays_entry, write_arrays_entry

#: the cache's entry kind of the coefficients, and its format
_KIND, _FORMAT = "savgol", 1


def _savgol_coefficients(window: int, polyorder: int, sample_period: float) -> dict[str, np.ndarray]:
    """scipy's filter as matrices, interior{d}, head{d}, tail{d} for the smoother (d = 0) and the derivative (1): read from
    the cache (:mod:`ea_gym.cache`), else computed once (importing scipy.signal takes about a second) and cached."""
    key = cache_key(_KIND, _FORMAT, window=window, polyorder=polyorder, sample_period=sample_period, scipy=scipy.__version__)
    cached = read_arrays_entry(_KIND, key)
    if cached is not None and all(f"{part}{d}" in cached for part in ("interior", "head", "tail") for d in (0, 1)):
        return cached
    from scipy.signal import savgol_coeffs, savgol_filter

    half, identity, coefficients = window // 2, np.eye(window), {}
    for deriv in (0, 1):
        # use="dot" gives the coefficients in signal order, as the correlation takes them
        coefficients[f"interior{deriv}"] = savgol_coeffs(window, polyorder, deriv=deriv, delta=sample_period, use="dot")
        edges = savgol_filter(identity, window, polyorder, deriv=deriv, delta=sample_period, axis=0)
        coefficients[f"head{deriv}"], coefficients[f"tail{deriv}"] = np.ascontiguousarray(edges[:half]), np.ascontiguousarray(edges[window - half :])
    try:
        write_arrays_entry(_KIND, key, coefficients)
    except OSError as error:  # a read-only home: the coefficients are right, only not kept
        warnings.warn(f"could not cache the Savitzky-Golay coefficients: {error}", RuntimeWarning, stacklevel=2)
    return coefficients


class SavitzkyGolay:
    """Smooths (``deriv=0``) or differentiates (``deriv=1``) along the last axis.

    Args:
        window: filter length (samples, odd).
        polyorder: polynomial order.
        sample_period: seconds between samples (scales the derivative).
    """

    def __init__(self, window: int, polyorder: int, sample_period: float) -> None:
        if window % 2 == 0 or window <= polyorder:
            raise ValueError(f"window must be odd and above polyorder, got window={window}, polyorder={polyorder}")
        self.window = window
        self.polyorder = polyorder
        self.half = window // 2
        Coefficients = tuple[np.ndarray, np.ndarray, np.ndarray]
        self._coefficients: dict[int, Coefficients] = {}
        self._polynomial: dict[int, Coefficients] = {}
        # tap offsets scaled to [-1, 1]: the moments of all orders keep the signal's magnitude
        scaled = np.arange(-self.half, self.half + 1) / max(self.half, 1)
        orders = np.arange(MOMENTS)
        powers = scaled[None, :] ** orders[:, None]
        step = 1.0 / max(self.half, 1)
        below = orders[:, None] - orders[None, :]  # binomial re-centring: order i takes the orders j <= i
        self._moments = (
            powers,
            np.array([[math.comb(i, j) for j in orders] for i in orders], dtype=float) * (-step) ** np.maximum(below, 0) * (below >= 0),
            (-1.0) ** orders,
            (1.0 + step) ** orders,
        )
        coefficients = _savgol_coefficients(window, polyorder, sample_period)
        for deriv in (0, 1):
            interior, head, tail = (coefficients[f"{part}{deriv}"] for part in ("interior", "head", "tail"))
            self._coefficients[deriv] = (interior, head, tail)
            # exact up to polyorder 3: the interior coefficients are a polynomial of order polyorder in
            # the offset, and the edge outputs depend on their window through its moments only
            on_head, on_tail, on_interior = (
                np.ascontiguousarray(np.linalg.lstsq(powers.T, rows.T, rcond=None)[0].T) for rows in (head, tail, interior)
            )
            self._polynomial[deriv] = (on_head, on_tail, on_interior)

    def coefficients(self, deriv: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(interior, head, tail) of ``filter_into`` for the smoother (0) or the derivative (1)."""
        return self._coefficients[deriv]

    def moments(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(powers, shift, drop, add) of ``filter_lanes``: the scaled offsets' powers (4, window), the
        binomial re-centring (4, 4), and the weights of the dropped and the added sample (4,)."""
        self._check_lanes()
        return self._moments

    def lane_coefficients(self, deriv: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(head, tail, interior) of ``filter_lanes`` for the smoother (0) or the derivative (1): maps
        from the moments of the first window to the first ``half`` outputs (half, 4), from the
        last window's to the last ``half`` outputs, and from each interior output's window to it (4,)."""
        self._check_lanes()
        return self._polynomial[deriv]

    def _check_lanes(self) -> None:
        if self.polyorder >= MOMENTS:
            raise ValueError(f"filter_lanes takes polynomial orders up to {MOMENTS - 1}, got {self.polyorder}")

    def __call__(self, x: np.ndarray, deriv: int = 0) -> np.ndarray:
        if x.shape[-1] < self.window:
            raise ValueError(f"signals of {x.shape[-1]} samples are shorter than the filter ({self.window})")
        rows = np.ascontiguousarray(x, dtype=float).reshape(-1, x.shape[-1])
        return filter_rows(rows, *self._coefficients[deriv]).reshape(x.shape)
