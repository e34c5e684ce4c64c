"""The plant's exact discretization run forward (``ea_gym._kernels.propagation``): x[k + 1] = Phi x[k] +
Gamma w[k], w the input's cubic Hermite (Taylor) coefficients over each interval (``reference.tracking.
hermite_row``). The kernels sum each product in another order: equal to ~1e-12 relative."""

from __future__ import annotations

import numpy as np

from ea_gym._kernels.reference.tracking import hermite_row


def propagate_states(Phi: np.ndarray, Gamma: np.ndarray, w: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """States (N, T + 1, nx) of x[k + 1] = Phi[s, k] x[k] + Gamma[s, k] w[s, k] from x0[s]; a length-1 time
    axis of Phi and Gamma means constant matrices."""
    x = np.empty((w.shape[0], w.shape[1] + 1, x0.shape[1]))
    x[:, 0] = x0
    for k in range(w.shape[1]):
        kp = k if Phi.shape[1] > 1 else 0
        x[:, k + 1] = (Phi[:, kp] @ x[:, k, :, None])[..., 0] + (Gamma[:, kp] @ w[:, k, :, None])[..., 0]
    return x


def simulate_hermite(
    Phi: np.ndarray, Gamma: np.ndarray, index: np.ndarray, u: np.ndarray, du: np.ndarray, inputs: np.ndarray, h: float, x0: np.ndarray,
    gain: np.ndarray, signals: np.ndarray, last: np.ndarray,
) -> None:
    """``propagate_states`` of system s with Phi[index[s]], Gamma[index[s]], driven by u[inputs[s]],
    du[inputs[s]]: gain x the states at every sample into signals (N, nx, T), the last states into last (N, nx)."""
    u, du = u[inputs], du[inputs]
    w = np.concatenate(hermite_row(u[:, :-1], u[:, 1:], du[:, :-1], du[:, 1:], h), axis=-1)
    x = propagate_states(Phi[index][:, None], Gamma[index][:, None], w, x0)
    signals[:] = x.transpose(0, 2, 1) * gain[:, :, None]
    last[:] = x[:, -1]
