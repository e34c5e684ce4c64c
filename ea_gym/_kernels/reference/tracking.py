"""The tracking filter bank (``ea_gym._kernels.tracking``): one extended Kalman filter per (system,
hypothesis) over z = [x, theta, drift], in matrix form. The kernel runs the same filters lane by lane in
another order of sums, so it meets ``track_filters`` and ``track_step`` to ~1e-10 relative; the steps
around the filters (``measurement_variance``, ``start_filters``, ``carry_filters``) to the bit."""

from __future__ import annotations

from typing import TypeVar

import numpy as np
from numpy.polynomial import chebyshev

from ea_gym._kernels.filter_records import FilterBank, FilterSettings, FilterStates, TrackedSignals, TrackOutputs
from ea_gym._kernels.tracking import VARIANCE_FLOOR

#: a float, or arrays of them elementwise
Values = TypeVar("Values", float, np.ndarray)


def chebyshev_matrices(
    coefficients: np.ndarray, terms: int, lo: float, hi: float, theta: float, value: np.ndarray, slope: np.ndarray, basis: np.ndarray
) -> None:
    """value = sum_k c_k T_k(s) over the first ``terms`` coefficients (K, rows, cols), slope its derivative in
    theta, s = theta mapped from [lo, hi] to [-1, 1] and clamped there; ``basis``, the kernel's workspace, unused."""
    width = hi - lo
    s = np.clip((2.0 * theta - (lo + hi)) / width, -1.0, 1.0) if width > 0 else 0.0
    c = coefficients[:terms]
    value[:] = chebyshev.chebval(s, c)
    slope[:] = chebyshev.chebval(s, chebyshev.chebder(c, axis=0)) * 2.0 / width if terms > 1 else 0.0


def measurement_variance(
    measured: np.ndarray, noise_variance: float, squares: np.ndarray, scratch: object, out: np.ndarray
) -> None:
    """Each channel's noise variance of one system's step (nx, L + 1): noise_variance x its clean mean
    square, from the noisy one, at least ``VARIANCE_FLOOR``; the workspaces are unused."""
    mean_square = np.array([np.sum(row * row) for row in measured]) / measured.shape[1]
    out[:] = np.maximum(noise_variance * mean_square / (1.0 + noise_variance), VARIANCE_FLOOR)


def start_filters(
    first: np.ndarray, variance: np.ndarray, gain: np.ndarray, nominal: np.ndarray, prior: np.ndarray,
    z: np.ndarray, P: np.ndarray, log_likelihood: np.ndarray,
) -> None:
    """A system's filters at nominal: the states read off the first samples through the gains, with their
    measurement's variance; theta at ``nominal``, no drift, their variances ``prior``."""
    nx = len(first)
    z[:, :nx], z[:, nx], z[:, nx + 1] = first / gain, nominal, 0.0
    P[:] = 0.0
    P[:, np.arange(nx), np.arange(nx)] = variance / (gain * gain)
    P[:, nx, nx], P[:, nx + 1, nx + 1] = prior[:, 0], prior[:, 1]
    log_likelihood[:] = 0.0


def carry_filters(gap: float, lo: np.ndarray, hi: np.ndarray, q: np.ndarray, h: float, z: np.ndarray, P: np.ndarray) -> None:
    """A system's filters carried over ``gap`` s without signals: theta += drift gap in [lo, hi]; P = J P J^T
    (J the identity but J[theta, drift] = gap) plus the random walks' variance over the gap."""
    nx = z.shape[1] - 2
    z[:, nx] = np.minimum(np.maximum(z[:, nx] + gap * z[:, nx + 1], lo), hi)
    P[:, nx, :] += gap * P[:, nx + 1, :]
    P[:, :, nx] += gap * P[:, :, nx + 1]
    P[:, nx, nx] += gap * q[:, 0] / h
    P[:, nx + 1, nx + 1] += gap * q[:, 1] / h


def hermite_row(u0: Values, u1: Values, d0: Values, d1: Values, h: float) -> tuple[Values, Values, Values, Values]:
    """The input's Taylor coefficients (value, first to third derivative) over an interval of the cubic
    Hermite interpolant between values u0, u1 with slopes d0, d1 (elementwise on arrays too)."""
    slope = (u1 - u0) / h
    return u0, d0, 2.0 * ((3.0 * slope - 2.0 * d0 - d1) / h), 6.0 * ((d0 + d1 - 2.0 * slope) / (h * h))


def filter_sample(
    bank: FilterBank, f: int, settings: FilterSettings, drift_time: float, M: np.ndarray, dM: np.ndarray, w: np.ndarray, y: np.ndarray,
    variance: np.ndarray, z: np.ndarray, P: np.ndarray,
) -> tuple[float, float]:
    """Filter f's prediction over one interval and update from the sample's measurements y (in place), M
    its [Phi | Gamma] at its theta and dM its theta-slope; the innovations' log-density and their
    normalized squares' sum. The channels update in turn, each linearised where the previous left the state."""
    nx = len(y)
    hyp = bank.hypotheses
    g = hyp.gain[f].copy()
    if hyp.own[f] >= 0:
        g[hyp.own[f]] = 1.0 / z[nx]
    F = np.zeros((nx + 2, nx + 2))
    F[:nx, :nx] = M[:, :nx]
    F[:nx, nx] = dM[:, :nx] @ z[:nx] + dM[:, nx:] @ w
    F[nx, nx] = F[nx + 1, nx + 1] = 1.0
    F[nx, nx + 1] = drift_time
    z[:nx] = M[:, :nx] @ z[:nx] + M[:, nx:] @ w
    z[nx] += drift_time * z[nx + 1]
    P[:] = F @ P @ F.T + np.diag(np.concatenate([settings.state_noise * variance / g**2, bank.process_noise[f]]))
    density, squares = 0.0, 0.0
    for i in range(nx):
        H = np.zeros(nx + 2)
        H[i] = hyp.gain[f, i]
        if i == hyp.own[f]:
            H[i], H[nx] = 1.0 / z[nx], -z[i] / z[nx] ** 2
        innovation = y[i] - H[i] * z[i]
        S = H @ P @ H + variance[i]
        K = P @ H / S
        density -= 0.5 * (np.log(S) + np.log(2.0 * np.pi) + innovation**2 / S)
        squares += innovation**2 / S
        z += K * innovation
        P -= np.outer(K, K) * S
    z[nx] = np.clip(z[nx], hyp.lo[f], hyp.hi[f])
    return density, squares


def track_filters(
    bank: FilterBank, settings: FilterSettings, drift_time: np.ndarray, offset: int, signals: TrackedSignals, variance: np.ndarray,
    filters: FilterStates, states: tuple[float, ...], inputs: tuple[float, ...],
) -> None:
    """Every hypothesis's filter of systems offset, offset + 1, ... over samples 1..L (in place): x' = M [x; w]
    with M = M0 + dM (theta - anchor), [Phi | Gamma] and its theta-slope read off the interpolant at the
    step's first theta (the anchor); theta' = theta + drift_time drift; each sample's log-density added to
    the log-likelihood decayed by ``forget``, its normalized innovations squared summed over the step into
    ``filters.nis``. ``states`` and ``inputs`` (the kernel's sizes) are unused."""
    nx = signals.measured.shape[1]
    hyp = bank.hypotheses
    for s, f in np.ndindex(len(drift_time), len(hyp.nominal)):
        m = offset + s
        z, P = filters.z[m, f], filters.P[m, f]
        anchor = z[nx]
        rows, columns = hyp.coefficients.shape[2], hyp.coefficients.shape[3]
        M0, dM = np.empty((rows, columns)), np.empty((rows, columns))
        filters.nis[m, f] = 0.0
        chebyshev_matrices(hyp.coefficients[f], hyp.terms[f], hyp.lo[f], hyp.hi[f], anchor, M0, dM, np.empty(0))
        for k in range(1, signals.measured.shape[2]):
            w = np.ones(columns - nx)  # the constant sources' column, where there is one, 1
            w[:4] = hermite_row(signals.load[m, k - 1], signals.load[m, k], signals.load_rate[m, k - 1], signals.load_rate[m, k], settings.h)
            M = M0 + dM * (z[nx] - anchor)
            density, squares = filter_sample(bank, f, settings, drift_time[s], M, dM, w, signals.measured[m, :, k], variance[s], z, P)
            filters.log_likelihood[m, f] = settings.forget * filters.log_likelihood[m, f] + density
            filters.nis[m, f] += squares


def track_step(
    bank: FilterBank, settings: FilterSettings, start: int, stop: int, signals: TrackedSignals, filters: FilterStates,
    outputs: TrackOutputs, states: tuple[float, ...], inputs: tuple[float, ...],
) -> None:
    """One step of systems [start, stop): each system's measurement noise, its filters started (a fresh
    system) or carried over the time its step stands for beyond its signals (theta then holds over the
    signals), the filters over the samples, and the estimates (6, N, D) and evidence (N, H) read off them."""
    measured, t, h = signals.measured, signals.t, settings.h
    nx, samples = measured.shape[1], measured.shape[2]
    variance = np.empty((stop - start, nx))
    drift_time = np.full(stop - start, h)
    for s, m in enumerate(range(start, stop)):
        measurement_variance(measured[m], settings.noise_variance, np.empty(0), (), variance[s])
        if not filters.started[m]:
            hyp = bank.hypotheses
            start_filters(measured[m, :, 0], variance[s], hyp.gain, hyp.nominal, bank.prior, filters.z[m], filters.P[m], filters.log_likelihood[m])
            filters.started[m] = True
        elif t[m] - filters.clock[m] > (samples - 1) * h * (1.0 + 1e-9):
            carry_filters(t[m] - filters.clock[m], bank.hypotheses.lo, bank.hypotheses.hi, bank.process_noise, h, filters.z[m], filters.P[m])
            drift_time[s] = 0.0
        filters.clock[m] = t[m]
    track_filters(bank, settings, drift_time, start, signals, variance, filters, states, inputs)
    part = slice(start, stop)
    z, P = filters.z[part, 1:], filters.P[part, 1:]
    time = np.broadcast_to(t[part, None], z[..., nx].shape)
    outputs.estimates[:, part] = z[..., nx], P[..., nx, nx], z[..., nx + 1], P[..., nx + 1, nx + 1], P[..., nx, nx + 1], time
    outputs.evidence[part] = filters.log_likelihood[part]
