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
def chebyshev_matrices(coefficients: np.ndarray, lo: float, hi: float, theta: float, value: np.ndarray, slope: np.ndarray) -> None:
    """value = sum_k c_k T_k(s), slope = its derivative in theta (per unit), s = theta mapped from [lo, hi]
    to [-1, 1] and clamped there (outside, the matrices and slope at the nearer end).

    Args:
        coefficients: (K, rows, cols) Chebyshev coefficients of every matrix entry.
    """
    width = hi - lo
    s = (2.0 * theta - (lo + hi)) / width if width > 0 else 0.0
    s = min(1.0, max(-1.0, s))
    value[:] = 0.0
    slope[:] = 0.0
    t_prev, t_now = 1.0, s
    d_prev, d_now = 0.0, 1.0
    value += coefficients[0]
    scale = 2.0 / width if width > 0 else 0.0
    for k in range(1, coefficients.shape[0]):
        value += coefficients[k] * t_now
        slope += coefficients[k] * (d_now * scale)
        t_prev, t_now = t_now, 2.0 * s * t_now - t_prev
        d_prev, d_now = d_now, 2.0 * t_prev + 2.0 * s * d_now - d_prev


@numba.njit(cache=True)
def predict(
    z: np.ndarray, P: np.ndarray, M: np.ndarray, dM: np.ndarray, w: np.ndarray, h: float, q: np.ndarray, F: np.ndarray, T: np.ndarray
) -> None:
    """Time update of one filter over one interval: z and P in place; M = [Phi | Gamma], dM its theta-slope.

    q: process-noise variances added to the diagonal (n,); F, T: (n, n) workspaces.
    """
    n = z.shape[0]
    nx = n - 2
    m = w.shape[0]
    F[:] = 0.0
    x_new = np.empty(nx)
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
    F[nx, nx] = 1.0
    F[nx, nx + 1] = h
    F[nx + 1, nx + 1] = 1.0
    z[:nx] = x_new
    z[nx] += h * z[nx + 1]
    # P = F P F^T + diag(q)
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += F[i, k] * P[k, j]
            T[i, j] = acc
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += T[i, k] * F[j, k]
            P[i, j] = acc
        P[i, i] += q[i]


@numba.njit(cache=True)
def correct(z: np.ndarray, P: np.ndarray, y: np.ndarray, r: np.ndarray, gain: np.ndarray, own: int) -> float:
    """Measurement update of one filter (Joseph form) from y = g x + noise of variances r; returns the
    innovation's log-density. ``own``: the state whose gain is 1 / theta (-1: none)."""
    n = z.shape[0]
    nx = n - 2
    H = np.zeros((nx, n))
    nu = np.empty(nx)
    for i in range(nx):
        g = gain[i]
        if i == own:
            g = 1.0 / z[nx]
            H[i, nx] = -z[i] * g * g
        H[i, i] = g
        nu[i] = y[i] - g * z[i]
    PHt = P @ H.T
    S = H @ PHt
    for i in range(nx):
        S[i, i] += r[i]
    L = np.linalg.cholesky(S)
    # solve S a = nu and S K^T = H P through the Cholesky factor
    a = np.linalg.solve(L.T, np.linalg.solve(L, nu))
    K = np.linalg.solve(L.T, np.linalg.solve(L, PHt.T)).T
    log_density = 0.0
    for i in range(nx):
        log_density -= math.log(L[i, i]) + 0.5 * LOG_2PI
        log_density -= 0.5 * nu[i] * a[i]
    z += K @ nu
    A = np.eye(n) - K @ H
    KR = K * r
    P[:] = A @ P @ A.T + KR @ K.T
    return log_density


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
    coefficients: np.ndarray, lo: np.ndarray, hi: np.ndarray, gain: np.ndarray, own: np.ndarray, q: np.ndarray,
    state_noise: float, forget: float, h: float,
    systems: np.ndarray, measured: np.ndarray, load: np.ndarray, load_rate: np.ndarray, variance: np.ndarray,
    z: np.ndarray, P: np.ndarray, log_likelihood: np.ndarray,
) -> None:
    """Run every hypothesis's filter of the listed systems over samples 1..L of their step (in place).

    Args:
        coefficients: (H, K, nx, nx + 4) Chebyshev coefficients of [Phi | Gamma] per hypothesis.
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
    dM = np.empty(coefficients.shape[2:])
    w = np.empty(4)
    F = np.empty((n, n))
    T = np.empty((n, n))
    qf = np.empty(n)
    for s in range(systems.shape[0]):
        row = systems[s]
        for f in range(n_hyp):
            zf = z[row, f]
            Pf = P[row, f]
            qf[nx] = q[f, 0]
            qf[nx + 1] = q[f, 1]
            for k in range(1, measured.shape[2]):
                chebyshev_matrices(coefficients[f], lo[f], hi[f], zf[nx], M, dM)
                for i in range(nx):
                    g = 1.0 / zf[nx] if i == own[f] else gain[f, i]
                    qf[i] = state_noise * variance[s, i] / (g * g)
                hermite_row(load[s, k - 1], load[s, k], load_rate[s, k - 1], load_rate[s, k], h, w)
                predict(zf, Pf, M, dM, w, h, qf, F, T)
                density = correct(zf, Pf, measured[s, :, k], variance[s], gain[f], own[f])
                log_likelihood[row, f] = forget * log_likelihood[row, f] + density
