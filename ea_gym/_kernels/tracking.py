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
def correct(z: np.ndarray, P: np.ndarray, y: np.ndarray, r: np.ndarray, gain: np.ndarray, own: int, work: np.ndarray) -> float:
    """Measurement update of one filter from y = g x + noise of variances r; returns the innovation's log-density.

    The noise is independent across channels, so the joint update is the channels' scalar updates in
    turn (the same posterior, and the log-density is the sum of the conditional ones), all linearised
    at the predicted state as the joint update is: no matrix inverse. ``own``: the state whose gain is
    1 / theta (-1: none). ``work``: (3, n) scratch.
    """
    n = z.shape[0]
    nx = n - 2
    prior = work[0]  # the predicted state, where the measurement is linearised
    column = work[1]
    for a in range(n):
        prior[a] = z[a]
    log_density = 0.0
    for i in range(nx):
        g = 1.0 / prior[nx] if i == own else gain[i]
        d = -prior[i] * g * g if i == own else 0.0  # d y_i / d theta
        # the channel's innovation about the state updated so far, through the fixed linearisation
        nu = y[i] - g * prior[i] - g * (z[i] - prior[i]) - d * (z[nx] - prior[nx])
        for a in range(n):
            column[a] = g * P[a, i] + d * P[a, nx]  # P h
        s = g * column[i] + d * column[nx] + r[i]
        log_density -= 0.5 * (math.log(s) + LOG_2PI + nu * nu / s)
        for a in range(n):
            z[a] += column[a] * nu / s
        for a in range(n):
            ka = column[a] / s
            for b in range(a + 1):
                P[a, b] -= ka * column[b]
                P[b, a] = P[a, b]
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
    w = np.empty((measured.shape[2], 4))  # the input's coefficients over each interval, shared by the hypotheses
    F = np.empty((n, n))
    T = np.empty((n, n))
    qf = np.empty(n)
    work = np.empty((3, n))
    basis = np.empty((2, coefficients.shape[1]))
    for s in range(systems.shape[0]):
        row = systems[s]
        for k in range(1, measured.shape[2]):
            hermite_row(load[s, k - 1], load[s, k], load_rate[s, k - 1], load_rate[s, k], h, w[k])
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
                predict(zf, Pf, M, dM, w[k], h, qf, F, T)
                density = correct(zf, Pf, measured[s, :, k], variance[s], gain[f], own[f], work)
                # theta stays where the model is defined (and positive, for a gain 1 / theta)
                zf[nx] = min(hi[f], max(lo[f], zf[nx]))
                log_likelihood[row, f] = forget * log_likelihood[row, f] + density
