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


#: Filters run side by side, one system per lane: their loops (lanes innermost) fill the SIMD lanes.
LANES = 32


@numba.njit(cache=True)
def predict(
    Z: np.ndarray, P: np.ndarray, M: np.ndarray, dM: np.ndarray, W: np.ndarray, ht: np.ndarray, Q: np.ndarray,
    F: np.ndarray, T: np.ndarray, lanes: int,
) -> None:
    """Time update of a block of filters over one interval, in place; every array has a last, lane axis.

    Z: (n, B) states [x, theta, drift]; P: (n, n, B); M = [Phi | Gamma] (nx, nx + 4 or nx + 5, B), dM its
    theta-slope; W: (4 or 5, B) the load's coefficients (then 1 for the constant sources' column); ht: (B,) the drift's time per sample (s: h, or 0
    where the parameter holds over the step); Q: (n, B) process-noise variances. F: (nx, 2, B)
    workspace (the Jacobian's theta column, the new states); T: (n, n, B) workspace. The Jacobian's
    other entries are Phi and the known rows theta' = theta + h drift, drift' = drift.
    """
    n = Z.shape[0]
    nx = n - 2
    for i in range(nx):
        for b in range(lanes):
            F[i, 0, b] = 0.0
            F[i, 1, b] = 0.0
        for j in range(nx):
            for b in range(lanes):
                F[i, 1, b] += M[i, j, b] * Z[j, b]
                F[i, 0, b] += dM[i, j, b] * Z[j, b]
        for j in range(W.shape[0]):
            for b in range(lanes):
                F[i, 1, b] += M[i, nx + j, b] * W[j, b]
                F[i, 0, b] += dM[i, nx + j, b] * W[j, b]
    for b in range(lanes):
        for i in range(nx):
            Z[i, b] = F[i, 1, b]
        Z[nx, b] += ht[b] * Z[nx + 1, b]
    propagate_covariance(P, M, F, ht, Q, T, lanes)


@numba.njit(cache=True)
def propagate_covariance(P: np.ndarray, M: np.ndarray, F: np.ndarray, ht: np.ndarray, Q: np.ndarray, T: np.ndarray, lanes: int) -> None:
    """P = J P J^T + diag(Q) for the Jacobian J of ``predict`` (Phi and theta column F[:, 0] in the state rows)."""
    jacobian_times(P, M, F, ht, T, lanes)  # T = J P, symmetric P: T^T = P J^T
    jacobian_times(T.transpose((1, 0, 2)), M, F, ht, P, lanes)  # P = J T^T = J P J^T
    n = P.shape[0]
    for i in range(n):
        for b in range(lanes):
            P[i, i, b] += Q[i, b]


@numba.njit(cache=True)
def jacobian_times(X: np.ndarray, M: np.ndarray, F: np.ndarray, ht: np.ndarray, out: np.ndarray, lanes: int) -> None:
    """out = J X for every lane, J as in ``propagate_covariance``; X, out: (n, n, B)."""
    n = X.shape[0]
    nx = n - 2
    for i in range(n):
        for j in range(n):
            if i < nx:
                for b in range(lanes):
                    out[i, j, b] = F[i, 0, b] * X[nx, j, b]
                for k in range(nx):
                    for b in range(lanes):
                        out[i, j, b] += M[i, k, b] * X[k, j, b]
            else:
                for b in range(lanes):
                    out[i, j, b] = X[nx, j, b] + ht[b] * X[nx + 1, j, b] if i == nx else X[nx + 1, j, b]


@numba.njit(cache=True)
def correct(Z: np.ndarray, P: np.ndarray, Y: np.ndarray, R: np.ndarray, gain: np.ndarray, own: np.ndarray, work: np.ndarray, lanes: int) -> None:
    """Measurement update of a block of filters from y = g x + noise of variances R (nx, B); the
    innovations' log-densities go to work[n + 4] (B,).

    The noise is independent across channels, so the channels update in turn, each a scalar update
    linearised at the state the previous ones left (exact where y is linear in the state; for the
    momentum read through 1 / theta, one relinearisation on the way): no matrix inverse, and the
    log-density is the sum of the channels' conditional ones. gain: (nx, B) at nominal; own: (B,) the
    state whose gain is 1 / theta instead (-1: none). ``work``: (n + 5, B) scratch: P h, then g, d y / d theta, the innovation,
    the inverse of its variance and the log-density.
    """
    n = Z.shape[0]
    nx = n - 2
    G, D, V, S, L = n, n + 1, n + 2, n + 3, n + 4  # rows of work
    for b in range(lanes):
        work[L, b] = 0.0
    for i in range(nx):
        for b in range(lanes):
            g = 1.0 / Z[nx, b] if i == own[b] else gain[i, b]
            work[G, b] = g
            work[D, b] = -Z[i, b] * g * g if i == own[b] else 0.0
            work[V, b] = Y[i, b] - g * Z[i, b]
        for a in range(n):
            for b in range(lanes):
                work[a, b] = work[G, b] * P[a, i, b] + work[D, b] * P[a, nx, b]
        for b in range(lanes):
            variance = work[G, b] * work[i, b] + work[D, b] * work[nx, b] + R[i, b]
            work[S, b] = 1.0 / variance  # kept as its inverse: one division, then products
            work[V, b] *= work[S, b]  # the innovation over its variance
            work[L, b] -= 0.5 * (math.log(variance) + LOG_2PI + work[V, b] * work[V, b] * variance)
        for a in range(n):
            for b in range(lanes):
                Z[a, b] += work[a, b] * work[V, b]
            for c in range(a + 1):
                for b in range(lanes):
                    P[a, c, b] -= work[a, b] * work[S, b] * work[c, b]
                    P[c, a, b] = P[a, c, b]


@numba.njit(cache=True)
def hermite_row(u0: float, u1: float, d0: float, d1: float, h: float, w: np.ndarray) -> None:
    """The input's Taylor coefficients (value, first to third derivative) over one interval, as the plant's integrator forms them."""
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
    state_noise: float, forget: float, h: float, drift_time: np.ndarray,
    systems: np.ndarray, measured: np.ndarray, load: np.ndarray, load_rate: np.ndarray, variance: np.ndarray,
    z: np.ndarray, P: np.ndarray, log_likelihood: np.ndarray,
) -> None:
    """Run every hypothesis's filter of the listed systems over samples 1..L of their step (in place).

    The S x H filters run LANES at a time, filter (s, f) in lane s H + f of the list.

    Args:
        coefficients: (H, K, nx, nx + 4 or 5) Chebyshev coefficients of ``transition``'s [Phi | Gamma] per hypothesis;
            terms (H,): how many are used.
        lo, hi: (H,) the interpolants' ranges; gain (H, nx), own (H,): the measurement of ``correct``.
        q: (H, 2) process-noise variances per sample of theta and drift.
        state_noise: each state's process-noise variance per sample, as a multiple of its measurement's variance / g^2.
        forget: factor on the log-likelihoods per sample.
        h: sample period (s); drift_time: (S,) how far theta drifts per sample (s): h, or 0 where the
            parameter holds over the step (it moves between steps instead).
        systems: (S,) rows of z, P, log_likelihood that ``measured`` etc. (S, ...) belong to.
        measured: (S, nx, L + 1); load, load_rate: (S, L + 1); variance: (S, nx) measurement noise variances.
        z: (N, H, nx + 2); P: (N, H, nx + 2, nx + 2); log_likelihood: (N, H).
    """
    n_filters = systems.shape[0] * coefficients.shape[0]
    B = max(1, min(LANES, n_filters))
    nx = measured.shape[1]
    n = nx + 2
    cols = coefficients.shape[3]
    # the block's copies, lanes last
    Z, PP, Q = np.empty((n, B)), np.empty((n, n, B)), np.zeros((n, B))
    M0, dM = np.empty((nx, cols, B)), np.empty((nx, cols, B))
    G, R, bounds, anchor, own_lane = np.empty((nx, B)), np.empty((nx, B)), np.empty((2, B)), np.empty(B), np.empty(B, dtype=np.int64)
    ht = np.empty(B)
    value, slope, basis = np.empty((nx, cols)), np.empty((nx, cols)), np.empty((2, coefficients.shape[1]))
    for first in range(0, n_filters, B):
        lanes = min(B, n_filters - first)
        for b in range(lanes):
            s, f = divmod(first + b, coefficients.shape[0])
            row = systems[s]
            Z[:, b] = z[row, f]
            PP[:, :, b] = P[row, f]
            # the interpolant at the step's first theta, carried to each sample's theta by its slope:
            # theta moves by parts per thousand over a step, a second-order error of ~1e-8 in Phi
            anchor[b] = z[row, f, nx]
            chebyshev_matrices(coefficients[f], terms[f], lo[f], hi[f], anchor[b], value, slope, basis)
            M0[:, :, b] = value
            dM[:, :, b] = slope
            G[:, b] = gain[f]
            R[:, b] = variance[s]
            own_lane[b] = own[f]
            bounds[0, b], bounds[1, b] = lo[f], hi[f]
            ht[b] = drift_time[s]
            Q[nx, b], Q[nx + 1, b] = q[f, 0], q[f, 1]
        density = track_block(
            Z, PP, Q, M0, dM, anchor, G, own_lane, R, bounds, state_noise, h, ht, first, coefficients.shape[0], measured, load, load_rate, lanes
        )
        for b in range(lanes):
            s, f = divmod(first + b, coefficients.shape[0])
            row = systems[s]
            z[row, f] = Z[:, b]
            P[row, f] = PP[:, :, b]
            likelihood = log_likelihood[row, f]
            for k in range(1, measured.shape[2]):
                likelihood = forget * likelihood + density[k, b]
            log_likelihood[row, f] = likelihood


@numba.njit(cache=True)
def track_block(
    Z: np.ndarray, P: np.ndarray, Q: np.ndarray, M0: np.ndarray, dM: np.ndarray, anchor: np.ndarray, G: np.ndarray, own: np.ndarray,
    R: np.ndarray, bounds: np.ndarray, state_noise: float, h: float, ht: np.ndarray, first: int, n_hyp: int,
    measured: np.ndarray, load: np.ndarray, load_rate: np.ndarray, lanes: int,
) -> np.ndarray:
    """A block of filters (lanes last; lane b is filter first + b of ``track``'s list) over the step, in place.

    Returns each sample's innovation log-density per lane, (L + 1, B) (row 0 unused).
    """
    n, B = Z.shape
    nx = n - 2
    cols = M0.shape[1]
    # the load's four Taylor coefficients, then 1 for the constant sources' column where there is one
    M, W, Y = np.empty((nx, cols, B)), np.ones((cols - nx, B)), np.empty((nx, B))
    F, T, work = np.empty((nx, 2, B)), np.empty((n, n, B)), np.empty((n + 5, B))
    density = np.zeros((measured.shape[2], B))
    for k in range(1, measured.shape[2]):
        for b in range(lanes):
            s = (first + b) // n_hyp
            hermite_row(load[s, k - 1], load[s, k], load_rate[s, k - 1], load_rate[s, k], h, W[:, b])
            for i in range(nx):
                Y[i, b] = measured[s, i, k]
                if state_noise > 0.0:
                    g = 1.0 / Z[nx, b] if i == own[b] else G[i, b]
                    Q[i, b] = state_noise * R[i, b] / (g * g)
        for i in range(nx):
            for j in range(cols):
                for b in range(lanes):
                    M[i, j, b] = M0[i, j, b] + dM[i, j, b] * (Z[nx, b] - anchor[b])
        predict(Z, P, M, dM, W, ht, Q, F, T, lanes)
        correct(Z, P, Y, R, G, own, work, lanes)
        for b in range(lanes):
            # theta stays where the model is defined (and positive, for a gain 1 / theta)
            Z[nx, b] = min(bounds[1, b], max(bounds[0, b], Z[nx, b]))
            density[k, b] = work[n + 4, b]
    return density
