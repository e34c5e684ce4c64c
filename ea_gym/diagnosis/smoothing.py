"""Savitzky-Golay smoothing and differentiation for many short signals at once.

``scipy.signal.savgol_filter`` with ``mode="interp"`` fits the edge polynomials row by row with a
least-squares solve, which dominates when thousands of short rows are filtered per step. The filter is
linear, so its edge rows are fixed matrices: they are taken once from ``savgol_filter`` itself
applied to the identity, and the interior is a correlation with ``savgol_coeffs``. The result equals
``savgol_filter(..., mode="interp")`` to round-off.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import correlate1d
from scipy.signal import savgol_coeffs, savgol_filter


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
        self._interior = {}
        self._edges = {}
        identity = np.eye(window)
        for deriv in (0, 1):
            # correlate1d takes the coefficients in signal order; savgol_coeffs gives them for convolution
            self._interior[deriv] = savgol_coeffs(window, polyorder, deriv=deriv, delta=sample_period, use="dot")
            self._edges[deriv] = savgol_filter(identity, window, polyorder, deriv=deriv, delta=sample_period, axis=0)

    def __call__(self, x: np.ndarray, deriv: int = 0) -> np.ndarray:
        if x.shape[-1] < self.window:
            raise ValueError(f"signals of {x.shape[-1]} samples are shorter than the filter ({self.window})")
        out = correlate1d(x, self._interior[deriv], axis=-1, mode="constant")
        edges = self._edges[deriv]
        out[..., : self.half] = x[..., : self.window] @ edges[: self.half].T
        out[..., -self.half :] = x[..., -self.window :] @ edges[-self.half :].T
        return out
