"""The joint filter's samples (``ea_gym.phm.joint``): one extended Kalman filter per system over the
energy variables, every degradable parameter and its drift, compiled system by system.

The arithmetic is the reference's with explicit sums over small matrices (n = nx + 2 D: 8 on the
spring-mass-damper) and the innovation covariance S inverted once per sample, so the kernel meets the
reference to ~1e-10 relative. A step of 100 samples costs tens of microseconds per system instead of the
reference's some twenty numpy calls per sample.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.joint``.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, error_model="numpy", inline="always")
def _product(A: np.ndarray, B: np.ndarray, transposed: bool, out: np.ndarray) -> None:
    """out = A B, or A B^T where ``transposed``."""
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            value = 0.0
            for c in range(A.shape[1]):
                value += A[i, c] * (B[j, c] if transposed else B[c, j])
            out[i, j] = value


@numba.njit(cache=True, error_model="numpy")
def _predict(
    M0: np.ndarray, dM: np.ndarray, anchor: np.ndarray, w: np.ndarray, drift_time: float, Q: np.ndarray, x: np.ndarray, P: np.ndarray,
    M: np.ndarray, F: np.ndarray, FP: np.ndarray,
) -> None:
    """One system's prediction over one sample (x, P in place): x = M(theta) [x; w], theta += drift_time drift,
    P = F P F^T + Q; M, F and FP its workspaces."""
    nx, d = M0.shape[0], anchor.shape[0]
    M[:, :] = M0
    for p in range(d):
        M += (x[nx + p] - anchor[p]) * dM[p]
    xw = np.concatenate((x[:nx], w))
    F[:, :] = np.eye(nx + 2 * d)
    F[:nx, :nx] = M[:, :nx]
    for p in range(d):
        F[:nx, nx + p] = dM[p] @ xw
        F[nx + p, nx + d + p] = drift_time
    x[:nx] = M @ xw
    x[nx : nx + d] += drift_time * x[nx + d :]
    _product(F, P, False, FP)
    _product(FP, F, True, P)
    P += Q


@numba.njit(cache=True, error_model="numpy")
def _update(
    z: np.ndarray, variance: np.ndarray, momenta: np.ndarray, inertia: np.ndarray, lo: np.ndarray, hi: np.ndarray, x: np.ndarray,
    P: np.ndarray, y: np.ndarray, S: np.ndarray, H: np.ndarray, PHt: np.ndarray, K: np.ndarray, KPHt: np.ndarray,
) -> None:
    """One system's update from one sample's measurements ``z`` (nx,) (x, P in place; y and S, the innovation
    and its covariance, written); H, PHt, K and KPHt its workspaces."""
    nx, d = z.shape[0], lo.shape[0]
    H[:, :] = 0.0
    for i in range(nx):
        H[i, i] = 1.0
    y[:] = z - x[:nx]
    for k in range(momenta.shape[0]):
        i, j = momenta[k, 0], momenta[k, 1]
        inertia_k = x[nx + j] if j >= 0 else inertia[k]
        H[i, i] = 1.0 / inertia_k
        if j >= 0:
            H[i, nx + j] = -x[i] / inertia_k**2
        y[i] = z[i] - x[i] / inertia_k
    _product(P, H, True, PHt)
    _product(H, PHt, False, S)
    for i in range(nx):
        S[i, i] += variance[i]
    _product(PHt, np.linalg.inv(S), False, K)
    x += K @ y
    # P - K S K^T = P - K (P H^T)^T, symmetrised
    _product(K, PHt, True, KPHt)
    for a in range(P.shape[0]):
        for b in range(a, P.shape[0]):
            P[a, b] = P[b, a] = 0.5 * ((P[a, b] - KPHt[a, b]) + (P[b, a] - KPHt[b, a]))
    for p in range(d):
        x[nx + p] = min(max(x[nx + p], lo[p]), hi[p])


@numba.njit(cache=True, error_model="numpy")
def joint_samples(
    M0: np.ndarray, dM: np.ndarray, anchor: np.ndarray, w: np.ndarray, drift_time: np.ndarray, Q: np.ndarray, measured: np.ndarray,
    variance: np.ndarray, momenta: np.ndarray, inertia: np.ndarray, lo: np.ndarray, hi: np.ndarray, x: np.ndarray, P: np.ndarray,
    innovation: np.ndarray, innovation_covariance: np.ndarray,
) -> None:
    """Every system's filter over samples 1..L of one step; the arguments as the reference's
    (``ea_gym._kernels.reference.joint.joint_samples``)."""
    nx, columns, n = M0.shape[1], M0.shape[2], x.shape[1]
    M, F, FP = np.empty((nx, columns)), np.empty((n, n)), np.empty((n, n))
    H, PHt, K, KPHt = np.empty((nx, n)), np.empty((n, nx)), np.empty((n, nx)), np.empty((n, n))
    for m in range(M0.shape[0]):
        for k in range(w.shape[1]):
            _predict(M0[m], dM[m], anchor[m], w[m, k], drift_time[m], Q[m], x[m], P[m], M, F, FP)
            _update(
                measured[m, :, k + 1], variance[m], momenta, inertia, lo, hi, x[m], P[m], innovation[m, k], innovation_covariance[m, k],
                H, PHt, K, KPHt,
            )
