"""The isolation's compiled steps (``ea_gym.phm.isolation``): the frame's and the balance evidence's sums
read from the history's rows, numpy's pseudo-inverse around its eigendecomposition and matrix product
(which stay numpy's), the classes' chi-squares and log likelihood ratios, the hypotheses to estimate, and
the fusion of the evidence around numpy's log and exp.

Each step repeats the arithmetic of the numpy form it replaces (``np.sum``, ``np.linalg.pinv`` with
``hermitian=True``, ``np.einsum``, the chi-square's element-wise formula) in the same order, so that
the numbers are the same to the bit.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.isolation``.
"""

from __future__ import annotations

import numba
import numpy as np

from ea_gym._kernels.numpy_forms import numpy_maximum, numpy_minimum
from ea_gym._kernels.summation import numpy_sum, summation_scratch
from ea_gym.numerics import TINY


@numba.njit(cache=True)
def history_sums(
    gram: np.ndarray, cross: np.ndarray, other: np.ndarray, rows: np.ndarray, span: int, by_system: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sums over the last ``span`` steps of the history's gram (N, C, C, R) and cross (N, C, R), and over
    every step of another history (N, X, V), for ``rows``: (M, C, C), (M, C), (M, X); by system: at each
    row's own system, (N, C, C), (N, C), (N, X), zeros for the systems not among ``rows``."""
    M, C, R, X = len(rows), gram.shape[1], gram.shape[-1], other.shape[1]
    size = gram.shape[0] if by_system else M
    gram_sum, cross_sum, other_sum = np.zeros((size, C, C)), np.zeros((size, C)), np.zeros((size, X))
    scratch = summation_scratch()
    for k in range(M):
        n = rows[k]
        at = n if by_system else k
        for i in range(C):
            for j in range(C):
                gram_sum[at, i, j] = numpy_sum(gram[n, i, j], R - span, R, scratch)
            cross_sum[at, i] = numpy_sum(cross[n, i], R - span, R, scratch)
        for x in range(X):
            other_sum[at, x] = numpy_sum(other[n, x], 0, other.shape[2], scratch)
    return gram_sum, cross_sum, other_sum


@numba.njit(cache=True)
def pseudo_inverse_factors(values: np.ndarray, vectors: np.ndarray, rcond: float) -> tuple[np.ndarray, np.ndarray, bool]:
    """The two factors whose product is numpy's ``pinv(a, rcond, hermitian=True)``, from ``np.linalg.eigh(a)``
    (values (M, C), vectors (M, C, C)).

    numpy orders the eigenpairs by decreasing |value|, moves the values' signs into the left factor
    (vectors times sign) and scales the right one (vectors transposed) by 1/|value|, or 0 where |value|
    is at most ``rcond`` times the largest. Returns the left factor (M, C, C), the right factor's
    transpose (M, C, C), C-contiguous (``np.matmul(left, right_t.transpose(0, 2, 1))`` is numpy's
    product, with its operands' layout), and whether two |values| of a matrix are equal (then
    numpy's sort decides their order: use numpy's ``pinv``).
    """
    M, C = values.shape
    left, right_t = np.empty((M, C, C)), np.empty((M, C, C))
    order = np.empty(C, dtype=np.int64)
    magnitude = np.empty(C)
    tied = False
    for m in range(M):
        for c in range(C):
            magnitude[c] = abs(values[m, c])
            order[c] = c
        # ascending by magnitude (insertion sort), read backwards
        for c in range(1, C):
            j = c
            while j > 0 and magnitude[order[j - 1]] > magnitude[order[j]]:
                order[j - 1], order[j] = order[j], order[j - 1]
                j -= 1
        for c in range(1, C):
            tied |= magnitude[order[c - 1]] == magnitude[order[c]]
        largest = magnitude[order[C - 1]]
        cutoff = rcond * largest
        for c in range(C):
            source = order[C - 1 - c]
            value = values[m, source]
            sign = 1.0 if value > 0 else (-1.0 if value < 0 else (0.0 if value == 0 else value))
            inverse = 1.0 / magnitude[source] if magnitude[source] > cutoff else 0.0
            for i in range(C):
                left[m, i, c] = vectors[m, i, source] * sign
                right_t[m, i, c] = inverse * vectors[m, i, source]
    return left, right_t, tied


@numba.njit(cache=True)
def chi_squares(
    gram: np.ndarray, cross: np.ndarray, square: np.ndarray, windows: np.ndarray, inverse: np.ndarray, columns: np.ndarray
) -> np.ndarray:
    """``balance_chi_square`` (M, 1 + D) from its sums and the pseudo-inverse (M, C, C) of ``gram``.

    The full regression's explained sum of squares is ``np.einsum("ni,nij,nj->n", cross, inverse, cross)``
    in einsum's order: each product left to right, all C^2 of them added in turn from 0.
    """
    M, C = cross.shape
    D = len(columns)
    chi2 = np.empty((M, 1 + D))
    for m in range(M):
        explained = 0.0
        for i in range(C):
            for j in range(C):
                explained += cross[m, i] * inverse[m, i, j] * cross[m, j]
        variance = numpy_maximum(square[m] - explained, TINY) / max(windows[m] - C, 1)
        chi2[m, 0] = numpy_maximum(explained, 0.0) / variance
        smallest = chi2[m, 0]
        for d in range(D):
            c = columns[d]
            alone = cross[m, c] ** 2 / numpy_maximum(gram[m, c, c], TINY) if c >= 0 else explained
            chi2[m, 1 + d] = numpy_maximum(explained - alone, 0.0) / variance
            smallest = numpy_minimum(smallest, chi2[m, 1 + d])
        for d in range(D):
            if columns[d] < 0:
                chi2[m, 1 + d] = smallest
    return chi2


@numba.njit(cache=True)
def balance_log_ratios(
    gram: np.ndarray, cross: np.ndarray, square: np.ndarray, inverse: np.ndarray, steps: np.ndarray, rows: np.ndarray, span: int,
    windows_per_step: int, columns: np.ndarray, inflation: float, n: int,
) -> np.ndarray:
    """``Isolation.balance_evidence`` (n, 1 + D) from the sums of ``rows``' last ``span`` steps (M of n systems,
    distinct) and the pseudo-inverse of their gram: each row's windows are min(steps, span) times
    ``windows_per_step``; its log likelihood ratios -0.5 (chi2 - its smallest) / ``inflation``, in
    numpy's order; 0 for the other systems."""
    M = len(rows)
    windows = np.empty(M, dtype=np.int64)
    for m in range(M):
        windows[m] = min(steps[rows[m]], span) * windows_per_step
    chi2 = chi_squares(gram, cross, square, windows, inverse, columns)
    evidence = np.zeros((n, chi2.shape[1]))
    for m in range(M):
        smallest = chi2[m, 0]
        for k in range(1, chi2.shape[1]):
            smallest = numpy_minimum(smallest, chi2[m, k])
        for k in range(chi2.shape[1]):
            evidence[rows[m], k] = -0.5 * (chi2[m, k] - smallest) / inflation
    return evidence


@numba.njit(cache=True)
def suspect_hypotheses(confident: np.ndarray, isolated: np.ndarray, parameters: int) -> np.ndarray:
    """The hypotheses to estimate, (N, D = ``parameters``): every one for a system that is not ``confident`` (N,),
    its suspect's alone (``isolated`` (N,) - 1) for one that is."""
    hypotheses = np.ones((len(confident), parameters), dtype=np.bool_)
    for n in range(len(confident)):
        if confident[n]:
            for d in range(parameters):
                hypotheses[n, d] = d == isolated[n] - 1
    return hypotheses


@numba.njit(cache=True)
def network_average(predicted: np.ndarray, counted: np.ndarray, n: int, weight: float, average: np.ndarray) -> np.ndarray:
    """The newest frame's class probabilities of n systems, (n, K): the network's ``predicted`` (M, K) for the
    ``counted`` systems (M,, distinct), "none" = 1 for the others. Moves each counted system's running
    ``average`` (n, K) towards its prediction: average += weight (predicted - average), in numpy's order."""
    K = average.shape[1]
    probabilities = np.zeros((n, K))
    probabilities[:, 0] = 1.0
    for m in range(len(counted)):
        row = counted[m]
        for k in range(K):
            probabilities[row, k] = predicted[m, k]
            average[row, k] += weight * (predicted[m, k] - average[row, k])
    return probabilities


@numba.njit(cache=True)
def belief_inputs(
    average: np.ndarray, log_evidence: np.ndarray, alarm: np.ndarray, estimator_weight: float, floor: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fusion's terms before its logarithm, N systems, K classes (``Isolation.fuse``).

    Returns the network's belief plus ``floor`` (N, K) (the network's running ``average`` normalised,
    uniform before its first frame), the estimator's weighted log evidence relative to its best
    finite class (0 where not finite) (N, K), and whether a system has a belief (N,): alarm raised,
    and a fault class fitted or a network frame seen.
    """
    N, K = average.shape
    network, evidence, believed = np.empty((N, K)), np.empty((N, K)), np.empty(N, dtype=np.bool_)
    scratch = summation_scratch()
    for n in range(N):
        total = numpy_sum(average[n], 0, K, scratch)
        best = -np.inf
        fitted = False
        for k in range(K):
            network[n, k] = (average[n, k] / total if total > 0 else 1.0 / K) + floor
            if np.isfinite(log_evidence[n, k]):
                best = numpy_maximum(best, log_evidence[n, k])
                fitted |= k > 0
        for k in range(K):
            weighted = estimator_weight * (log_evidence[n, k] - best)
            evidence[n, k] = weighted if np.isfinite(weighted) else 0.0
        believed[n] = alarm[n] and (fitted or total > 0)
    return network, evidence, believed


@numba.njit(cache=True)
def shifted_log_belief(
    log_network: np.ndarray, evidence: np.ndarray, balance: np.ndarray, network_weight: float, balance_weight: float
) -> np.ndarray:
    """The log belief (N, K), each system's largest subtracted: network_weight log_network + evidence + balance_weight balance."""
    N, K = log_network.shape
    out = np.empty((N, K))
    for n in range(N):
        top = -np.inf
        for k in range(K):
            out[n, k] = network_weight * log_network[n, k] + evidence[n, k] + balance_weight * balance[n, k]
            top = out[n, k] if k == 0 else numpy_maximum(top, out[n, k])
        for k in range(K):
            out[n, k] -= top
    return out


@numba.njit(cache=True)
def verdict(
    belief: np.ndarray, believed: np.ndarray, suspect: np.ndarray, sure: np.ndarray, estimated: np.ndarray, threshold: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The fused belief's verdict, N systems (``Fusion``): the normalised belief where ``believed`` ("none" = 1
    elsewhere) (N, K), the suspect (N,), its share of the fault classes' belief (N,), whether that share
    reaches ``threshold`` (N,), and the systems whose suspect changed from the previous ``suspect`` to one
    the estimator did not update (``estimated`` (N, K - 1)), (M,). Stores the suspects in ``suspect``
    (N,) and whether they are sure in ``sure`` (N,)."""
    N, K = belief.shape
    diagnosis = np.zeros((N, K))
    isolated = np.zeros(N, dtype=np.int64)
    confidence = np.zeros(N)
    confident = np.zeros(N, dtype=np.bool_)
    restarted = np.zeros(N, dtype=np.bool_)
    scratch = summation_scratch()
    for n in range(N):
        if not believed[n]:
            diagnosis[n, 0] = 1.0
        else:
            total = numpy_sum(belief[n], 0, K, scratch)
            for k in range(K):
                diagnosis[n, k] = belief[n, k] / total
            # np.argmax over the fault classes: the first largest (the first NaN if any)
            best = 1
            for k in range(2, K):
                if diagnosis[n, best] != diagnosis[n, best]:
                    break
                if not diagnosis[n, k] <= diagnosis[n, best]:
                    best = k
            isolated[n] = best
        faults = numpy_sum(diagnosis[n], 1, K, scratch)
        share = diagnosis[n, isolated[n]] / numpy_maximum(faults, TINY)
        if isolated[n] > 0:
            confidence[n] = share
            confident[n] = share >= threshold
            restarted[n] = isolated[n] != suspect[n] and not estimated[n, isolated[n] - 1]
        suspect[n], sure[n] = isolated[n], confident[n]
    return diagnosis, isolated, confidence, confident, restarted.nonzero()[0]
