"""The joint filter's samples (``ea_gym._kernels.joint``) in filterpy's x, P, F, H form, vectorised over the
systems. The kernel runs the same filter system by system with explicit sums, S through its Cholesky factor
where this solves with it and the covariances' upper triangles mirrored where this symmetrises, so it
meets ``joint_samples`` to ~1e-10 relative."""

from __future__ import annotations

import numpy as np


def joint_samples(
    M0: np.ndarray, dM: np.ndarray, anchor: np.ndarray, w: np.ndarray, drift_time: np.ndarray, Q: np.ndarray, measured: np.ndarray,
    variance: np.ndarray, momenta: np.ndarray, inertia: np.ndarray, lo: np.ndarray, hi: np.ndarray, x: np.ndarray, P: np.ndarray,
    nis: np.ndarray,
) -> None:
    """Every system's filter over samples 1..L of one step (x, P and nis written in place).

    Args:
        M0: [Phi | Gamma] at the step's anchor, (N, nx, nx + nw); dM: its slope in each parameter, (N, D, nx, nx + nw).
        anchor: the parameters M0 was taken at, (N, D).
        w: the load's Taylor coefficients over each sample (and 1 for constant sources), (N, L, nw).
        drift_time: seconds theta moves by its drift per sample (0 where it holds over the signals), (N,).
        Q: process noise per sample, (N, n, n), n = nx + 2 D.
        measured: the step's measured signals, (N, nx, L + 1); variance: their noise variance, (N, nx).
        momenta: (signal, degradable index or -1) of every I element's flow p / I, (K, 2); inertia: its nominal I, (K,).
        lo, hi: the parameters' bounds, (D,).
        x: [energy variables, theta, drift], (N, n); P: its covariance, (N, n, n).
        nis: the normalized innovations squared y^T S^-1 y summed over the step's samples, (N,).
    """
    n_systems, nx = M0.shape[0], M0.shape[1]
    d = anchor.shape[1]
    thetas, drifts = np.arange(nx, nx + d), np.arange(nx + d, nx + 2 * d)
    nis[:] = 0.0
    for k in range(w.shape[1]):
        # predict: x = M(theta) [x; w], theta += drift_time drift, P = F P F^T + Q
        theta = x[:, nx : nx + d]
        M = M0 + np.einsum("nd,ndij->nij", theta - anchor, dM)
        states = x[:, :nx].copy()
        F = np.repeat(np.eye(x.shape[1])[None], n_systems, axis=0)
        F[:, :nx, :nx] = M[:, :, :nx]
        F[:, :nx, nx : nx + d] = np.einsum("ndij,nj->nid", dM[..., :nx], states) + np.einsum("ndij,nj->nid", dM[..., nx:], w[:, k])
        F[:, thetas, drifts] = drift_time[:, None]
        x[:, :nx] = np.einsum("nij,nj->ni", M[:, :, :nx], states) + np.einsum("nij,nj->ni", M[:, :, nx:], w[:, k])
        x[:, nx : nx + d] += drift_time[:, None] * x[:, nx + d :]
        P[:] = F @ P @ F.transpose(0, 2, 1) + Q
        # update: y = z - h(x), S = H P H^T + R, K = P H^T S^-1; an I element's signal p / I under an estimated I
        inverse = np.ones((n_systems, nx))
        for (i, j), value in zip(momenta, inertia):
            inverse[:, i] = x[:, nx + j] if j >= 0 else value
        predicted = x[:, :nx] / inverse
        H = np.zeros((n_systems, nx, x.shape[1]))
        H[:, np.arange(nx), np.arange(nx)] = 1.0 / inverse
        for i, j in momenta:
            if j >= 0:
                H[:, i, nx + j] = -predicted[:, i] / inverse[:, i]
        y = measured[:, :, k + 1] - predicted
        PHt = P @ H.transpose(0, 2, 1)
        S = H @ PHt
        S[:, np.arange(nx), np.arange(nx)] += variance
        K = np.linalg.solve(S, PHt.transpose(0, 2, 1)).transpose(0, 2, 1)
        x += np.einsum("nij,nj->ni", K, y)
        updated = P - K @ S @ K.transpose(0, 2, 1)
        P[:] = 0.5 * (updated + updated.transpose(0, 2, 1))
        x[:, nx : nx + d] = np.clip(x[:, nx : nx + d], lo, hi)
        nis += np.einsum("ni,ni->n", y, np.linalg.solve(S, y[..., None])[..., 0])
