"""The matrix exponential by scaling and squaring with the [13/13] Pade approximant (Higham 2005)
(``ea_gym._kernels.expm``), in numpy's matrix products and solve: the kernels meet it to ~1e-13 relative."""

from __future__ import annotations

import numpy as np

from ea_gym._kernels.expm import PADE13, THETA13


def matmul(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> None:
    """c = a b."""
    c[:] = a @ b


def solve(a: np.ndarray, b: np.ndarray) -> None:
    """b = a^-1 b (a is the kernel's workspace)."""
    b[:] = np.linalg.solve(a, b)


def pade_polynomial(A2: np.ndarray, A4: np.ndarray, A6: np.ndarray, c: np.ndarray, T: np.ndarray, out: np.ndarray) -> None:
    """out = A6 (c6 A6 + c5 A4 + c4 A2) + c3 A6 + c2 A4 + c1 A2 + c0 I (T: the kernel's workspace)."""
    out[:] = A6 @ (c[6] * A6 + c[5] * A4 + c[4] * A2) + c[3] * A6 + c[2] * A4 + c[1] * A2 + c[0] * np.eye(len(A2))


def expm_batch(Z: np.ndarray, out: np.ndarray) -> None:
    """out[k] = e^Z[k]: Z[k] scaled by 2^-s below ``THETA13`` in 1-norm, r = (V - U)^-1 (V + U) with U, V the
    approximant's odd and even halves, squared s times."""
    for k, A in enumerate(Z):
        norm = np.abs(A).sum(axis=0).max()
        s = int(np.ceil(np.log2(norm / THETA13))) if norm > THETA13 else 0
        A = A * 0.5**s
        A2 = A @ A
        A4 = A2 @ A2
        A6 = A4 @ A2
        U, V = np.empty_like(A), np.empty_like(A)
        pade_polynomial(A2, A4, A6, PADE13[1::2], A, U)
        U = A @ U
        pade_polynomial(A2, A4, A6, PADE13[0::2], A, V)
        r = np.linalg.solve(V - U, V + U)
        for _ in range(s):
            r = r @ r
        out[k] = r


def held_input_discretization(A: np.ndarray, B: np.ndarray, h: float, chain: np.ndarray, Phi: np.ndarray, Gamma: np.ndarray) -> None:
    """Phi[k], Gamma[k]: the top block row of e^(Z h), Z = [[A[k], B[k], 0], chain]."""
    rows, nx, nu = B.shape
    size = chain.shape[1]
    Z = np.zeros((rows, size, size))
    Z[:, :nx, :nx], Z[:, :nx, nx : nx + nu], Z[:, nx:] = A, B, chain
    E = np.empty_like(Z)
    expm_batch(Z * h, E)
    Phi[:], Gamma[:] = E[:, :nx, :nx], E[:, :nx, nx:]
