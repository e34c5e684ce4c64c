"""The joint filter's samples (``ea_gym.phm.joint``): one extended Kalman filter per system over the
energy variables, every degradable parameter and its drift, compiled system by system.

The arithmetic is the reference's with the filter's structure written out instead of its dense products
(n = nx + 2 D: 8 on the spring-mass-damper): the transition F is the identity but for the energy
variables' rows [M_x | dM x] and theta's d / d drift, so F P F^T costs nx (nx + D) n twice instead of n^3;
each measurement row reads its own energy variable and at most one parameter (an I element's flow
p / I), so P H^T, S and K P H^T are sums over those; S (nx x nx, symmetric positive definite) is inverted
through its Cholesky factor. No array is allocated per sample. The kernel meets the reference to ~1e-10
relative. A step of 100 samples costs some tens of microseconds per system; the systems' rows are
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
def _predicted_covariance(M: np.ndarray, B: np.ndarray, drift_time: float, Q: np.ndarray, P: np.ndarray, FP: np.ndarray) -> None:
    """P = F P F^T + Q in place, F the identity but for the energy variables' rows [M_x | B | 0] and theta's
    d / d drift = ``drift_time``; FP its workspace."""
    nx, d, n = M.shape[0], B.shape[1], P.shape[0]
    for j in range(n):  # F P
        for i in range(nx):
            value = 0.0
            for c in range(nx):
                value += M[i, c] * P[c, j]
            for p in range(d):
                value += B[i, p] * P[nx + p, j]
            FP[i, j] = value
        for p in range(d):
            FP[nx + p, j] = P[nx + p, j] + drift_time * P[nx + d + p, j]
            FP[nx + d + p, j] = P[nx + d + p, j]
    for i in range(n):  # (F P) F^T, the same structure from the right
        for j in range(nx):
            value = 0.0
            for c in range(nx):
                value += FP[i, c] * M[j, c]
            for p in range(d):
                value += FP[i, nx + p] * B[j, p]
            P[i, j] = value + Q[i, j]
        for p in range(d):
            P[i, nx + p] = FP[i, nx + p] + drift_time * FP[i, nx + d + p] + Q[i, nx + p]
            P[i, nx + d + p] = FP[i, nx + d + p] + Q[i, nx + d + p]


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
def _symmetric_inverse(S: np.ndarray, L: np.ndarray, inverse: np.ndarray) -> None:
    """S^-1 of the symmetric positive definite S through its Cholesky factor: S = L L^T, S^-1 = L^-T L^-1, into
    L's upper triangle (its diagonal included); ``inverse`` holds L^-1 on the way."""
    nx = S.shape[0]
    for i in range(nx):
        for k in range(i + 1):
            value = 0.5 * (S[i, k] + S[k, i])
            for c in range(k):
                value -= L[i, c] * L[k, c]
            L[i, k] = np.sqrt(value) if i == k else value / L[k, k]
    for k in range(nx):  # L^-1, column by column
        for i in range(nx):
            value = 1.0 if i == k else 0.0
            for c in range(k, i):
                value -= L[i, c] * inverse[c, k]
            inverse[i, k] = value / L[i, i] if i >= k else 0.0
    for i in range(nx):
        for k in range(i, nx):
            value = 0.0
            for c in range(k, nx):
                value += inverse[c, i] * inverse[c, k]
            L[i, k] = value


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _update(
    z: np.ndarray, variance: np.ndarray, parameter: np.ndarray, inertia: np.ndarray, lo: np.ndarray, hi: np.ndarray, x: np.ndarray,
    P: np.ndarray, y: np.ndarray, S: np.ndarray, diagonal: np.ndarray, slope: np.ndarray, PHt: np.ndarray, K: np.ndarray,
    L: np.ndarray, inverse: np.ndarray,
) -> None:
    """One system's update from one sample's measurements ``z`` (nx,) (x, P in place; y and S, the innovation and
    its covariance, written); the measurement rows as ``_measurement_rows``'s; PHt, K, L and inverse workspaces."""
    nx, d, n = z.shape[0], lo.shape[0], x.shape[0]
    _measurement_rows(z, parameter, inertia, x, diagonal, slope, y)
    for a in range(n):  # P H^T: column i is diagonal[i] P[:, i] (+ slope[i] P[:, its parameter])
        for i in range(nx):
            PHt[a, i] = diagonal[i] * P[a, i] + (slope[i] * P[a, nx + parameter[i]] if parameter[i] >= 0 else 0.0)
    for i in range(nx):
        for k in range(nx):
            S[i, k] = diagonal[i] * PHt[i, k] + (slope[i] * PHt[nx + parameter[i], k] if parameter[i] >= 0 else 0.0)
        S[i, i] += variance[i]
    _symmetric_inverse(S, L, inverse)
    for a in range(n):  # K = P H^T S^-1, and x += K y
        correction = 0.0
        for k in range(nx):
            value = 0.0
            for i in range(nx):
                value += PHt[a, i] * (L[i, k] if i <= k else L[k, i])
            K[a, k] = value
            correction += value * y[k]
        x[a] += correction
    for a in range(n):  # P - K S K^T = P - K (P H^T)^T, symmetrised
        for b in range(a, n):
            ka, kb = 0.0, 0.0
            for i in range(nx):
                ka += K[a, i] * PHt[b, i]
                kb += K[b, i] * PHt[a, i]
            P[a, b] = P[b, a] = 0.5 * ((P[a, b] - ka) + (P[b, a] - kb))
    for p in range(d):
        x[nx + p] = min(max(x[nx + p], lo[p]), hi[p])


@numba.njit(cache=True, nogil=True, error_model="numpy")
def joint_samples(
    M0: np.ndarray, dM: np.ndarray, anchor: np.ndarray, w: np.ndarray, drift_time: np.ndarray, Q: np.ndarray, measured: np.ndarray,
    variance: np.ndarray, momenta: np.ndarray, inertia: np.ndarray, lo: np.ndarray, hi: np.ndarray, x: np.ndarray, P: np.ndarray,
    innovation: np.ndarray, innovation_covariance: np.ndarray,
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
    M, xw, B, states, FP = np.empty((nx, columns)), np.empty(columns), np.empty((nx, d)), np.empty(nx), np.empty((n, n))
    diagonal, slope, PHt, K = np.empty(nx), np.zeros(nx), np.empty((n, nx)), np.empty((n, nx))
    L, inverse = np.empty((nx, nx)), np.empty((nx, nx))
    for m in range(M0.shape[0]):
        for k in range(w.shape[1]):
            # predict: x = M(theta) [x; w], theta += drift_time drift, P = F P F^T + Q
            _transition_rows(M0[m], dM[m], anchor[m], x[m], w[m, k], M, xw, B, states)
            _predicted_covariance(M, B, drift_time[m], Q[m], P[m], FP)
            for i in range(nx):
                x[m, i] = states[i]
            for p in range(d):
                x[m, nx + p] += drift_time[m] * x[m, nx + d + p]
            _update(
                measured[m, :, k + 1], variance[m], parameter, nominal, lo, hi, x[m], P[m], innovation[m, k], innovation_covariance[m, k],
                diagonal, slope, PHt, K, L, inverse,
            )
