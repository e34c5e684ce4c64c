"""numpy's arithmetic, scalar by scalar, for compiled kernels that must give numpy's results to the bit:
``np.minimum`` and ``np.maximum`` (NaN propagated, the first argument where they compare equal) and the
sum over a contiguous last axis (``ndarray.sum``: pairwise, eight accumulators in blocks of up to 128,
from 0.0). Reductions along any other axis add in order from 0.0, which a plain loop does.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, inline="always")
def numpy_minimum(a: float, b: float) -> float:
    """``np.minimum(a, b)``: NaN if either is, otherwise the smaller (a where they compare equal)."""
    return a if (a <= b or math.isnan(a)) else b


@numba.njit(cache=True, inline="always")
def numpy_maximum(a: float, b: float) -> float:
    """``np.maximum(a, b)``: NaN if either is, otherwise the larger (a where they compare equal)."""
    return a if (a >= b or math.isnan(a)) else b


#: numpy's pairwise summation: runs longer than this are halved (``PW_BLOCKSIZE``).
PAIRWISE_BLOCK = 128


@numba.njit(cache=True)
def block_sum(a: np.ndarray, start: int, n: int) -> float:
    """numpy's pairwise sum of a[start : start + n] (1-d) for n <= ``PAIRWISE_BLOCK``: under 8 terms in
    order from 0.0; otherwise eight interleaved accumulators, combined as a tree, then the rest in order."""
    if n < 8:
        total = 0.0
        for i in range(n):
            total += a[start + i]
        return total
    r0, r1, r2, r3 = a[start], a[start + 1], a[start + 2], a[start + 3]
    r4, r5, r6, r7 = a[start + 4], a[start + 5], a[start + 6], a[start + 7]
    i = 8
    while i < n - n % 8:
        r0 += a[start + i]
        r1 += a[start + i + 1]
        r2 += a[start + i + 2]
        r3 += a[start + i + 3]
        r4 += a[start + i + 4]
        r5 += a[start + i + 5]
        r6 += a[start + i + 6]
        r7 += a[start + i + 7]
        i += 8
    total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        total += a[start + i]
        i += 1
    return total


@numba.njit(cache=True)
def pairwise_sum(a: np.ndarray, start: int, n: int) -> float:
    """numpy's pairwise sum of a[start : start + n] (1-d): runs longer than ``PAIRWISE_BLOCK`` halved at
    a multiple of 8, left half plus right half, down to ``block_sum``'s blocks. The halving runs on an
    explicit stack (a cached compiled function must not call itself)."""
    if n <= PAIRWISE_BLOCK:
        return block_sum(a, start, n)
    starts, lengths = np.empty(64, np.int64), np.empty(64, np.int64)
    stage, left = np.zeros(64, np.int64), np.empty(64)
    depth, result = 0, 0.0
    starts[0], lengths[0] = start, n
    while depth >= 0:
        first, length = starts[depth], lengths[depth]
        half = length // 2
        half -= half % 8
        if length <= PAIRWISE_BLOCK:
            result = block_sum(a, first, length)
            depth -= 1
        elif stage[depth] == 0:  # the left half first
            stage[depth] = 1
            depth += 1
            starts[depth], lengths[depth], stage[depth] = first, half, 0
        elif stage[depth] == 1:  # the left half's sum is in: the right half
            left[depth] = result
            stage[depth] = 2
            depth += 1
            starts[depth], lengths[depth], stage[depth] = first + half, length - half, 0
        else:
            result = left[depth] + result
            depth -= 1
    return result


@numba.njit(cache=True)
def numpy_sum(a: np.ndarray, start: int, n: int) -> float:
    """``a[start : start + n].sum()`` as numpy forms it (a 1-d, contiguous): 0.0 plus the pairwise sum."""
    return 0.0 + pairwise_sum(a, start, n)
