"""Detection's per-step statistic and alarm (``ea_gym.phm.detection.Detector.update``) in one compiled loop.

Its sums are numpy's own: ``numpy_sum`` adds a contiguous run as ``ndarray.sum`` over a last axis does
(pairwise, eight accumulators in blocks of up to 128, from 0.0), so the statistic is the numpy form's
to the bit; the alarm's bookkeeping is integer and boolean.
"""

from __future__ import annotations

import math

import numba
import numpy as np

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


@numba.njit(cache=True, inline="always")
def numpy_maximum(a: float, b: float) -> float:
    """``np.maximum(a, b)``: NaN if either is, otherwise the larger (a where they compare equal)."""
    return a if (a >= b or math.isnan(a)) else b


@numba.njit(cache=True)
def detect(
    ea: np.ndarray, ea_reference: np.ndarray, window: int, balance: np.ndarray, dissipated: np.ndarray, steps: np.ndarray, step_samples: int,
    span_samples: np.ndarray, thresholds: np.ndarray, persistence: int, time: np.ndarray, tiny: float,
    above: np.ndarray, alarm: np.ndarray, detection_time: np.ndarray, statistic: np.ndarray,
) -> None:
    """Every system's detection statistic after its newest step, and its alarm (N systems, E elements).

    Args:
        ea, ea_reference: real and reference EA per sub-window (N, E, S), the last ``window`` summed.
        balance, dissipated: the energy-balance residual and the dissipators' EA per step (N, B), all summed.
        steps: updates since each system's reset (N,); step_samples: samples per update; span_samples: the
            samples each statistic needs (E + 1,), before which it is 0.
        thresholds: (E + 1,); persistence: steps in a row above one that raise the alarm; time: now (s), (N,).
        tiny: the denominators' floor.
        above, alarm, detection_time: the detection state (N,), updated in place.
        statistic: (N, E + 1) out: relative EA residual of every element, then the relative balance residual.
    """
    n_elements = ea.shape[1]
    subs = ea.shape[2]
    for m in range(ea.shape[0]):
        seen = steps[m] * step_samples
        for e in range(n_elements + 1):
            if e < n_elements:
                real = numpy_sum(ea[m, e], subs - window, window)
                reference = numpy_sum(ea_reference[m, e], subs - window, window)
                value = (real - reference) / numpy_maximum(reference, tiny)
            else:
                value = numpy_sum(balance[m], 0, balance.shape[1]) / numpy_maximum(numpy_sum(dissipated[m], 0, dissipated.shape[1]), tiny)
            statistic[m, e] = value if seen >= span_samples[e] else 0.0
        exceeded = False
        for e in range(n_elements + 1):
            if abs(statistic[m, e]) > thresholds[e]:
                exceeded = True
        above[m] = above[m] + 1 if exceeded else 0
        if not alarm[m] and above[m] >= persistence:
            alarm[m] = True
            detection_time[m] = time[m]
