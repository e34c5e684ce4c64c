"""The bond-graph equations M(phi) z = N(phi) x + P u of many parameter sets, assembled in one compiled loop
(``ea_gym.bondgraph.equations.StateSpaceModel.matrices``): each coefficient added to the constant part in
the entries' order, as its numpy form adds them, so to the bit.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def assemble_equations(
    theta: np.ndarray, M0: np.ndarray, P: np.ndarray, parameter: np.ndarray, in_M: np.ndarray, row: np.ndarray, col: np.ndarray,
    scale: np.ndarray, reciprocal: np.ndarray, M: np.ndarray, rhs: np.ndarray,
) -> None:
    """M (S, 2n, 2n) and rhs = [N | P] (S, 2n, nx + nu) of the parameter rows ``theta`` (S, n_parameters).

    Entry k adds scale[k] / value (``reciprocal``) or scale[k] * value, value = theta[:, parameter[k]], at
    (row[k], col[k]) of M (``in_M``) or of N; M starts from M0, N from 0.
    """
    nx = rhs.shape[2] - P.shape[1]
    for s in range(theta.shape[0]):
        M[s] = M0
        rhs[s, :, :nx] = 0.0
        rhs[s, :, nx:] = P
        for k in range(len(parameter)):
            value = theta[s, parameter[k]]
            coefficient = scale[k] / value if reciprocal[k] else scale[k] * value
            if in_M[k]:
                M[s, row[k], col[k]] += coefficient
            else:
                rhs[s, row[k], col[k]] += coefficient
