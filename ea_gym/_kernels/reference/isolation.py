"""Fault isolation's arithmetic (``ea_gym._kernels.isolation``): the energy-balance regression's chi-squares
and evidence, the network's running average, and the fused belief's verdict, in numpy's own operations
and order: the kernels meet them to the bit."""

from __future__ import annotations

import numpy as np

from ea_gym.numerics import TINY


def history_sums(
    gram: np.ndarray, cross: np.ndarray, other: np.ndarray, rows: np.ndarray, span: int, by_system: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """numpy's sums over the last ``span`` steps of gram (N, C, C, R) and cross (N, C, R), and over every step
    of ``other`` (N, X, V), for ``rows``; by system: at each row's own system, zeros for the others."""
    sums = gram[rows, ..., -span:].sum(-1), cross[rows, ..., -span:].sum(-1), other[rows].sum(-1)
    if not by_system:
        return sums
    gram_sum, cross_sum, other_sum = (np.zeros((len(gram),) + total.shape[1:]) for total in sums)
    gram_sum[rows], cross_sum[rows], other_sum[rows] = sums
    return gram_sum, cross_sum, other_sum


def pseudo_inverse_factors(values: np.ndarray, vectors: np.ndarray, rcond: float) -> tuple[np.ndarray, np.ndarray, bool]:
    """The factors of numpy's ``pinv(a, rcond, hermitian=True)`` from ``eigh(a)``: the eigenpairs by decreasing
    |value|, the left factor the vectors times the values' signs, the right factor's transpose the vectors
    times 1/|value| (0 at most ``rcond`` times the largest); and whether two |values| of a matrix tie."""
    magnitude = np.abs(values)
    order = np.argsort(magnitude, axis=1, kind="stable")[:, ::-1]
    ordered = np.take_along_axis(magnitude, order, axis=1)
    vectors = np.take_along_axis(vectors, order[:, None, :], axis=2)
    sign = np.sign(np.take_along_axis(values, order, axis=1))
    large = ordered > rcond * ordered[:, :1]
    inverse = np.where(large, 1.0 / np.where(large, ordered, 1.0), 0.0)
    tied = bool((ordered[:, 1:] == ordered[:, :-1]).any())
    return vectors * sign[:, None, :], inverse[:, None, :] * vectors, tied


def explained_sums(cross: np.ndarray, inverse: np.ndarray) -> np.ndarray:
    """cross^T inverse cross per row, each product left to right and all C^2 added in turn from 0 (einsum's order)."""
    explained = np.zeros(len(cross))
    for i, j in np.ndindex(inverse.shape[1:]):
        explained += cross[:, i] * inverse[:, i, j] * cross[:, j]
    return explained


def chi_squares(
    gram: np.ndarray, cross: np.ndarray, square: np.ndarray, windows: np.ndarray, inverse: np.ndarray, columns: np.ndarray
) -> np.ndarray:
    """(M, 1 + D): the full regression's explained sum over the residual variance, then each hypothesis's
    loss of it without its component (``columns`` -1: the smallest chi-square)."""
    C = gram.shape[-1]
    explained = explained_sums(cross, inverse)
    variance = np.maximum(square - explained, TINY) / np.maximum(windows - C, 1)
    single = cross**2 / np.maximum(np.diagonal(gram, axis1=-2, axis2=-1), TINY)
    chi2 = np.empty((len(square), 1 + len(columns)))
    chi2[:, 0] = explained
    chi2[:, 1:] = explained[:, None] - np.where(columns >= 0, single[:, columns], explained[:, None])
    with np.errstate(over="ignore", invalid="ignore"):  # a regression that explains everything: variance TINY, chi-squares inf
        chi2 = np.maximum(chi2, 0.0) / variance[:, None]
    chi2[:, 1:] = np.where(columns >= 0, chi2[:, 1:], np.minimum.reduce(chi2, axis=1, keepdims=True))
    return chi2


def balance_log_ratios(
    gram: np.ndarray, cross: np.ndarray, square: np.ndarray, inverse: np.ndarray, steps: np.ndarray, rows: np.ndarray, span: int,
    windows_per_step: int, columns: np.ndarray, inflation: float, n: int,
) -> np.ndarray:
    """(n, 1 + D): -0.5 (chi2 - its smallest) / ``inflation`` for ``rows``, each over min(steps, span)
    ``windows_per_step`` windows; 0 for the other systems."""
    chi2 = chi_squares(gram, cross, square, np.minimum(steps[rows], span) * windows_per_step, inverse, columns)
    evidence = np.zeros((n, chi2.shape[1]))
    evidence[rows] = -0.5 * (chi2 - np.minimum.reduce(chi2, axis=1, keepdims=True)) / inflation
    return evidence


def suspect_hypotheses(confident: np.ndarray, isolated: np.ndarray, parameters: int) -> np.ndarray:
    """(N, D): every hypothesis, or a ``confident`` system's suspect (``isolated`` - 1) alone."""
    return np.where(confident[:, None], np.arange(parameters) == isolated[:, None] - 1, True)


def network_average(predicted: np.ndarray, counted: np.ndarray, n: int, weight: float, average: np.ndarray) -> np.ndarray:
    """The ``counted`` systems' ``predicted`` probabilities ("none" = 1 for the others), (n, K); their running
    ``average`` += weight (predicted - average)."""
    probabilities = np.zeros((n, average.shape[1]))
    probabilities[:, 0] = 1.0
    probabilities[counted] = predicted
    average[counted] += weight * (predicted - average[counted])
    return probabilities


def belief_inputs(
    average: np.ndarray, log_evidence: np.ndarray, alarm: np.ndarray, estimator_weight: float, floor: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The network's normalised average (uniform before its first frame) plus ``floor``; the weighted log
    evidence relative to the best finite class (0 where not finite); and whether a system has a belief:
    alarm raised, and a fault class fitted or a network frame seen."""
    K = average.shape[1]
    total = average.sum(1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        network = np.where(total > 0, average / total, 1.0 / K) + floor
    finite = np.isfinite(log_evidence)
    best = np.max(log_evidence, axis=1, initial=-np.inf, where=finite, keepdims=True)
    with np.errstate(invalid="ignore"):
        weighted = estimator_weight * (log_evidence - best)
    return network, np.where(np.isfinite(weighted), weighted, 0.0), alarm & (finite[:, 1:].any(axis=1) | (total[:, 0] > 0))


def shifted_log_belief(
    log_network: np.ndarray, evidence: np.ndarray, balance: np.ndarray, network_weight: float, balance_weight: float
) -> np.ndarray:
    """network_weight log_network + evidence + balance_weight balance, each system's largest subtracted."""
    log_belief = network_weight * log_network + evidence + balance_weight * balance
    return log_belief - np.maximum.reduce(log_belief, axis=1, keepdims=True)


def verdict(
    belief: np.ndarray, believed: np.ndarray, suspect: np.ndarray, sure: np.ndarray, estimated: np.ndarray, threshold: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The normalised belief where ``believed`` ("none" = 1 elsewhere), the suspect (the first largest fault
    class), its share of the fault classes' belief, whether that reaches ``threshold``, and the systems whose
    suspect changed to one the estimator did not update; ``suspect`` and ``sure`` take the new verdict."""
    N, K = belief.shape
    diagnosis = np.where(believed[:, None], belief / belief.sum(1, keepdims=True), np.eye(K)[0])
    isolated = np.where(believed, 1 + np.argmax(diagnosis[:, 1:], axis=1), 0).astype(np.int64)
    share = diagnosis[np.arange(N), isolated] / np.maximum(diagnosis[:, 1:].sum(1), TINY)
    confident = (isolated > 0) & (share >= threshold)
    restarted = (isolated > 0) & (isolated != suspect) & ~estimated[np.arange(N), isolated - 1]
    suspect[:], sure[:] = isolated, confident
    return diagnosis, isolated, np.where(isolated > 0, share, 0.0), confident, np.flatnonzero(restarted)
