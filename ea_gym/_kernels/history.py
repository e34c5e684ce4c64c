"""What the chain's history keeps of one step of the monitor (``ea_gym.phm.history.MonitorHistory.record``):
the step's sums, in one compiled loop, each as numpy forms it (``summation``), so to the bit.
"""

from __future__ import annotations

import numba
import numpy as np

from ea_gym._kernels.summation import numpy_sum, summation_scratch


@numba.njit(cache=True)
def step_sums(
    gram: np.ndarray, cross: np.ndarray, balance: np.ndarray, ea_reference: np.ndarray, dissipators: np.ndarray,
    gram_sum: np.ndarray, cross_sum: np.ndarray, balance_sum: np.ndarray, balance_square: np.ndarray, dissipated: np.ndarray,
) -> None:
    """One step's sums of N systems, each into the first entry of its output's last axis (length 1).

    Args:
        gram, cross: the balance regression's terms per balance window (N, W, C, C) and (N, W, C): summed
            over the windows, in order (as ``sum(axis=1)``), into gram_sum (N, C, C, 1) and cross_sum (N, C, 1).
        balance: the energy-balance residual per window (N, W): its sum and the sum of its squares into
            balance_sum and balance_square (N, 1).
        ea_reference: the reference EA per element and sub-window (N, E, S); dissipators: the elements
            whose sum over the step, element after element, goes to dissipated (N, 1).
    """
    n, windows, components = gram.shape[0], gram.shape[1], gram.shape[2]
    squares = np.empty(balance.shape[1])
    scratch = summation_scratch()
    for m in range(n):
        for i in range(components):
            for j in range(components):
                total = 0.0
                for w in range(windows):
                    total += gram[m, w, i, j]
                gram_sum[m, i, j, 0] = total
            total = 0.0
            for w in range(windows):
                total += cross[m, w, i]
            cross_sum[m, i, 0] = total
        balance_sum[m, 0] = numpy_sum(balance[m], 0, balance.shape[1], scratch)
        for w in range(balance.shape[1]):
            squares[w] = balance[m, w] * balance[m, w]
        balance_square[m, 0] = numpy_sum(squares, 0, balance.shape[1], scratch)
        total = 0.0
        for d in dissipators:
            total += numpy_sum(ea_reference[m, d], 0, ea_reference.shape[2], scratch)
        dissipated[m, 0] = total
