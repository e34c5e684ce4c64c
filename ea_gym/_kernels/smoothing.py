"""Savitzky-Golay filter kernels: the filter row by row (``filter_rows``) and on many signals side by
side from running polynomial moments (``filter_lanes``); ``ea_gym.diagnosis.smoothing.SavitzkyGolay``
makes their coefficients and says why they are exact.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.smoothing``.
"""

from __future__ import annotations

import numba
import numpy as np


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
def filter_rows(x: np.ndarray, interior: np.ndarray, head: np.ndarray, tail: np.ndarray) -> np.ndarray:
    """The filter on every row of x (rows, L); coefficients as in ``filter_into``."""
    out = np.empty_like(x)
    for r in range(x.shape[0]):
        filter_into(x[r], out[r], interior, head, tail)
    return out


MOMENTS = 4  # moments (orders 0 to 3) ``filter_lanes`` carries: it takes polynomial orders up to 3
LANES = 32  # signals ``filter_lanes`` takes side by side, the SIMD axis of its recursion (32: a fifth faster than 16 or 64)


@numba.njit(cache=True, inline="always")
def combine(polynomial: np.ndarray, moments: np.ndarray, y: np.ndarray) -> None:
    """y (B,) = sum_j polynomial[j] moments[j] (B,), the four moments in one loop over the lanes."""
    c0, c1, c2, c3 = polynomial[0], polynomial[1], polynomial[2], polynomial[3]
    for b in range(len(y)):
        y[b] = c0 * moments[0, b] + c1 * moments[1, b] + c2 * moments[2, b] + c3 * moments[3, b]


@numba.njit(cache=True, inline="always")
def direct(M: np.ndarray, x: np.ndarray, powers: np.ndarray) -> None:
    """Moments M (4, B) of the window x (window, B) summed sample by sample, all four in one loop over the lanes."""
    M[:] = 0.0
    for k in range(len(x)):
        p0, p1, p2, p3 = powers[0, k], powers[1, k], powers[2, k], powers[3, k]
        for b in range(M.shape[1]):
            v = x[k, b]
            M[0, b] += p0 * v
            M[1, b] += p1 * v
            M[2, b] += p2 * v
            M[3, b] += p3 * v


@numba.njit(cache=True, inline="always")
def advance(M: np.ndarray, leaving: np.ndarray, entering: np.ndarray, drop: np.ndarray, add: np.ndarray, shift: np.ndarray) -> None:
    """Moments M (4, B) of each lane's window moved one sample on: ``leaving`` (B,) drops out, ``entering`` comes in.

    The window's moments about its old centre, less the leaving and plus the entering sample, are
    re-centred with the binomial weights ``shift``. One loop over the lanes with the four moments
    in registers: the loop-per-moment form spends its time in loop set-up.
    """
    d0, d1, d2, d3 = drop[0], drop[1], drop[2], drop[3]
    a0, a1, a2, a3 = add[0], add[1], add[2], add[3]
    s10, s20, s21, s30, s31, s32 = shift[1, 0], shift[2, 0], shift[2, 1], shift[3, 0], shift[3, 1], shift[3, 2]
    for b in range(M.shape[1]):
        out, new = leaving[b], entering[b]
        n0 = M[0, b] - d0 * out + a0 * new
        n1 = M[1, b] - d1 * out + a1 * new
        n2 = M[2, b] - d2 * out + a2 * new
        n3 = M[3, b] - d3 * out + a3 * new
        M[0, b] = n0
        M[1, b] = s10 * n0 + n1
        M[2, b] = s20 * n0 + s21 * n1 + n2
        M[3, b] = s30 * n0 + s31 * n1 + s32 * n2 + n3


@numba.njit(cache=True, inline="always")
def edges(
    M: np.ndarray, lowest: int, smoother: np.ndarray, differentiator: np.ndarray, derivative: bool, smooth: np.ndarray, slope: np.ndarray
) -> None:
    """Edge outputs i >= ``lowest`` from their window's moments M (4, B), written to row i."""
    for i in range(lowest, len(smoother)):
        combine(smoother[i], M, smooth[i])
        if derivative:
            combine(differentiator[i], M, slope[i])


@numba.njit(cache=True)
def filter_lanes(
    x: np.ndarray, first: int, moments: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    smoother: tuple[np.ndarray, np.ndarray, np.ndarray], differentiator: tuple[np.ndarray, np.ndarray, np.ndarray],
    derivative: bool, smooth: np.ndarray, slope: np.ndarray,
) -> None:
    """The smoother, and the derivative where ``derivative``, on B signals side by side (the SIMD axis).

    Every lane runs the same arithmetic, so a signal's result does not depend on its neighbours.

    Args:
        x: the signals, (L, B).
        first: the first output needed; earlier ones are not computed.
        moments: ``SavitzkyGolay.moments()``.
        smoother, differentiator: ``SavitzkyGolay.lane_coefficients(0)`` and ``(1)``.
        smooth, slope: written from row ``first`` on: the filtered signals, (L, B).
    """
    powers, shift, drop, add = moments
    L, B = x.shape
    window = powers.shape[1]
    half = window // 2
    last = L - 1 - half  # the last interior output; its window's moments also give the tail edge
    M = np.empty((MOMENTS, B))
    start = min(max(first, half), last)
    interior, slope_interior = smoother[2], differentiator[2]
    # blocks of one window: a direct sum, then the recursion (a branch inside the recursion's loop
    # would keep it from vectorising)
    for t0 in range(start, last + 1, window):
        direct(M, x[t0 - half : t0 + half + 1], powers)
        # the edge outputs are polynomial fits to the first (last) window: linear in its moments
        if t0 == half and first < half:
            edges(M, first, smoother[0], differentiator[0], derivative, smooth, slope)
        if t0 >= first:
            combine(interior, M, smooth[t0])
            if derivative:
                combine(slope_interior, M, slope[t0])
        for t in range(t0 + 1, min(t0 + window, last + 1)):
            advance(M, x[t - 1 - half], x[t + half], drop, add, shift)
            combine(interior, M, smooth[t])
            if derivative:
                combine(slope_interior, M, slope[t])
    edges(M, max(first - last - 1, 0), smoother[1], differentiator[1], derivative, smooth[last + 1 :], slope[last + 1 :])
