"""The joint filter's samples (``ea_gym.phm.joint``): one extended Kalman filter per system over the
energy variables, every degradable parameter and its drift, compiled system by system.

The arithmetic is the reference's with the filter's structure written out instead of its dense products
(n = nx + 2 D: 8 on the spring-mass-damper): the transition F is the identity but for the energy
variables' rows [M_x | dM x] and theta's d / d drift, so F P F^T is F_E P (nx (nx + D) n) and a few
additions by blocks; each measurement row reads its own energy variable and at most one parameter (an
I element's flow p / I), so P H^T and S are sums over those; S (nx x nx, symmetric positive definite) is
factored, S = L L^T, and the update written with W = P H^T L^-T: x += W L^-1 y, P -= W W^T, each sample's
normalized innovation squared |L^-1 y|^2 summed per system (the model-fit test's statistic). Covariances
are computed in their upper triangles and mirrored, so P stays symmetric to the bit. No array is
allocated per sample. The kernel meets the reference (dense products, symmetrised, S solved with) to
~1e-10 relative. A step of 100 samples costs some tens of microseconds per system; the systems' rows are
independent, and the kernel releases the GIL, so the caller may split them between threads.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.joint``.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _transition_rows(M0: np.ndarray, dM: np.ndarray, anchor: np.ndarray, x: np.ndarray, w: np.ndarray, M: np.ndarray, xw: np.ndarray,
                     B: np.ndarray, states: np.ndarray) -> None:
    """The energy variables' rows of one sample's transition at theta = x's: M = M0 + sum_p (theta_p - anchor_p) dM_p,
    the predicted energy variables ``states`` = M [x; w] (into xw: [x; w]) and the parameter columns B = dM [x; w]."""
    nx, d, columns = M0.shape[0], anchor.shape[0], M0.shape[1]
    for i in range(nx):
        for c in range(columns):
            value = M0[i, c]
            for p in range(d):
                value += (x[nx + p] - anchor[p]) * dM[p, i, c]
            M[i, c] = value
    xw[:nx] = x[:nx]
    xw[nx:] = w
    for i in range(nx):
        value = 0.0
        for c in range(columns):
            value += M[i, c] * xw[c]
        states[i] = value
        for p in range(d):
            value = 0.0
            for c in range(columns):
                value += dM[p, i, c] * xw[c]
            B[i, p] = value


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _predicted_covariance(M: np.ndarray, B: np.ndarray, drift_time: float, Q: np.ndarray, P: np.ndarray, G: np.ndarray) -> None:
    """P = F P F^T + Q in place, F the identity but for the energy variables' rows [M_x | B | 0] and theta's
    d / d drift = ``drift_time``. By blocks (E the energy variables, T theta, R the drift): G = F_E P (G its
    workspace, (nx, n)), P_EE = G_E M_x^T + G_T B^T, P_ET = G_T + drift_time G_R, P_ER = G_R, P_TT = P_TT +
    drift_time (P_TR + P_RT) + drift_time^2 P_RR, P_TR = P_TR + drift_time P_RR, P_RR unchanged; the upper triangle
    computed, the lower its mirror (P and Q symmetric)."""
    nx, d, n = M.shape[0], B.shape[1], P.shape[0]
    for i in range(nx):  # G = F_E P
        for j in range(n):
            value = 0.0
            for c in range(nx):
                value += M[i, c] * P[c, j]
            for p in range(d):
                value += B[i, p] * P[nx + p, j]
            G[i, j] = value
    for p in range(d):  # the parameters' blocks, from P's own entries (the energy rows are not read)
        t, r = nx + p, nx + d + p
        for q in range(p, d):
            u, v = nx + q, nx + d + q
            P[t, u] += drift_time * (P[t, v] + P[r, u]) + drift_time * drift_time * P[r, v] + Q[t, u]
        for q in range(d):
            v = nx + d + q
            P[t, v] += drift_time * P[r, v] + Q[t, v]
        for q in range(p, d):
            P[r, nx + d + q] += Q[r, nx + d + q]
    for i in range(nx):  # the energy variables' rows, from G
        for j in range(i, nx):
            value = 0.0
            for c in range(nx):
                value += G[i, c] * M[j, c]
            for p in range(d):
                value += G[i, nx + p] * B[j, p]
            P[i, j] = value + Q[i, j]
        for p in range(d):
            P[i, nx + p] = G[i, nx + p] + drift_time * G[i, nx + d + p] + Q[i, nx + p]
            P[i, nx + d + p] = G[i, nx + d + p] + Q[i, nx + d + p]
    _mirror_upper(P)


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _mirror_upper(P: np.ndarray) -> None:
    """P's lower triangle from its upper one."""
    for i in range(P.shape[0]):
        for j in range(i):
            P[i, j] = P[j, i]


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _measurement_rows(z: np.ndarray, parameter: np.ndarray, inertia: np.ndarray, x: np.ndarray, diagonal: np.ndarray, slope: np.ndarray,
                      y: np.ndarray) -> None:
    """Signal i reads energy variable i through ``diagonal[i]`` (1, or 1 / I of an I element's flow) and, where
    ``parameter[i]`` >= 0 (its I is estimated), that parameter through ``slope[i]`` (-p / I^2); ``inertia[i]``: the
    nominal I of a flow whose I is not estimated (0: a displacement). Writes those and the innovation y = z - h(x)."""
    nx = z.shape[0]
    for i in range(nx):
        j = parameter[i]
        gain = 1.0 / x[nx + j] if j >= 0 else (1.0 / inertia[i] if inertia[i] > 0.0 else 1.0)
        diagonal[i] = gain
        if j >= 0:
            slope[i] = -x[i] * gain * gain
        y[i] = z[i] - x[i] * gain


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _innovation_cholesky(variance: np.ndarray, parameter: np.ndarray, diagonal: np.ndarray, slope: np.ndarray, PHt: np.ndarray,
                         S: np.ndarray) -> None:
    """The Cholesky factor L of S = H P H^T + R into S's lower triangle, from P H^T (``PHt``) and the measurement
    rows (``_measurement_rows``'s); ``variance``: R's diagonal."""
    nx = S.shape[0]
    for i in range(nx):
        for k in range(i + 1):
            value = diagonal[i] * PHt[i, k] + (slope[i] * PHt[nx + parameter[i], k] if parameter[i] >= 0 else 0.0)
            if k == i:
                value += variance[i]
            for c in range(k):
                value -= S[i, c] * S[k, c]
            S[i, k] = np.sqrt(value) if i == k else value / S[k, k]


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _update(
    z: np.ndarray, variance: np.ndarray, parameter: np.ndarray, inertia: np.ndarray, lo: np.ndarray, hi: np.ndarray, x: np.ndarray,
    P: np.ndarray, y: np.ndarray, S: np.ndarray, diagonal: np.ndarray, slope: np.ndarray, PHt: np.ndarray, W: np.ndarray,
    u: np.ndarray,
) -> float:
    """One system's update from one sample's measurements ``z`` (nx,), x and P in place; returns the sample's
    normalized innovation squared y^T S^-1 y. With S = L L^T (Cholesky), u = L^-1 y and W = P H^T L^-T: the
    gain K = W L^-1, so x += W u, P -= K S K^T = W W^T (symmetric by construction) and y^T S^-1 y = u^T u.
    The measurement rows as ``_measurement_rows``'s; y, S (its Cholesky factor in the lower triangle), PHt,
    W and u workspaces."""
    nx, d, n = z.shape[0], lo.shape[0], x.shape[0]
    _measurement_rows(z, parameter, inertia, x, diagonal, slope, y)
    for a in range(n):  # P H^T: column i is diagonal[i] P[:, i] (+ slope[i] P[:, its parameter])
        for i in range(nx):
            PHt[a, i] = diagonal[i] * P[a, i] + (slope[i] * P[a, nx + parameter[i]] if parameter[i] >= 0 else 0.0)
    _innovation_cholesky(variance, parameter, diagonal, slope, PHt, S)
    nis = 0.0
    for i in range(nx):  # u = L^-1 y
        value = y[i]
        for c in range(i):
            value -= S[i, c] * u[c]
        u[i] = value / S[i, i]
        nis += u[i] * u[i]
    for a in range(n):  # W = P H^T L^-T, row by row; x += W u
        correction = 0.0
        for i in range(nx):
            value = PHt[a, i]
            for c in range(i):
                value -= W[a, c] * S[i, c]
            W[a, i] = value / S[i, i]
            correction += W[a, i] * u[i]
        x[a] += correction
    for a in range(n):  # P -= W W^T
        for b in range(a, n):
            value = 0.0
            for i in range(nx):
                value += W[a, i] * W[b, i]
            P[a, b] -= value
            P[b, a] = P[a, b]
    for p in range(d):
        x[nx + p] = min(max(x[nx + p], lo[p]), hi[p])
    return nis


@numba.njit(cache=True, nogil=True, error_model="numpy")
def joint_samples(
    M0: np.ndarray, dM: np.ndarray, anchor: np.ndarray, w: np.ndarray, drift_time: np.ndarray, Q: np.ndarray, measured: np.ndarray,
    variance: np.ndarray, momenta: np.ndarray, inertia: np.ndarray, lo: np.ndarray, hi: np.ndarray, x: np.ndarray, P: np.ndarray,
    nis: np.ndarray,
) -> None:
    """Every system's filter over samples 1..L of one step; the arguments as the reference's
    (``ea_gym._kernels.reference.joint.joint_samples``)."""
    nx, columns, n = M0.shape[1], M0.shape[2], x.shape[1]
    d = anchor.shape[1]
    # each signal's measurement row: the estimated parameter it reads (-1: none) and the nominal I of a flow whose I is not
    parameter, nominal = np.full(nx, -1, dtype=np.int64), np.zeros(nx)
    for k in range(momenta.shape[0]):
        if momenta[k, 1] >= 0:
            parameter[momenta[k, 0]] = momenta[k, 1]
        else:
            nominal[momenta[k, 0]] = inertia[k]
    M, xw, B, states, G = np.empty((nx, columns)), np.empty(columns), np.empty((nx, d)), np.empty(nx), np.empty((nx, n))
    diagonal, slope, PHt, W = np.empty(nx), np.zeros(nx), np.empty((n, nx)), np.empty((n, nx))
    y, S, u = np.empty(nx), np.empty((nx, nx)), np.empty(nx)
    for m in range(M0.shape[0]):
        total = 0.0
        for k in range(w.shape[1]):
            # predict: x = M(theta) [x; w], theta += drift_time drift, P = F P F^T + Q
            _transition_rows(M0[m], dM[m], anchor[m], x[m], w[m, k], M, xw, B, states)
            _predicted_covariance(M, B, drift_time[m], Q[m], P[m], G)
            for i in range(nx):
                x[m, i] = states[i]
            for p in range(d):
                x[m, nx + p] += drift_time[m] * x[m, nx + d + p]
            total += _update(measured[m, :, k + 1], variance[m], parameter, nominal, lo, hi, x[m], P[m], y, S, diagonal, slope, PHt, W, u)
        nis[m] = total
