"""The parameter rows of a batch kept from one simulation to the next (``ea_gym.bondgraph.simulation.RowDiscretizations``):
which rows changed, and the kept rows and their discretizations replaced by the new ones.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.rows``.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def changed_rows(theta: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """The indices of the rows of ``theta`` (N, P) that differ from those of ``kept`` (N, P): a row is the same
    where every value equals its kept one with the same sign (so the same bits; a NaN is never the same)."""
    changed = np.empty(theta.shape[0], dtype=np.intp)
    count = 0
    for r in range(theta.shape[0]):
        for j in range(theta.shape[1]):
            a, b = theta[r, j], kept[r, j]
            if not (a == b and math.copysign(1.0, a) == math.copysign(1.0, b)):
                changed[count] = r
                count += 1
                break
    return changed[:count]


@numba.njit(cache=True)
def replace_rows(
    rows: np.ndarray, index: np.ndarray, theta: np.ndarray, Phi: np.ndarray, Gamma: np.ndarray, kept: np.ndarray, kept_Phi: np.ndarray,
    kept_Gamma: np.ndarray,
) -> None:
    """kept[r] = theta[k], kept_Phi[r] = Phi[index[k]] and kept_Gamma[r] = Gamma[index[k]] for r = rows[k]: the
    rows ``rows`` of ``theta`` (K, P), each with the discretization of its distinct copy."""
    for k in range(rows.shape[0]):
        r = rows[k]
        kept[r] = theta[k]
        kept_Phi[r] = Phi[index[k]]
        kept_Gamma[r] = Gamma[index[k]]
