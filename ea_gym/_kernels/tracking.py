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


#: Filters run side by side, LANES to a block: their loops (lanes innermost) fill the SIMD lanes.
LANES = 32


@numba.njit(cache=True)
def hermite_row(u0: float, u1: float, d0: float, d1: float, h: float) -> tuple[float, float, float, float]:
    """The input's Taylor coefficients (value, first to third derivative) over one interval, as the plant's integrator forms them."""
    slope = (u1 - u0) / h
    c2 = (3.0 * slope - 2.0 * d0 - d1) / h
    c3 = (d0 + d1 - 2.0 * slope) / (h * h)
    return u0, d0, 2.0 * c2, 6.0 * c3


@numba.njit(cache=True)
def step_inputs(load: np.ndarray, load_rate: np.ndarray, measured: np.ndarray, h: float, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Per sample k and system s, the input's coefficients W (L + 1, width, S) (``hermite_row``'s four over
    interval k, then 1 for the constant sources' column where there is one) and the measurements Y
    (L + 1, nx, S): what each of a system's filters reads, systems last."""
    S, nx, samples = measured.shape
    W = np.ones((samples, width, S))
    Y = np.empty((samples, nx, S))
    for s in range(S):
        for k in range(1, samples):
            W[k, 0, s], W[k, 1, s], W[k, 2, s], W[k, 3, s] = hermite_row(load[s, k - 1], load[s, k], load_rate[s, k - 1], load_rate[s, k], h)
            for i in range(nx):
                Y[k, i, s] = measured[s, i, k]
    return W, Y


@numba.njit(cache=True)
def positive_zero(v: float) -> bool:
    """v is +0.0."""
    return v == 0.0 and math.copysign(1.0, v) > 0.0


@numba.njit(cache=True)
def parameter_fixed(terms: int, q: np.ndarray, own: int, lo: float, hi: float, z: np.ndarray, P: np.ndarray) -> bool:
    """Whether a filter's parameter cannot move over the step: an interpolant of one term (no slope), no
    process noise on it, a measurement that does not read it, theta nonzero and in range, and a drift
    and covariance rows and columns of theta and drift all +0. Its theta, drift and their rows then stay
    as they are, and ``track_block`` may run it over its states alone: the same bits."""
    nx = z.shape[0] - 2
    if terms != 1 or q[0] != 0.0 or q[1] != 0.0 or own >= 0 or z[nx] == 0.0 or not lo <= z[nx] <= hi or not positive_zero(z[nx + 1]):
        return False
    for a in range(nx, nx + 2):
        for c in range(nx + 2):
            if not (positive_zero(P[a, c]) and positive_zero(P[c, a])):
                return False
    return True


@numba.njit(cache=True)
def track(
    coefficients: np.ndarray, terms: np.ndarray, lo: np.ndarray, hi: np.ndarray, gain: np.ndarray, own: np.ndarray, q: np.ndarray,
    state_noise: float, forget: float, h: float, drift_time: np.ndarray,
    systems: np.ndarray, measured: np.ndarray, load: np.ndarray, load_rate: np.ndarray, variance: np.ndarray,
    z: np.ndarray, P: np.ndarray, log_likelihood: np.ndarray,
) -> None:
    """Run every hypothesis's filter of the listed systems over samples 1..L of their step (in place).

    The S x H filters run LANES at a time; those whose parameter is fixed (``parameter_fixed``: the
    "none" hypothesis's) in blocks of their own, over their states alone.

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
    n_hyp = coefficients.shape[0]
    nx = measured.shape[1]
    n = nx + 2
    cols = coefficients.shape[3]
    samples = measured.shape[2]
    W, Y = step_inputs(load, load_rate, measured, h, cols - nx)
    # the filters as (system, hypothesis), those with a fixed parameter last
    listed = np.empty((systems.shape[0] * n_hyp, 2), dtype=np.int64)
    n_full = 0
    n_fixed = 0
    for s in range(systems.shape[0]):
        for f in range(n_hyp):
            if parameter_fixed(terms[f], q[f], own[f], lo[f], hi[f], z[systems[s], f], P[systems[s], f]):
                n_fixed += 1
                listed[-n_fixed, 0], listed[-n_fixed, 1] = s, f
            else:
                listed[n_full, 0], listed[n_full, 1] = s, f
                n_full += 1
    # the block's copies, lanes last
    B = LANES
    Z, PP, Q, T = np.empty((n, B)), np.empty((n, n, B)), np.empty((n, B)), np.empty((n, n, B))
    M0, dM, M = np.empty((nx, cols, B)), np.empty((nx, cols, B)), np.empty((nx, cols, B))
    G, R, bounds, anchor, ht = np.empty((nx, B)), np.empty((nx, B)), np.empty((2, B)), np.empty(B), np.empty(B)
    own_lane, lane_system = np.empty(B, dtype=np.int64), np.empty(B, dtype=np.int64)
    value, slope, basis = np.empty((nx, cols)), np.empty((nx, cols)), np.empty((2, coefficients.shape[1]))
    Wb, Yb, F, work = np.empty((cols - nx, B)), np.empty((nx, B)), np.empty((2, nx, B)), np.empty((n + 5, B))
    density = np.empty((samples, B))
    for first in list(range(0, n_full, B)) + list(range(n_full, listed.shape[0], B)):
        fixed = first >= n_full
        lanes = min(B, (listed.shape[0] if fixed else n_full) - first)
        m = nx if fixed else n  # the rows that move
        for b in range(lanes):
            s, f = listed[first + b]
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
            Q[:nx, b] = 0.0
            Q[nx, b], Q[nx + 1, b] = q[f, 0], q[f, 1]
            lane_system[b] = s
        if fixed:
            # what the full filter's arithmetic gives where dM and theta's rows are +0 and theta stays at the anchor
            F[0] = 0.0
            T[:, nx:] = 0.0
            for i in range(nx):
                for j in range(cols):
                    for b in range(lanes):
                        M[i, j, b] = M0[i, j, b] + 0.0
        for k in range(1, samples):
            for b in range(lanes):
                for j in range(cols - nx):
                    Wb[j, b] = W[k, j, lane_system[b]]
                for i in range(nx):
                    Yb[i, b] = Y[k, i, lane_system[b]]
            if state_noise > 0.0:
                for i in range(nx):
                    for b in range(lanes):
                        g = 1.0 / Z[nx, b] if i == own_lane[b] else G[i, b]
                        Q[i, b] = state_noise * R[i, b] / (g * g)
            if not fixed:
                for b in range(lanes):
                    work[0, b] = Z[nx, b] - anchor[b]
                for i in range(nx):
                    for j in range(cols):
                        for b in range(lanes):
                            M[i, j, b] = M0[i, j, b] + dM[i, j, b] * work[0, b]
            predict(Z, PP, M, dM, Wb, ht, Q, F, T, m, lanes)
            correct(Z, PP, Yb, R, G, own_lane, work, m, lanes)
            for b in range(lanes):
                # theta stays where the model is defined (and positive, for a gain 1 / theta)
                Z[nx, b] = min(bounds[1, b], max(bounds[0, b], Z[nx, b]))
                density[k, b] = work[n + 4, b]
        for b in range(lanes):
            s, f = listed[first + b]
            row = systems[s]
            z[row, f] = Z[:, b]
            P[row, f] = PP[:, :, b]
            likelihood = log_likelihood[row, f]
            for k in range(1, samples):
                likelihood = forget * likelihood + density[k, b]
            log_likelihood[row, f] = likelihood


@numba.njit(cache=True)
def predict(
    Z: np.ndarray, P: np.ndarray, M: np.ndarray, dM: np.ndarray, W: np.ndarray, ht: np.ndarray, Q: np.ndarray,
    F: np.ndarray, T: np.ndarray, m: int, lanes: int,
) -> None:
    """Time update of a block of filters over one interval, in place; every array has a last, lane axis.

    Z: (n, B) states [x, theta, drift]; P: (n, n, B); M = [Phi | Gamma] (nx, nx + 4 or nx + 5, B), dM its
    theta-slope; W: (4 or 5, B) the load's coefficients (then 1 for the constant sources' column); ht: (B,) the drift's time per sample (s: h, or 0
    where the parameter holds over the step); Q: (n, B) process-noise variances. F: (2, nx, B)
    workspace (the Jacobian's theta column, the new states); T: (n, n, B) workspace. The Jacobian's
    other entries are Phi and the known rows theta' = theta + h drift, drift' = drift. Only the first
    m = n or nx rows move (nx: a fixed parameter's filter, F[0] and T's last two columns +0).

    P = J P J^T + diag(Q) as T = J P, then J T^T (P symmetric: T^T = P J^T).
    """
    n = Z.shape[0]
    nx = n - 2
    for i in range(nx):
        for b in range(lanes):
            F[1, i, b] = 0.0
        for j in range(nx):
            for b in range(lanes):
                F[1, i, b] += M[i, j, b] * Z[j, b]
        for j in range(W.shape[0]):
            for b in range(lanes):
                F[1, i, b] += M[i, nx + j, b] * W[j, b]
        if m == n:
            for b in range(lanes):
                F[0, i, b] = 0.0
            for j in range(nx):
                for b in range(lanes):
                    F[0, i, b] += dM[i, j, b] * Z[j, b]
            for j in range(W.shape[0]):
                for b in range(lanes):
                    F[0, i, b] += dM[i, nx + j, b] * W[j, b]
    for i in range(nx):
        for b in range(lanes):
            Z[i, b] = F[1, i, b]
    if m == n:
        for b in range(lanes):
            Z[nx, b] += ht[b] * Z[nx + 1, b]
    for i in range(nx):
        for j in range(m):
            for b in range(lanes):
                T[i, j, b] = F[0, i, b] * P[nx, j, b]
            for k in range(nx):
                for b in range(lanes):
                    T[i, j, b] += M[i, k, b] * P[k, j, b]
    if m == n:
        for j in range(n):
            for b in range(lanes):
                T[nx, j, b] = P[nx, j, b] + ht[b] * P[nx + 1, j, b]
                T[nx + 1, j, b] = P[nx + 1, j, b]
    for i in range(nx):
        for j in range(m):
            for b in range(lanes):
                P[i, j, b] = F[0, i, b] * T[j, nx, b]
            for k in range(nx):
                for b in range(lanes):
                    P[i, j, b] += M[i, k, b] * T[j, k, b]
    if m == n:
        for j in range(n):
            for b in range(lanes):
                P[nx, j, b] = T[j, nx, b] + ht[b] * T[j, nx + 1, b]
                P[nx + 1, j, b] = T[j, nx + 1, b]
    for i in range(m):
        for b in range(lanes):
            P[i, i, b] += Q[i, b]


@numba.njit(cache=True)
def correct(
    Z: np.ndarray, P: np.ndarray, Y: np.ndarray, R: np.ndarray, gain: np.ndarray, own: np.ndarray, work: np.ndarray, m: int, lanes: int
) -> None:
    """Measurement update of a block of filters from y = g x + noise of variances R (nx, B); the
    innovations' log-densities go to work[n + 4] (B,). Only the first m rows move (as in ``predict``).

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
        for a in range(m):
            for b in range(lanes):
                Z[a, b] += work[a, b] * work[V, b]
            for c in range(a + 1):
                for b in range(lanes):
                    P[a, c, b] -= work[a, b] * work[S, b] * work[c, b]
                    P[c, a, b] = P[a, c, b]
