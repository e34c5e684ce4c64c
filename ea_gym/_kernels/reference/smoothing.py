"""Savitzky-Golay smoothing and differentiation (``ea_gym._kernels.smoothing``): each output a fixed
linear map of its window, the edges' of the first (last) window. The kernels sum in another order (SIMD
partial sums, running moments), so they meet these forms to a few ulps of the window's magnitude."""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view


def filter_into(xr: np.ndarray, yr: np.ndarray, interior: np.ndarray, head: np.ndarray, tail: np.ndarray) -> None:
    """The filter on one signal xr (L,) into yr: ``interior`` (window,) correlated with the signal at least
    half a window from an end, ``head`` and ``tail`` (half, window) on the first and last window."""
    half, window = head.shape
    yr[:half] = head @ xr[:window]
    yr[len(xr) - half :] = tail @ xr[len(xr) - window :]
    yr[half : len(xr) - half] = sliding_window_view(xr, window) @ interior


def filter_rows(x: np.ndarray, interior: np.ndarray, head: np.ndarray, tail: np.ndarray) -> np.ndarray:
    """``filter_into`` on every row of x (rows, L)."""
    out = np.empty_like(x)
    for row, filtered in zip(x, out, strict=True):
        filter_into(row, filtered, interior, head, tail)
    return out


def filter_lanes(
    x: np.ndarray, first: int, moments: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    smoother: tuple[np.ndarray, np.ndarray, np.ndarray], differentiator: tuple[np.ndarray, np.ndarray, np.ndarray],
    derivative: bool, smooth: np.ndarray, slope: np.ndarray,
) -> None:
    """The smoother (and the derivative where ``derivative``) on the columns of x (L, B), rows ``first`` on:
    each window's polynomial moments ``moments[0]`` (4, window) @ window, then each output the
    coefficients (``smoother``: head (half, 4), tail (half, 4), interior (4,)) times its window's moments."""
    powers = moments[0]
    window = powers.shape[1]
    M = np.einsum("jw,tbw->tjb", powers, sliding_window_view(x, window, axis=0))  # (L - window + 1, 4, B)
    for coefficients, out in ((smoother, smooth), (differentiator, slope)) if derivative else ((smoother, smooth),):
        head, tail, interior = coefficients
        filtered = np.concatenate([head @ M[0], np.einsum("j,tjb->tb", interior, M), tail @ M[-1]])
        out[first:] = filtered[first:]
