"""The plant's kept rows and their discretizations (``ea_gym._kernels.rows``)."""

from __future__ import annotations

import numpy as np


def changed_rows(theta: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """The rows of ``theta`` (N, P) whose bits differ from ``kept``'s (a NaN is never the same)."""
    same = (theta == kept) & (np.signbit(theta) == np.signbit(kept))
    return np.flatnonzero(~same.all(axis=1)).astype(np.intp)


def replace_rows(
    rows: np.ndarray, index: np.ndarray, theta: np.ndarray, Phi: np.ndarray, Gamma: np.ndarray, kept: np.ndarray, kept_Phi: np.ndarray,
    kept_Gamma: np.ndarray,
) -> None:
    """kept[rows] = theta, kept_Phi[rows] = Phi[index], kept_Gamma[rows] = Gamma[index]."""
    kept[rows] = theta
    kept_Phi[rows] = Phi[index]
    kept_Gamma[rows] = Gamma[index]
