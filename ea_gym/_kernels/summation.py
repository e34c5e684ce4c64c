"""numpy's float64 sum, compiled: the kernels that must give the same numbers as a numpy form of their
arithmetic add as ``np.sum`` does along a contiguous axis (pairwise, eight accumulators), not in order.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.summation``.
"""

from __future__ import annotations

import numba
import numpy as np

#: numpy's pairwise summation: blocks up to this length are summed with eight accumulators
_BLOCK = 128


@numba.njit(cache=True)
def _block_sum(values: np.ndarray, start: int, count: int) -> float:
    """numpy's sum of a block of up to ``_BLOCK`` values: in order below 8, else eight interleaved accumulators."""
    if count < 8:
        total = -0.0
        for i in range(start, start + count):
            total += values[i]
        return total
    # the block indexed by unsigned offsets: a signed index costs a check for negative (wraparound) indices
    # at every load, which halves the sum's speed
    block = values[start : start + count]
    r0, r1, r2, r3 = block[0], block[1], block[2], block[3]
    r4, r5, r6, r7 = block[4], block[5], block[6], block[7]
    whole = count - count % 8
    for eighth in range(1, whole // 8):
        i = np.uint64(8 * eighth)
        r0 += block[i]
        r1 += block[i + np.uint64(1)]
        r2 += block[i + np.uint64(2)]
        r3 += block[i + np.uint64(3)]
        r4 += block[i + np.uint64(4)]
        r5 += block[i + np.uint64(5)]
        r6 += block[i + np.uint64(6)]
        r7 += block[i + np.uint64(7)]
    total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    for j in range(whole, count):
        total += block[j]
    return total


@numba.njit(cache=True)
def summation_scratch() -> tuple[np.ndarray, np.ndarray]:
    """The working space of :func:`numpy_sum` (pending blocks, partial sums): one for any number of sums."""
    return np.empty((128, 3), dtype=np.int64), np.empty(64)


@numba.njit(cache=True)
def numpy_sum(values: np.ndarray, start: int, stop: int, scratch: tuple[np.ndarray, np.ndarray]) -> float:
    """``np.sum(values[start:stop])`` of a 1-D float64 array, to the bit.

    numpy halves a run longer than ``_BLOCK`` (the first half a multiple of 8) and adds the halves'
    sums, recursively; the recursion is unrolled on ``scratch`` (numba's cache cannot hold a recursive
    function). The total is added to the sum's identity 0, as numpy's reduction does.
    """
    count = stop - start
    if count <= _BLOCK:
        return 0.0 + _block_sum(values, start, count)
    half = count // 2
    half -= half % 8
    if count - half <= _BLOCK:  # one halving into two blocks (the frame's 200 sub-windows): no stack
        return 0.0 + (_block_sum(values, start, half) + _block_sum(values, start + half, count - half))
    tasks, partial = scratch
    # a task is (start, count, 0) to sum a run, or (0, 0, 1) to add the last two partial sums
    tasks[0, 0], tasks[0, 1], tasks[0, 2] = start, count, 0
    pending, done = 1, 0
    while pending:
        pending -= 1
        first, length, add = tasks[pending, 0], tasks[pending, 1], tasks[pending, 2]
        if add:
            done -= 1
            partial[done - 1] += partial[done]
        elif length <= _BLOCK:
            partial[done] = _block_sum(values, first, length)
            done += 1
        else:
            half = length // 2
            half -= half % 8
            # popped in reverse: the first half, the second, then their sum
            tasks[pending, 0], tasks[pending, 1], tasks[pending, 2] = 0, 0, 1
            tasks[pending + 1, 0], tasks[pending + 1, 1], tasks[pending + 1, 2] = first + half, length - half, 0
            tasks[pending + 2, 0], tasks[pending + 2, 1], tasks[pending + 2, 2] = first, half, 0
            pending += 3
    return 0.0 + partial[0]
