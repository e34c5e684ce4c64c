"""The linear recursion x[k+1] = Phi x[k] + Gamma w[k] of an exactly discretized model, many systems
at once: with given input coefficients (``propagate_states``), and with the cubic Hermite input's
coefficients made on the fly and constant matrices per system (``simulate_hermite``).

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.propagation``.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def propagate_states(Phi: np.ndarray, Gamma: np.ndarray, w: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """x[k+1] = Phi[s, k] x[k] + Gamma[s, k] w[s, k] from x0[s] for every system s: states (N, T + 1, nx);
    a length-1 time axis of Phi and Gamma means constant matrices."""
    n_sys, n_steps, nx = w.shape[0], w.shape[1], x0.shape[1]
    m = w.shape[2]
    x = np.empty((n_sys, n_steps + 1, nx))
    for s in range(n_sys):
        x[s, 0] = x0[s]
        for k in range(n_steps):
            kp = k if Phi.shape[1] > 1 else 0
            for i in range(nx):
                acc = 0.0
                for j in range(nx):
                    acc += Phi[s, kp, i, j] * x[s, k, j]
                for j in range(m):
                    acc += Gamma[s, kp, i, j] * w[s, k, j]
                x[s, k + 1, i] = acc
    return x


SYSTEMS_BLOCK = 128  # systems propagated side by side; their lanes are the SIMD axis of the recursion
SAMPLES_CHUNK = 16  # samples of a block's lane-major copies


@numba.njit(cache=True, nogil=True)
def simulate_hermite(
    Phi: np.ndarray, Gamma: np.ndarray, index: np.ndarray, u: np.ndarray, du: np.ndarray, inputs: np.ndarray, h: float, x0: np.ndarray,
    gain: np.ndarray, signals: np.ndarray, last: np.ndarray,
) -> None:
    """``propagate_states`` with constant matrices Phi[index[s]], Gamma[index[s]] for system s, driven by the
    inputs u[inputs[s]], du[inputs[s]], and the Hermite coefficients of
    ``ea_gym.bondgraph.simulation.hermite_coefficients`` computed on the fly, in the same arithmetic (same result).
    Writes gain[s, i] x_i of system s at every sample to signals (N, nx, T) and its states at the
    last sample to last (N, nx).

    One system's recursion is a chain of dependent sums; ``SYSTEMS_BLOCK`` systems run side by side
    with the system innermost, so the chains of different systems fill the SIMD lanes. Every system
    takes the same operations in the same order as alone, so its result does not depend on the batch:
    a batch's rows may be split over threads (``ea_gym.threads.over_rows``).
    """
    n_sys, n_samples, nu = len(index), u.shape[1], u.shape[2]
    nx = Phi.shape[1]
    m = Gamma.shape[2]
    h2 = h * h
    B = min(SYSTEMS_BLOCK, n_sys)
    # lane-major copies, system last, of SAMPLES_CHUNK samples at a time: they stay in the first-level
    # cache, and so do the lines of the system-major arrays that the copies' loops (lanes innermost,
    # twice as fast as samples innermost) stride across
    P = np.empty((nx, nx, B))
    G = np.empty((nx, m, B))
    load = np.empty((SAMPLES_CHUNK + 1, 2, nu, B))
    w = np.empty((m, B))
    X = np.empty((SAMPLES_CHUNK + 1, nx, B))
    for s0 in range(0, n_sys, B):
        lanes = min(B, n_sys - s0)
        start_block(Phi, Gamma, index, x0, gain, s0, lanes, P, G, X, signals)
        for k0 in range(0, n_samples - 1, SAMPLES_CHUNK):
            steps = min(SAMPLES_CHUNK, n_samples - 1 - k0)
            load_chunk(u, du, inputs, s0, k0, steps, lanes, load)
            for k in range(steps):
                hermite_block(load, k, h, h2, lanes, w)
                step_block(P, G, X, k, w, lanes)
            store_chunk(X, gain, s0, k0, steps, lanes, signals)
            X[0] = X[steps]
        for i in range(nx):
            for b in range(lanes):
                last[s0 + b, i] = X[0, i, b]


# the steps of ``simulate_hermite`` on one block of ``lanes`` systems from system s0, inlined into it


@numba.njit(cache=True, inline="always")
def start_block(
    Phi: np.ndarray, Gamma: np.ndarray, index: np.ndarray, x0: np.ndarray, gain: np.ndarray, s0: int, lanes: int,
    P: np.ndarray, G: np.ndarray, X: np.ndarray, signals: np.ndarray,
) -> None:
    """The block's matrices P, G and initial states X[0], lane-major, and its signals at the first sample."""
    nx, m = Phi.shape[1], Gamma.shape[2]
    for b in range(lanes):
        for i in range(nx):
            X[0, i, b] = x0[s0 + b, i]
            signals[s0 + b, i, 0] = x0[s0 + b, i] * gain[s0 + b, i]
            for j in range(nx):
                P[i, j, b] = Phi[index[s0 + b], i, j]
            for j in range(m):
                G[i, j, b] = Gamma[index[s0 + b], i, j]


@numba.njit(cache=True, inline="always")
def load_chunk(u: np.ndarray, du: np.ndarray, inputs: np.ndarray, s0: int, k0: int, steps: int, lanes: int, load: np.ndarray) -> None:
    """load[k, 0 / 1, c, b]: u and du of input c of system s0 + b (row inputs[s0 + b]) at sample k0 + k, for k = 0..steps."""
    nu = u.shape[2]
    for k in range(steps + 1):
        for c in range(nu):
            for b in range(lanes):
                load[k, 0, c, b] = u[inputs[s0 + b], k0 + k, c]
                load[k, 1, c, b] = du[inputs[s0 + b], k0 + k, c]


@numba.njit(cache=True, inline="always")
def hermite_block(load: np.ndarray, k: int, h: float, h2: float, lanes: int, w: np.ndarray) -> None:
    """w (HOLD_ORDER nu, B): the Taylor coefficients of interval k of the loaded inputs, in ``hermite_coefficients``' arithmetic."""
    nu = load.shape[2]
    for c in range(nu):
        for b in range(lanes):
            u0, u1, d0, d1 = load[k, 0, c, b], load[k + 1, 0, c, b], load[k, 1, c, b], load[k + 1, 1, c, b]
            slope = (u1 - u0) / h
            c2 = (3.0 * slope - 2.0 * d0 - d1) / h
            c3 = (d0 + d1 - 2.0 * slope) / h2
            w[c, b] = u0
            w[nu + c, b] = d0
            w[2 * nu + c, b] = 2.0 * c2
            w[3 * nu + c, b] = 6.0 * c3


@numba.njit(cache=True, inline="always")
def step_block(P: np.ndarray, G: np.ndarray, X: np.ndarray, k: int, w: np.ndarray, lanes: int) -> None:
    """X[k + 1] = P X[k] + G w in every lane, summed over the states, then the input coefficients, in order."""
    nx, m = P.shape[0], G.shape[1]
    for i in range(nx):
        acc = X[k + 1, i]
        acc[:lanes] = 0.0
        for j in range(nx):
            for b in range(lanes):
                acc[b] += P[i, j, b] * X[k, j, b]
        for j in range(m):
            for b in range(lanes):
                acc[b] += G[i, j, b] * w[j, b]


@numba.njit(cache=True, inline="always")
def store_chunk(X: np.ndarray, gain: np.ndarray, s0: int, k0: int, steps: int, lanes: int, signals: np.ndarray) -> None:
    """signals at samples k0 + 1..k0 + steps: the gains times the states X[1..steps]."""
    nx = X.shape[1]
    for k in range(1, steps + 1):
        for i in range(nx):
            for b in range(lanes):
                signals[s0 + b, i, k0 + k] = X[k, i, b] * gain[s0 + b, i]
