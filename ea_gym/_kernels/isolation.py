"""The balance evidence's compiled steps (``ea_gym.phm.isolation``): the regression sums of the evidence
span read from the history's rows, numpy's pseudo-inverse around its eigendecomposition and matrix
product (which stay numpy's), and the classes' chi-squares.

Each step repeats the arithmetic of the numpy form it replaces (``np.sum``, ``np.linalg.pinv`` with
``hermitian=True``, the chi-square's element-wise formula) in the same order, so that the numbers are
the same to the bit.
"""

from __future__ import annotations

import numba
import numpy as np

from ea_gym._kernels.summation import numpy_sum, summation_scratch
from ea_gym.numerics import TINY


@numba.njit(cache=True)
def balance_sums(
    gram: np.ndarray, cross: np.ndarray, square: np.ndarray, rows: np.ndarray, span: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sums over the last ``span`` steps of gram (N, C, C, R) and cross (N, C, R), and over every step of
    square (N, V), for ``rows``: (M, C, C), (M, C), (M,)."""
    M, C, R = len(rows), gram.shape[1], gram.shape[-1]
    gram_sum, cross_sum, square_sum = np.empty((M, C, C)), np.empty((M, C)), np.empty(M)
    scratch = summation_scratch()
    for k in range(M):
        n = rows[k]
        for i in range(C):
            for j in range(C):
                gram_sum[k, i, j] = numpy_sum(gram[n, i, j], R - span, R, scratch)
            cross_sum[k, i] = numpy_sum(cross[n, i], R - span, R, scratch)
        square_sum[k] = numpy_sum(square[n], 0, square.shape[1], scratch)
    return gram_sum, cross_sum, square_sum


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
def _maximum(a: float, b: float) -> float:
    """np.maximum(a, b) of two floats (NaN propagates; of equal ones, a)."""
    return a if (a >= b or a != a) else b


@numba.njit(cache=True)
def chi_squares(
    gram: np.ndarray, cross: np.ndarray, square: np.ndarray, windows: np.ndarray, explained: np.ndarray, columns: np.ndarray
) -> np.ndarray:
    """``balance_chi_square`` (M, 1 + D) from its sums and the full regression's explained sum of squares (M,)."""
    M, C = cross.shape
    D = len(columns)
    chi2 = np.empty((M, 1 + D))
    for m in range(M):
        variance = _maximum(square[m] - explained[m], TINY) / max(windows[m] - C, 1)
        chi2[m, 0] = _maximum(explained[m], 0.0) / variance
        smallest = chi2[m, 0]
        for d in range(D):
            c = columns[d]
            alone = cross[m, c] ** 2 / _maximum(gram[m, c, c], TINY) if c >= 0 else explained[m]
            chi2[m, 1 + d] = _maximum(explained[m] - alone, 0.0) / variance
            smallest = smallest if (smallest <= chi2[m, 1 + d] or smallest != smallest) else chi2[m, 1 + d]
        for d in range(D):
            if columns[d] < 0:
                chi2[m, 1 + d] = smallest
    return chi2
