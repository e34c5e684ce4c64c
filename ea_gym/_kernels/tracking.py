"""The tracking filter bank: one extended Kalman filter per (system, hypothesis), run over a step's samples.

Filter f's state is z = [x (nx energy variables), theta (the hypothesis's parameter), drift (its rate,
unit/s)]. Between samples x follows the plant's own exact discretization x' = Phi(theta) x + Gamma(theta) w
(w: the input's cubic Hermite coefficients over the interval), read off a Chebyshev interpolant in theta
with its derivative, theta' = theta + h drift, drift' = drift; the measurement is y = g(theta) x (gain
1/theta on the momentum of the hypothesis's own I element). Every filter adds each innovation's
log-density to its log-likelihood, decayed by ``forget`` per sample. ``tracking_step_reference`` in
the tests is the same arithmetic in plain numpy.
"""

from __future__ import annotations

import math

import numba
import numpy as np

LOG_2PI = math.log(2.0 * math.pi)


@numba.njit(cache=True)
def chebyshev_matrices(
    coefficients: np.ndarray, terms: int, lo: float, hi: float, theta: float, value: np.ndarray, slope: np.ndarray, basis: np.ndarray
) -> None:
    """value = sum_k c_k T_k(s) over the first ``terms`` coefficients, slope = its derivative in theta (per
    unit), s = theta mapped from [lo, hi] to [-1, 1] and clamped there (outside: the nearer end's).

    Args:
        coefficients: (K, rows, cols) Chebyshev coefficients of every matrix entry.
        basis: (2, K) workspace for T_k(s) and dT_k/dtheta.
    """
    width = hi - lo
    s = (2.0 * theta - (lo + hi)) / width if width > 0 else 0.0
    s = min(1.0, max(-1.0, s))
    scale = 2.0 / width if width > 0 else 0.0
    basis[0, 0], basis[1, 0] = 1.0, 0.0
    if terms > 1:
        basis[0, 1], basis[1, 1] = s, 1.0
    for k in range(2, terms):
        basis[0, k] = 2.0 * s * basis[0, k - 1] - basis[0, k - 2]
        basis[1, k] = 2.0 * basis[0, k - 1] + 2.0 * s * basis[1, k - 1] - basis[1, k - 2]
    for i in range(value.shape[0]):
        for j in range(value.shape[1]):
            v = 0.0
            d = 0.0
            for k in range(terms):
                c = coefficients[k, i, j]
                v += c * basis[0, k]
                d += c * basis[1, k]
            value[i, j] = v
            slope[i, j] = d * scale


@numba.njit(cache=True)
def predict(
    z: np.ndarray, P: np.ndarray, M: np.ndarray, dM: np.ndarray, w: np.ndarray, h: float, q: np.ndarray, F: np.ndarray, T: np.ndarray
) -> None:
    """Time update of one filter over one interval: z and P in place; M = [Phi | Gamma], dM its theta-slope.

    q: process-noise variances added to the diagonal (n,); F, T: (n, n) workspaces: F's first nx rows
    are the Jacobian's state rows, the others are known (theta' = theta + h drift, drift' = drift), and
    its last row holds the new states meanwhile.
    """
    n = z.shape[0]
    nx = n - 2
    m = w.shape[0]
    x_new = F[n - 1]
    for i in range(nx):
        acc = 0.0
        sens = 0.0
        for j in range(nx):
            acc += M[i, j] * z[j]
            sens += dM[i, j] * z[j]
            F[i, j] = M[i, j]
        for j in range(m):
            acc += M[i, nx + j] * w[j]
            sens += dM[i, nx + j] * w[j]
        x_new[i] = acc
        F[i, nx] = sens
    z[:nx] = x_new[:nx]
    z[nx] += h * z[nx + 1]
    # P = F P F^T + diag(q); only the state rows of F are general
    for i in range(n):
        for j in range(n):
            if i < nx:
                acc = F[i, nx] * P[nx, j]
                for k in range(nx):
                    acc += F[i, k] * P[k, j]
            elif i == nx:
                acc = P[nx, j] + h * P[nx + 1, j]
            else:
                acc = P[nx + 1, j]
            T[i, j] = acc
    for i in range(n):
        for j in range(i + 1):
            if j < nx:
                acc = T[i, nx] * F[j, nx]
                for k in range(nx):
                    acc += T[i, k] * F[j, k]
            elif j == nx:
                acc = T[i, nx] + h * T[i, nx + 1]
            else:
                acc = T[i, nx + 1]
            P[i, j] = acc
            P[j, i] = acc
        P[i, i] += q[i]


@numba.njit(cache=True)
def cholesky_solve(L: np.ndarray, b: np.ndarray) -> None:
    """b = (L L^T)^-1 b in place, column by column; L lower triangular (m, m), b (m, k)."""
    m = L.shape[0]
    for c in range(b.shape[1]):
        for i in range(m):
            acc = b[i, c]
            for j in range(i):
                acc -= L[i, j] * b[j, c]
            b[i, c] = acc / L[i, i]
        for i in range(m - 1, -1, -1):
            acc = b[i, c]
            for j in range(i + 1, m):
                acc -= L[j, i] * b[j, c]
            b[i, c] = acc / L[i, i]


@numba.njit(cache=True)
def cholesky(S: np.ndarray, L: np.ndarray) -> None:
    """L lower triangular with L L^T = S (m, m)."""
    m = S.shape[0]
    L[:] = 0.0
    for i in range(m):
        for j in range(i + 1):
            acc = S[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            L[i, j] = math.sqrt(acc) if i == j else acc / L[j, j]


@numba.njit(cache=True)
def correct(z: np.ndarray, P: np.ndarray, y: np.ndarray, r: np.ndarray, gain: np.ndarray, own: int, work: np.ndarray) -> float:
    """Measurement update of one filter from y = g x + noise of variances r; returns the
    innovation's log-density. ``own``: the state whose gain is 1 / theta (-1: none).

    H has one nonzero per row (the state's gain) plus, on row ``own``, the theta column.
    ``work``: (4 n, n) scratch rows.
    """
    n = z.shape[0]
    nx = n - 2
    g = work[0, :nx]
    d = 0.0  # d y_own / d theta
    for i in range(nx):
        g[i] = gain[i]
    if own >= 0:
        g[own] = 1.0 / z[nx]
        d = -z[own] * g[own] * g[own]
    # PHt (n, nx): column i = g_i P[:, i] (+ d P[:, nx] on own)
    PHt = work[1 : 1 + n, :nx]
    for row in range(n):
        for i in range(nx):
            PHt[row, i] = g[i] * P[row, i] + (d * P[row, nx] if i == own else 0.0)
    S = work[1 + n : 1 + n + nx, :nx]
    for i in range(nx):
        for j in range(nx):
            S[i, j] = g[i] * PHt[i, j] + (d * PHt[nx, j] if i == own else 0.0)
        S[i, i] += r[i]
    L = work[1 + n + nx : 1 + n + 2 * nx, :nx]
    cholesky(S, L)
    # innovation nu and a = S^-1 nu; Kt = S^-1 PHt^T (nx, n)
    nu = work[1 + n + 2 * nx : 2 + n + 2 * nx, :nx]
    for i in range(nx):
        nu[0, i] = y[i] - g[i] * z[i]
    a = work[2 + n + 2 * nx : 3 + n + 2 * nx, :nx]
    a[0, :] = nu[0, :]
    cholesky_solve(L, a.T)
    Kt = work[3 + n + 2 * nx : 3 + 2 * n + 2 * nx, :nx].T
    Kt[:, :] = PHt.T
    cholesky_solve(L, Kt)
    log_density = 0.0
    for i in range(nx):
        log_density -= math.log(L[i, i]) + 0.5 * LOG_2PI + 0.5 * nu[0, i] * a[0, i]
    gain_update(z, P, Kt, PHt, nu[0])
    return log_density


@numba.njit(cache=True)
def gain_update(z: np.ndarray, P: np.ndarray, Kt: np.ndarray, PHt: np.ndarray, nu: np.ndarray) -> None:
    """z += K nu; P -= K (P H^T)^T with K = Kt^T, kept exactly symmetric."""
    n = z.shape[0]
    nx = Kt.shape[0]
    for a in range(n):
        acc = 0.0
        for i in range(nx):
            acc += Kt[i, a] * nu[i]
        z[a] += acc
    for a in range(n):
        for b in range(a + 1):
            acc = 0.0
            for i in range(nx):
                acc += 0.5 * (Kt[i, a] * PHt[b, i] + Kt[i, b] * PHt[a, i])
            P[a, b] -= acc
            if a != b:
                P[b, a] = P[a, b]


@numba.njit(cache=True)
def hermite_row(u0: float, u1: float, d0: float, d1: float, h: float, w: np.ndarray) -> None:
    """The input's Taylor coefficients [u, u', u'', u'''] over one interval, as the plant's integrator forms them."""
    slope = (u1 - u0) / h
    c2 = (3.0 * slope - 2.0 * d0 - d1) / h
    c3 = (d0 + d1 - 2.0 * slope) / (h * h)
    w[0] = u0
    w[1] = d0
    w[2] = 2.0 * c2
    w[3] = 6.0 * c3


@numba.njit(cache=True)
def track(
    coefficients: np.ndarray, terms: np.ndarray, lo: np.ndarray, hi: np.ndarray, gain: np.ndarray, own: np.ndarray, q: np.ndarray,
    state_noise: float, forget: float, h: float,
    systems: np.ndarray, measured: np.ndarray, load: np.ndarray, load_rate: np.ndarray, variance: np.ndarray,
    z: np.ndarray, P: np.ndarray, log_likelihood: np.ndarray,
) -> None:
    """Run every hypothesis's filter of the listed systems over samples 1..L of their step (in place).

    Args:
        coefficients: (H, K, nx, nx + 4) Chebyshev coefficients of [Phi | Gamma] per hypothesis; terms (H,): how many are used.
        lo, hi: (H,) the interpolants' ranges; gain (H, nx), own (H,): the measurement of ``correct``.
        q: (H, 2) process-noise variances per sample of theta and drift.
        state_noise: each state's process-noise variance per sample, as a multiple of its measurement's variance / g^2.
        forget: factor on the log-likelihoods per sample.
        systems: (S,) rows of z, P, log_likelihood that ``measured`` etc. (S, ...) belong to.
        measured: (S, nx, L + 1); load, load_rate: (S, L + 1); variance: (S, nx) measurement noise variances.
        z: (N, H, nx + 2); P: (N, H, nx + 2, nx + 2); log_likelihood: (N, H).
    """
    n_hyp = coefficients.shape[0]
    nx = measured.shape[1]
    n = nx + 2
    M = np.empty(coefficients.shape[2:])
    M0 = np.empty(coefficients.shape[2:])
    dM = np.empty(coefficients.shape[2:])
    w = np.empty(4)
    F = np.empty((n, n))
    T = np.empty((n, n))
    qf = np.empty(n)
    work = np.empty((4 * n, n))
    basis = np.empty((2, coefficients.shape[1]))
    for s in range(systems.shape[0]):
        row = systems[s]
        for f in range(n_hyp):
            zf = z[row, f]
            Pf = P[row, f]
            qf[nx] = q[f, 0]
            qf[nx + 1] = q[f, 1]
            # the interpolant at the step's first theta, carried to each sample's theta by its slope:
            # theta moves by parts per thousand over a step, a second-order error of ~1e-8 in Phi
            anchor = zf[nx]
            chebyshev_matrices(coefficients[f], terms[f], lo[f], hi[f], anchor, M0, dM, basis)
            for k in range(1, measured.shape[2]):
                shift = zf[nx] - anchor
                for i in range(nx):
                    for j in range(coefficients.shape[3]):
                        M[i, j] = M0[i, j] + dM[i, j] * shift
                for i in range(nx):
                    g = 1.0 / zf[nx] if i == own[f] else gain[f, i]
                    qf[i] = state_noise * variance[s, i] / (g * g)
                hermite_row(load[s, k - 1], load[s, k], load_rate[s, k - 1], load_rate[s, k], h, w)
                predict(zf, Pf, M, dM, w, h, qf, F, T)
                density = correct(zf, Pf, measured[s, :, k], variance[s], gain[f], own[f], work)
                log_likelihood[row, f] = forget * log_likelihood[row, f] + density
