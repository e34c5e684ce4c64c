"""The tracking filter bank: one extended Kalman filter per (system, hypothesis), run over a step's samples.

Filter f's state is z = [x (nx energy variables), theta (the hypothesis's parameter), drift (its rate,
unit/s)]. Between samples x follows the plant's own exact discretization x' = Phi(theta) x + Gamma(theta) w
(w: the input's cubic Hermite coefficients over the interval), read off a Chebyshev interpolant in theta
with its derivative, theta' = theta + h drift, drift' = drift; the measurement is y = g(theta) x (gain
1/theta on the momentum of the hypothesis's own I element). Every filter adds each innovation's
log-density to its log-likelihood, decayed by ``forget`` per sample, and keeps its normalized innovations
squared summed over the step (the model-fit test's statistic, ``ea_gym.phm.fit``).

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.tracking``. The arguments
travel in records (``ea_gym._kernels.filter_records``; ``BlockRows``, ``layout``'s).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from ea_gym._kernels.filter_records import FilterBank, FilterSettings, FilterStates, HypothesisModels, TrackedSignals, TrackOutputs
from ea_gym._kernels.numpy_forms import numpy_maximum, numpy_minimum
from ea_gym._kernels.summation import numpy_sum, summation_scratch

LOG_2PI = math.log(2.0 * math.pi)
#: Smallest measurement noise variance (the channel's unit squared).
VARIANCE_FLOOR = 1e-30


class BlockRows(NamedTuple):
    """Where each quantity's rows start in a block of filters (``layout``), and the rows in all."""

    state: int  # z (n)
    covariance: int  # P (n x n)
    product: int  # T = J P (n x n)
    transition_anchor: int  # M0: [Phi | Gamma] at the anchor (nx x (nx + nw))
    transition_slope: int  # dM: its theta-slope (nx x (nx + nw))
    transition: int  # M = M0 + dM (theta - anchor) (nx x (nx + nw))
    theta_column: int  # F0: the Jacobian's theta column (nx)
    predicted: int  # F1: the predicted states (nx)
    inputs: int  # W: the input's coefficients (nw)
    measured: int  # Y (nx)
    gain: int  # g at nominal (nx)
    noise: int  # R: the measurement noise variances (nx)
    process_noise: int  # Q (n)
    drift_time: int  # ht
    anchor: int  # theta where M0 and dM were read
    lo: int
    hi: int
    own: int
    innovation_variance: int  # each channel's (nx)
    innovation: int  # each channel's, normalised (nx)
    covariance_column: int  # P h (n)
    rows: int


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


#: Filters run side by side, LANES to a block: each sample's arithmetic is one loop over the lanes,
#: which fills the SIMD lanes.
LANES = 16


@numba.njit(cache=True)
def hermite_row(u0: float, u1: float, d0: float, d1: float, h: float) -> tuple[float, float, float, float]:
    """The input's Taylor coefficients (value, first to third derivative) over one interval, as the plant's integrator forms them."""
    slope = (u1 - u0) / h
    c2 = (3.0 * slope - 2.0 * d0 - d1) / h
    c3 = (d0 + d1 - 2.0 * slope) / (h * h)
    return u0, d0, 2.0 * c2, 6.0 * c3


@numba.njit(cache=True)
def positive_zero(v: float) -> bool:
    """v is +0.0."""
    return v == 0.0 and math.copysign(1.0, v) > 0.0


@numba.njit(cache=True)
def parameter_fixed(terms: int, q: np.ndarray, own: int, lo: float, hi: float, z: np.ndarray, P: np.ndarray) -> bool:
    """Whether a filter's parameter cannot move over the step: an interpolant of one term (no slope), no
    process noise on it, a measurement that does not read it, theta nonzero and in range, and a drift
    and covariance rows and columns of theta and drift all +0. The filter's arithmetic then leaves its
    theta, drift and their rows as they are, and its states' is that of a filter over the states alone,
    bit for bit: ``filter_samples`` runs it so."""
    nx = z.shape[0] - 2
    if terms != 1 or q[0] != 0.0 or q[1] != 0.0 or own >= 0 or z[nx] == 0.0 or not lo <= z[nx] <= hi or not positive_zero(z[nx + 1]):
        return False
    for a in range(nx, nx + 2):
        for c in range(nx + 2):
            if not (positive_zero(P[a, c]) and positive_zero(P[c, a])):
                return False
    return True


def track(
    bank: FilterBank, settings: FilterSettings, start: int, stop: int, signals: TrackedSignals, filters: FilterStates, outputs: TrackOutputs
) -> None:
    """One step of systems [start, stop) of N (in place): each system's measurement noise
    (``measurement_variance``), its filters started (``start_filters``) or carried over a step longer than its
    signals (``carry_filters``), every hypothesis's filter over samples 1..L (``track_filters``), and the
    estimates read off them. A system's results do not depend on the others', so parts of the systems run on
    several threads (GIL released).
    """
    nx = signals.measured.shape[1]
    # the sizes as tuple lengths, which the compiled code sees as constants: its loops over them unroll
    states, inputs = (0.0,) * nx, (0.0,) * (bank.hypotheses.coefficients.shape[3] - nx)
    # the records cross into compiled code as plain tuples (``track_step``)
    plain_bank = (tuple(bank.hypotheses), bank.process_noise, bank.prior)
    track_step(plain_bank, tuple(settings), start, stop, tuple(signals), tuple(filters), tuple(outputs), states, inputs)


@numba.njit(cache=True)
def measurement_variance(
    measured: np.ndarray, noise_variance: float, squares: np.ndarray, scratch: tuple[np.ndarray, np.ndarray], out: np.ndarray
) -> None:
    """Each channel's noise variance (nx,) of one system's step (nx, L + 1) into ``out``: noise_variance x
    its clean mean square, from the noisy one (numpy's sum of the squares, to the bit), and at least
    ``VARIANCE_FLOOR`` (a channel at rest, zero signal and zero noise, is exact; the floor keeps its
    update defined). squares: (L + 1,) workspace."""
    samples = measured.shape[1]
    for i in range(measured.shape[0]):
        for k in range(samples):
            squares[k] = measured[i, k] * measured[i, k]
        mean_square = numpy_sum(squares, 0, samples, scratch) / samples
        out[i] = numpy_maximum(noise_variance * mean_square / (1.0 + noise_variance), VARIANCE_FLOOR)


@numba.njit(cache=True)
def start_filters(
    first: np.ndarray, variance: np.ndarray, gain: np.ndarray, nominal: np.ndarray, prior: np.ndarray,
    z: np.ndarray, P: np.ndarray, log_likelihood: np.ndarray,
) -> None:
    """A system's filters (z (H, nx + 2), P (H, nx + 2, nx + 2), log_likelihood (H,)) at nominal: the states
    read off the step's first samples ``first`` (nx,) through the gains (H, nx), with their measurement's
    ``variance`` (nx,); theta at ``nominal`` (H,), no drift, their variances ``prior`` (H, 2)."""
    nx = first.shape[0]
    for f in range(z.shape[0]):
        P[f] = 0.0
        for i in range(nx):
            z[f, i] = first[i] / gain[f, i]
            P[f, i, i] = variance[i] / (gain[f, i] * gain[f, i])
        z[f, nx], z[f, nx + 1] = nominal[f], 0.0
        P[f, nx, nx], P[f, nx + 1, nx + 1] = prior[f, 0], prior[f, 1]
        log_likelihood[f] = 0.0


@numba.njit(cache=True)
def carry_filters(gap: float, lo: np.ndarray, hi: np.ndarray, q: np.ndarray, h: float, z: np.ndarray, P: np.ndarray) -> None:
    """A system's filters (z (H, nx + 2), P (H, nx + 2, nx + 2)) carried over ``gap`` s without signals:
    theta += drift gap (kept in [lo, hi]), with the random walks' variance over the gap (q (H, 2) per
    sample of h s); the states, whose signal goes on, stay. P = J P J^T with J the identity but for
    J[theta, drift] = gap: theta's row, then its column."""
    nx = z.shape[1] - 2
    for f in range(z.shape[0]):
        z[f, nx] = numpy_minimum(numpy_maximum(z[f, nx] + gap * z[f, nx + 1], lo[f]), hi[f])
        for c in range(nx + 2):
            P[f, nx, c] += gap * P[f, nx + 1, c]
        for a in range(nx + 2):
            P[f, a, nx] += gap * P[f, a, nx + 1]
        P[f, nx, nx] += gap * q[f, 0] / h
        P[f, nx + 1, nx + 1] += gap * q[f, 1] / h


@numba.njit(cache=True, nogil=True)
def track_step(
    bank: tuple, settings: tuple, start: int, stop: int, signals: tuple, filters: tuple, outputs: tuple, states: tuple[float, ...],
    inputs: tuple[float, ...],
) -> None:
    """``track``, nx = len(states) and the input's coefficients per sample len(inputs).

    The records come as plain tuples of their fields (or as the records): numba types a plain tuple's
    fields in compiled code and a named tuple's in Python, which cost 3 us a call here (2.7 us of a step's
    ~20 us at N = 1); they are named again here, which costs nothing.
    """
    hypotheses, process_noise, prior = bank
    bank = FilterBank(HypothesisModels(*hypotheses), process_noise, prior)
    settings, filters = FilterSettings(*settings), FilterStates(*filters)
    signals, outputs = TrackedSignals(*signals), TrackOutputs(*outputs)
    measured, t, h = signals.measured, signals.t, settings.h
    started, clock, z, P, log_likelihood, _ = filters
    nx, samples = measured.shape[1], measured.shape[2]
    variance = np.empty((stop - start, nx))
    drift_time = np.empty(stop - start)
    squares, scratch = np.empty(samples), summation_scratch()
    # a step may stand for more (degradation) time than its signals last (the environment's step_seconds >
    # window): the plant's parameters then hold over each window and move between windows, so the
    # filters carry theta over the step's whole span before its signals, not within
    longest = (samples - 1) * h * (1.0 + 1e-9)
    for s in range(stop - start):
        m = start + s
        measurement_variance(measured[m], settings.noise_variance, squares, scratch, variance[s])
        held = False
        if not started[m]:
            start_filters(measured[m, :, 0], variance[s], bank.hypotheses.gain, bank.hypotheses.nominal, bank.prior, z[m], P[m], log_likelihood[m])
            started[m] = True
        elif t[m] - clock[m] > longest:
            carry_filters(t[m] - clock[m], bank.hypotheses.lo, bank.hypotheses.hi, bank.process_noise, h, z[m], P[m])
            held = True
        clock[m] = t[m]
        drift_time[s] = 0.0 if held else h
    track_filters(bank, settings, drift_time, start, signals, variance, filters, states, inputs)
    estimates, evidence = outputs
    for m in range(start, stop):
        for d in range(z.shape[1] - 1):
            estimates[0, m, d], estimates[1, m, d] = z[m, d + 1, nx], P[m, d + 1, nx, nx]
            estimates[2, m, d], estimates[3, m, d] = z[m, d + 1, nx + 1], P[m, d + 1, nx + 1, nx + 1]
            estimates[4, m, d], estimates[5, m, d] = P[m, d + 1, nx, nx + 1], t[m]
        for f in range(z.shape[1]):
            evidence[m, f] = log_likelihood[m, f]


@numba.njit(cache=True)
def track_filters(
    bank: FilterBank, settings: FilterSettings, drift_time: np.ndarray, offset: int, signals: TrackedSignals, variance: np.ndarray,
    filters: FilterStates, states: tuple[float, ...], inputs: tuple[float, ...],
) -> None:
    """Every hypothesis's filter of systems offset, offset + 1, ... (one per entry of drift_time, variance
    (S, nx)) over samples 1..L of their step (in place); drift_time: (S,) how far theta drifts per
    sample (s): h, or 0 where the parameter holds over the step (it moves between steps instead).

    The S x H filters run LANES at a time (``filter_samples``); those whose parameter is fixed
    (``parameter_fixed``: the "none" hypothesis's) in blocks of their own, over their states alone.
    """
    coefficients, terms, lo, hi, gain, own, _ = bank.hypotheses
    q = bank.process_noise
    measured, load, load_rate, _ = signals
    z, P, log_likelihood, nis = filters.z, filters.P, filters.log_likelihood, filters.nis
    state_noise, forget, h = settings.state_noise, settings.forget, settings.h
    n_hyp = coefficients.shape[0]
    nx, nw = len(states), len(inputs)
    n = nx + 2
    samples = measured.shape[2]
    n_systems = drift_time.shape[0]
    # what each of a system's filters reads at sample k: the input's coefficients (``hermite_row``'s
    # four over interval k, then 1 for the constant sources' column where there is one) and the measurements
    W, Y = np.ones((samples, nw, n_systems)), np.empty((samples, nx, n_systems))
    for s in range(n_systems):
        m = offset + s
        for k in range(1, samples):
            W[k, 0, s], W[k, 1, s], W[k, 2, s], W[k, 3, s] = hermite_row(load[m, k - 1], load[m, k], load_rate[m, k - 1], load_rate[m, k], h)
            for i in range(nx):
                Y[k, i, s] = measured[m, i, k]
    # the filters as (system, hypothesis), those with a fixed parameter last
    listed = np.empty((n_systems * n_hyp, 2), dtype=np.int64)
    n_full, n_fixed = 0, 0
    for s in range(n_systems):
        for f in range(n_hyp):
            if parameter_fixed(terms[f], q[f], own[f], lo[f], hi[f], z[offset + s, f], P[offset + s, f]):
                n_fixed += 1
                listed[-n_fixed, 0], listed[-n_fixed, 1] = s, f
            else:
                listed[n_full, 0], listed[n_full, 1] = s, f
                n_full += 1
    block = np.empty(layout(nx, nw).rows * LANES)
    value, slope, basis = np.empty((nx, nx + nw)), np.empty((nx, nx + nw)), np.empty((2, coefficients.shape[1]))
    lane_system = np.empty(LANES, dtype=np.int64)
    density, squares = np.empty((samples, LANES)), np.empty((samples, LANES))
    for first in list(range(0, n_full, LANES)) + list(range(n_full, listed.shape[0], LANES)):
        fixed = first >= n_full
        lanes = min(LANES, (listed.shape[0] if fixed else n_full) - first)
        for b in range(lanes):
            s, f = listed[first + b]
            lane_system[b] = s
            # the interpolant at the step's first theta, carried to each sample's theta by its slope:
            # theta moves by parts per thousand over a step, a second-order error of ~1e-8 in Phi
            chebyshev_matrices(coefficients[f], terms[f], lo[f], hi[f], z[offset + s, f, nx], value, slope, basis)
            load_lane(block, b, z[offset + s, f], P[offset + s, f], value, slope, gain[f], variance[s], q[f], drift_time[s], lo[f], hi[f], own[f], nw)
        if fixed:
            filter_samples(block, lanes, lane_system, W, Y, state_noise, density, squares, states, states, inputs)
        else:
            filter_samples(block, lanes, lane_system, W, Y, state_noise, density, squares, states, states + (0.0, 0.0), inputs)
        for b in range(lanes):
            s, f = listed[first + b]
            row = offset + s
            for a in range(n):
                z[row, f, a] = block[at(a, b)]
                for c in range(n):
                    P[row, f, a, c] = block[at(n + a * n + c, b)]
            likelihood, total = log_likelihood[row, f], 0.0
            for k in range(1, samples):
                likelihood = forget * likelihood + density[k, b]
                total += squares[k, b]
            log_likelihood[row, f], nis[row, f] = likelihood, total


@numba.njit(cache=True)
def layout(nx: int, nw: int) -> BlockRows:
    """Where each quantity's rows start in a block of filters (each row LANES wide, one lane per filter),
    in ``BlockRows``' order, and the rows in all."""
    n, cols = nx + 2, nx + nw
    state = 0
    covariance = state + n
    product = covariance + n * n
    transition_anchor = product + n * n
    transition_slope = transition_anchor + nx * cols
    transition = transition_slope + nx * cols
    theta_column = transition + nx * cols
    predicted = theta_column + nx
    inputs = predicted + nx
    measured = inputs + nw
    gain = measured + nx
    noise = gain + nx
    process_noise = noise + nx
    drift_time = process_noise + n
    anchor = drift_time + 1
    lo = anchor + 1
    hi = lo + 1
    own = hi + 1
    innovation_variance = own + 1
    innovation = innovation_variance + nx
    covariance_column = innovation + nx
    return BlockRows(
        state, covariance, product, transition_anchor, transition_slope, transition, theta_column, predicted, inputs, measured, gain,
        noise, process_noise, drift_time, anchor, lo, hi, own, innovation_variance, innovation, covariance_column, covariance_column + n,
    )


@numba.njit(cache=True, inline="always")
def at(row: int, b: int) -> np.uint64:
    """Where lane b of a block's row is, unsigned: that spares the index its check for a negative
    value, a branch that keeps the lanes' loop from vectorizing."""
    return numba.uint64(row * LANES + b)


@numba.njit(cache=True)
def load_lane(
    block: np.ndarray, b: int, z: np.ndarray, P: np.ndarray, value: np.ndarray, slope: np.ndarray, gain: np.ndarray, variance: np.ndarray,
    q: np.ndarray, ht: float, lo: float, hi: float, own: int, nw: int,
) -> None:
    """Lane b of a block: a filter's state z and covariance P, its transition at the anchor (value, its
    theta-slope slope) and its settings."""
    n = z.shape[0]
    nx = n - 2
    cols = nx + nw
    rows = layout(nx, nw)
    Z, PP, M0, DM, M = rows.state, rows.covariance, rows.transition_anchor, rows.transition_slope, rows.transition
    G, R, Q = rows.gain, rows.noise, rows.process_noise
    HT, ANCHOR, LO, HI, OWN = rows.drift_time, rows.anchor, rows.lo, rows.hi, rows.own
    for a in range(n):
        block[at(Z + a, b)] = z[a]
        for c in range(n):
            block[at(PP + a * n + c, b)] = P[a, c]
    for i in range(nx):
        for j in range(cols):
            block[at(M0 + i * cols + j, b)] = value[i, j]
            block[at(DM + i * cols + j, b)] = slope[i, j]
            # a fixed parameter's filter keeps the M the full arithmetic gives it: M0 + dM (theta - anchor) = M0 + (+0)
            block[at(M + i * cols + j, b)] = value[i, j] + 0.0
        block[at(G + i, b)] = gain[i]
        block[at(R + i, b)] = variance[i]
        block[at(Q + i, b)] = 0.0
    block[at(Q + nx, b)], block[at(Q + nx + 1, b)] = q[0], q[1]
    block[at(HT, b)], block[at(ANCHOR, b)], block[at(LO, b)], block[at(HI, b)], block[at(OWN, b)] = ht, z[nx], lo, hi, float(own)


@numba.njit(cache=True, error_model="numpy")
def filter_samples(
    block: np.ndarray, lanes: int, lane_system: np.ndarray, W: np.ndarray, Y: np.ndarray, state_noise: float, density: np.ndarray,
    squares: np.ndarray, states: tuple[float, ...], moving: tuple[float, ...], inputs: tuple[float, ...],
) -> None:
    """A block of filters (rows as ``layout`` says; lane b a filter of system lane_system[b]) over
    samples 1..L of W (L + 1, nw, S) and Y (L + 1, nx, S), in place; each sample's innovation
    log-density per lane to density[k, b] and its normalized innovations squared (summed over the
    channels) to squares[k, b].

    A filter's state is z = [x (nx = len(states)), theta, drift]; only the first m = len(moving) rows
    move: n, or nx for a fixed parameter's filter (``parameter_fixed``), on whose other rows the
    arithmetic is the identity. The sizes come as tuple lengths, constants to the compiler: every loop
    but the lanes' unrolls, and the lanes' loop, whose accesses are all to ``block`` at whole rows'
    distance, vectorizes.
    """
    nx, nw = len(states), len(inputs)
    rows = layout(nx, nw)
    WW, YY, VAR, VN = rows.inputs, rows.measured, rows.innovation_variance, rows.innovation
    for k in range(1, W.shape[0]):
        for b in range(lanes):
            s = lane_system[b]
            for j in range(nw):
                block[at(WW + j, b)] = W[k, j, s]
            for i in range(nx):
                block[at(YY + i, b)] = Y[k, i, s]
        predict_states(block, lanes, state_noise, states, moving, inputs)
        propagate_covariance(block, lanes, states, moving, inputs)
        measurement_update(block, lanes, states, moving, inputs)
        for b in range(lanes):  # the log-densities apart: the logarithm is no vector instruction here
            log_density, square = 0.0, 0.0
            for i in range(nx):
                variance, v = block[at(VAR + i, b)], block[at(VN + i, b)]
                normalized = v * v * variance  # innovation^2 / its variance
                log_density -= 0.5 * (math.log(variance) + LOG_2PI + normalized)
                square += normalized
            density[k, b], squares[k, b] = log_density, square


@numba.njit(cache=True, error_model="numpy")
def predict_states(
    block: np.ndarray, lanes: int, state_noise: float, states: tuple[float, ...], moving: tuple[float, ...], inputs: tuple[float, ...]
) -> None:
    """The block's states over one interval: x' = M [x; w] with M = M0 + dM (theta - anchor) ([Phi |
    Gamma] interpolated, dM its theta-slope), theta' = theta + ht drift, drift' = drift; the Jacobian's
    theta column F0 = dM [x; w], and the states' process noise Q: state_noise x R / g^2 (g as in
    ``measurement_update``)."""
    nx, nw, m = len(states), len(inputs), len(moving)
    n, cols = nx + 2, nx + nw
    rows = layout(nx, nw)
    Z, M0, DM, M, F0, F1 = rows.state, rows.transition_anchor, rows.transition_slope, rows.transition, rows.theta_column, rows.predicted
    WW, G, R, Q, HT, ANCHOR, OWN = rows.inputs, rows.gain, rows.noise, rows.process_noise, rows.drift_time, rows.anchor, rows.own
    for b in range(lanes):
        if state_noise > 0.0:
            for i in range(nx):
                g = 1.0 / block[at(Z + nx, b)] if i == block[at(OWN, b)] else block[at(G + i, b)]
                block[at(Q + i, b)] = state_noise * block[at(R + i, b)] / (g * g)
        if m == n:
            delta = block[at(Z + nx, b)] - block[at(ANCHOR, b)]
            for i in range(nx):
                for j in range(cols):
                    block[at(M + i * cols + j, b)] = block[at(M0 + i * cols + j, b)] + block[at(DM + i * cols + j, b)] * delta
        for i in range(nx):
            f1 = 0.0
            for j in range(nx):
                f1 += block[at(M + i * cols + j, b)] * block[at(Z + j, b)]
            for j in range(nw):
                f1 += block[at(M + i * cols + nx + j, b)] * block[at(WW + j, b)]
            block[at(F1 + i, b)] = f1
            if m == n:
                f0 = 0.0
                for j in range(nx):
                    f0 += block[at(DM + i * cols + j, b)] * block[at(Z + j, b)]
                for j in range(nw):
                    f0 += block[at(DM + i * cols + nx + j, b)] * block[at(WW + j, b)]
                block[at(F0 + i, b)] = f0
        for i in range(nx):
            block[at(Z + i, b)] = block[at(F1 + i, b)]
        if m == n:
            block[at(Z + nx, b)] += block[at(HT, b)] * block[at(Z + nx + 1, b)]


@numba.njit(cache=True, error_model="numpy")
def propagate_covariance(block: np.ndarray, lanes: int, states: tuple[float, ...], moving: tuple[float, ...], inputs: tuple[float, ...]) -> None:
    """P = J P J^T + diag(Q) over one interval, J ``predict_states``' Jacobian, as T = J P, then J T^T
    (P symmetric: T^T = P J^T); a fixed parameter's F0 and theta rows are +0."""
    nx, nw, m = len(states), len(inputs), len(moving)
    n, cols = nx + 2, nx + nw
    rows = layout(nx, nw)
    PP, T, M, F0, Q, HT = rows.covariance, rows.product, rows.transition, rows.theta_column, rows.process_noise, rows.drift_time
    for b in range(lanes):
        for i in range(nx):  # T = J P
            for j in range(m):
                t = block[at(F0 + i, b)] * block[at(PP + nx * n + j, b)] if m == n else 0.0
                for c in range(nx):
                    t += block[at(M + i * cols + c, b)] * block[at(PP + c * n + j, b)]
                block[at(T + i * n + j, b)] = t
        if m == n:
            for j in range(n):
                block[at(T + nx * n + j, b)] = block[at(PP + nx * n + j, b)] + block[at(HT, b)] * block[at(PP + (nx + 1) * n + j, b)]
                block[at(T + (nx + 1) * n + j, b)] = block[at(PP + (nx + 1) * n + j, b)]
        for i in range(nx):  # P = J T^T
            for j in range(m):
                p = block[at(F0 + i, b)] * block[at(T + j * n + nx, b)] if m == n else 0.0
                for c in range(nx):
                    p += block[at(M + i * cols + c, b)] * block[at(T + j * n + c, b)]
                block[at(PP + i * n + j, b)] = p
        if m == n:
            for j in range(n):
                block[at(PP + nx * n + j, b)] = block[at(T + j * n + nx, b)] + block[at(HT, b)] * block[at(T + j * n + nx + 1, b)]
                block[at(PP + (nx + 1) * n + j, b)] = block[at(T + j * n + nx + 1, b)]
        for i in range(m):
            block[at(PP + i * n + i, b)] += block[at(Q + i, b)]


@numba.njit(cache=True, error_model="numpy")
def measurement_update(block: np.ndarray, lanes: int, states: tuple[float, ...], moving: tuple[float, ...], inputs: tuple[float, ...]) -> None:
    """The block's filters' update from y = g x + noise of variances R, g the gain at nominal but 1 / theta for
    the state ``own`` (-1: none). The noise is independent across channels, so the channels update in
    turn, each a scalar update linearised at the state the previous ones left (exact where y is linear
    in the state; for the momentum read through 1 / theta, one relinearisation on the way): no matrix
    inverse, and the log-density is the sum of the channels' conditional ones, whose innovation
    variances and normalised innovations it leaves in rows VAR and VN. Theta then stays in [lo, hi],
    where the model is defined (and positive, for a gain 1 / theta)."""
    nx, nw, m = len(states), len(inputs), len(moving)
    n = nx + 2
    rows = layout(nx, nw)
    Z, PP, YY, G, R, LO, HI, OWN = rows.state, rows.covariance, rows.measured, rows.gain, rows.noise, rows.lo, rows.hi, rows.own
    VAR, VN, PH = rows.innovation_variance, rows.innovation, rows.covariance_column
    for b in range(lanes):
        for i in range(nx):
            if i == block[at(OWN, b)]:
                g = 1.0 / block[at(Z + nx, b)]
                d = -block[at(Z + i, b)] * g * g
            else:
                g = block[at(G + i, b)]
                d = 0.0
            v = block[at(YY + i, b)] - g * block[at(Z + i, b)]
            for a in range(n):
                block[at(PH + a, b)] = g * block[at(PP + a * n + i, b)] + d * block[at(PP + a * n + nx, b)]
            variance = g * block[at(PH + i, b)] + d * block[at(PH + nx, b)] + block[at(R + i, b)]
            inverse = 1.0 / variance  # one division, then products
            v *= inverse  # the innovation over its variance
            block[at(VAR + i, b)] = variance
            block[at(VN + i, b)] = v
            for a in range(m):
                block[at(Z + a, b)] += block[at(PH + a, b)] * v
                gain_a = block[at(PH + a, b)] * inverse
                for c in range(a + 1):
                    block[at(PP + a * n + c, b)] -= gain_a * block[at(PH + c, b)]
                    block[at(PP + c * n + a, b)] = block[at(PP + a * n + c, b)]
        if m == n:
            block[at(Z + nx, b)] = min(block[at(HI, b)], max(block[at(LO, b)], block[at(Z + nx, b)]))
