"""The matrix exponential of many small matrices: scaling and squaring with the [13/13] Pade
approximant (Higham 2005), in compiled loops (``ea_gym.bondgraph.simulation.expm`` is its front).

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.expm``.
"""

from __future__ import annotations

import numba
import numpy as np

from ea_gym._kernels.numpy_forms import numpy_maximum

#: Coefficients b_0..b_13 of the [13/13] Pade approximant of exp (Higham 2005, Table 2.2).
PADE13 = np.array([
    64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0, 129060195264000.0,
    10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0, 40840800.0, 960960.0, 16380.0, 182.0, 1.0,
])
#: Largest 1-norm for which the [13/13] approximant is exact to double precision (Higham 2005, Table 2.3).
THETA13 = 5.371920351148152


@numba.njit(cache=True)
def matmul(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> None:
    """c = a @ b; explicit loops, since a BLAS call costs more than the product for matrices this small.
    Each entry sums its products in k's order from 0.0 in a register (c may not be a or b)."""
    n = a.shape[0]
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += a[i, k] * b[k, j]
            c[i, j] = acc


@numba.njit(cache=True)
def solve(a: np.ndarray, b: np.ndarray) -> None:
    """b = a^-1 b by Gaussian elimination with partial pivoting; a is overwritten."""
    n = a.shape[0]
    for k in range(n):
        p = k
        for i in range(k + 1, n):
            if abs(a[i, k]) > abs(a[p, k]):
                p = i
        if p != k:
            for j in range(n):
                a[k, j], a[p, j] = a[p, j], a[k, j]
                b[k, j], b[p, j] = b[p, j], b[k, j]
        for i in range(k + 1, n):
            f = a[i, k] / a[k, k]
            for j in range(k + 1, n):
                a[i, j] -= f * a[k, j]
            for j in range(n):
                b[i, j] -= f * b[k, j]
    for k in range(n - 1, -1, -1):
        for j in range(n):
            acc = b[k, j]
            for i in range(k + 1, n):
                acc -= a[k, i] * b[i, j]
            b[k, j] = acc / a[k, k]


@numba.njit(cache=True)
def pade_polynomial(A2: np.ndarray, A4: np.ndarray, A6: np.ndarray, c: np.ndarray, T: np.ndarray, out: np.ndarray) -> None:
    """out = A6 (c6 A6 + c5 A4 + c4 A2) + c3 A6 + c2 A4 + c1 A2 + c0 I: the even or odd half of the
    [13/13] Pade approximant's coefficients (``PADE13[0::2]`` or ``[1::2]``); T is a workspace.
    Element by element in the order of the array expressions, without their temporary arrays."""
    n = A2.shape[0]
    for i in range(n):
        for j in range(n):
            T[i, j] = c[6] * A6[i, j] + c[5] * A4[i, j] + c[4] * A2[i, j]
    matmul(A6, T, out)
    for i in range(n):
        for j in range(n):
            out[i, j] += c[3] * A6[i, j] + c[2] * A4[i, j] + c[1] * A2[i, j]
        out[i, i] += c[0]


@numba.njit(cache=True, nogil=True)
def expm_batch(Z: np.ndarray, out: np.ndarray) -> None:
    """out[k] = e^Z[k] for each of the (M, n, n) matrices: scaling and squaring with the [13/13] Pade
    approximant (Higham 2005). Each matrix's arithmetic is its own, so a batch's rows may be split over
    threads (``ea_gym.threads.over_rows``)."""
    odd, even = PADE13[1::2], PADE13[0::2]
    n = Z.shape[1]
    # one workspace for all matrices: allocations would cost more than the arithmetic
    A, A2, A4, A6, T, W, U, V = np.empty((8, n, n))
    for k in range(Z.shape[0]):
        A[:] = Z[k]
        norm = 0.0  # the largest column sum of |A| (numpy's max, NaN propagated)
        for j in range(n):
            column = 0.0
            for i in range(n):
                column += abs(A[i, j])
            norm = column if j == 0 else numpy_maximum(norm, column)
        s = 0
        if norm > THETA13:
            s = int(np.ceil(np.log2(norm / THETA13)))
            A *= 0.5**s
        matmul(A, A, A2)
        matmul(A2, A2, A4)
        matmul(A4, A2, A6)
        # U = A [A6 (b13 A6 + b11 A4 + b9 A2) + b7 A6 + b5 A4 + b3 A2 + b1 I]
        pade_polynomial(A2, A4, A6, odd, T, W)
        matmul(A, W, U)
        # V = A6 (b12 A6 + b10 A4 + b8 A2) + b6 A6 + b4 A4 + b2 A2 + b0 I
        pade_polynomial(A2, A4, A6, even, T, V)
        # r = (V - U)^-1 (V + U), then squared s times
        for i in range(n):
            for j in range(n):
                T[i, j] = V[i, j] - U[i, j]
                W[i, j] = V[i, j] + U[i, j]
        solve(T, W)
        for _ in range(s):
            matmul(W, W, T)
            W[:] = T
        out[k] = W


@numba.njit(cache=True, nogil=True)
def held_input_discretization(A: np.ndarray, B: np.ndarray, h: float, chain: np.ndarray, Phi: np.ndarray, Gamma: np.ndarray) -> None:
    """Phi[k] and Gamma[k], the top block row of e^(Z h) with Z = [[A[k], B[k], 0], chain] for each of the
    (M, nx, nx) and (M, nx, nu) matrices (``ea_gym.bondgraph.simulation.discretize``): Z h element by
    element as numpy multiplies it, then ``expm_batch``'s exponential. Rows may be split over threads."""
    rows, nx, nu = A.shape[0], A.shape[1], B.shape[2]
    size = chain.shape[1]
    Z = np.empty((rows, size, size))
    E = np.empty((rows, size, size))
    for k in range(rows):
        for i in range(nx):
            for j in range(nx):
                Z[k, i, j] = A[k, i, j] * h
            for j in range(nu):
                Z[k, i, nx + j] = B[k, i, j] * h
            for j in range(nx + nu, size):
                Z[k, i, j] = 0.0 * h
        for i in range(size - nx):
            for j in range(size):
                Z[k, nx + i, j] = chain[i, j] * h
    expm_batch(Z, E)
    for k in range(rows):
        for i in range(nx):
            for j in range(nx):
                Phi[k, i, j] = E[k, i, j]
            for j in range(size - nx):
                Gamma[k, i, j] = E[k, i, nx + j]
