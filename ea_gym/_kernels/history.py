"""What the chain's history keeps of one step of the monitor (``ea_gym.phm.history.MonitorHistory.record``),
in one compiled call: the step's sums, each as numpy forms it (``summation``), so to the bit, pushed with the
step's EA and noise sums onto the histories' sliding windows.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.history``.
"""

from __future__ import annotations

import numba
import numpy as np

from ea_gym._kernels.summation import numpy_sum, summation_scratch


@numba.njit(cache=True)
def slide(history: np.ndarray, start: int, length: int, k: int) -> int:
    """Where the window of ``length`` entries on the last axis of ``history`` (N, A, 2 length) starts once
    ``k`` new entries follow it: k further on, or, where that passes the end, back at 0 with its last
    length - k entries moved there (they lie past length - k, clear of where they go). The new entries'
    place, its last k, is the caller's to fill."""
    start += k
    if start + length > history.shape[2]:
        for m in range(history.shape[0]):
            for a in range(history.shape[1]):
                row = history[m, a]
                for j in range(length - k):
                    row[j] = row[start + j]
        start = 0
    return start


@numba.njit(cache=True)
def record_step(
    ea: np.ndarray, ea_reference: np.ndarray, gram: np.ndarray, cross: np.ndarray, balance: np.ndarray, noise: np.ndarray,
    dissipators: np.ndarray, step_time: float, time: np.ndarray, steps: np.ndarray,
    histories: tuple[np.ndarray, ...], starts: np.ndarray, lengths: np.ndarray,
) -> None:
    """One step of N systems onto their histories, in place.

    Args:
        ea, ea_reference: the step's EA per element and sub-window (N, E, S), pushed as they are.
        gram, cross: the balance regression's terms per balance window (N, W, C, C) and (N, W, C): summed
            over the windows in order (as ``sum(axis=1)``) and pushed, one entry.
        balance: the energy-balance residual per window (N, W): its sum and the sum of its squares pushed.
        noise: the noise estimate's sums (N, 2, nx), pushed as they are.
        dissipators: the elements whose reference EA summed over the step, element after element, is pushed.
        step_time: added to ``time`` (N,) (s); ``steps`` (N,) counts the step.
        histories: the eight histories' backing arrays (N, A, 2 length), in the order ea, ea_reference, gram
            (A = C x C), cross, balance, balance square, dissipated (A = 1 each), noise (A = 2 nx); starts
            (8,): where their windows start, moved on (``slide``); lengths (8,): the windows' lengths.
    """
    n, subs, components = ea.shape[0], ea.shape[2], cross.shape[2]
    for i in range(len(histories)):
        starts[i] = slide(histories[i], starts[i], lengths[i], subs if i < 2 else 1)
    ea_history, reference_history, gram_history, cross_history, balance_history, square_history, dissipated_history, noise_history = histories
    ends = starts + lengths  # each window's end: the newest entries just before it
    squares = np.empty(balance.shape[1])
    scratch = summation_scratch()
    for m in range(n):
        time[m] += step_time
        steps[m] += 1
        for e in range(ea.shape[1]):
            for s in range(subs):
                ea_history[m, e, ends[0] - subs + s] = ea[m, e, s]
                reference_history[m, e, ends[1] - subs + s] = ea_reference[m, e, s]
        for i in range(components):
            for j in range(components):
                total = 0.0
                for w in range(gram.shape[1]):
                    total += gram[m, w, i, j]
                gram_history[m, i * components + j, ends[2] - 1] = total
            total = 0.0
            for w in range(cross.shape[1]):
                total += cross[m, w, i]
            cross_history[m, i, ends[3] - 1] = total
        balance_history[m, 0, ends[4] - 1] = numpy_sum(balance[m], 0, balance.shape[1], scratch)
        for w in range(balance.shape[1]):
            squares[w] = balance[m, w] * balance[m, w]
        square_history[m, 0, ends[5] - 1] = numpy_sum(squares, 0, balance.shape[1], scratch)
        total = 0.0
        for d in dissipators:
            total += numpy_sum(ea_reference[m, d], 0, subs, scratch)
        dissipated_history[m, 0, ends[6] - 1] = total
        for a in range(noise.shape[1]):
            for c in range(noise.shape[2]):
                noise_history[m, a * noise.shape[2] + c, ends[7] - 1] = noise[m, a, c]
