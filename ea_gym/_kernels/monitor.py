"""The monitor's compiled steps (``ea_gym.diagnosis.monitor.Monitor``): a chunk padded with its smoothing
context, the rows smoothed and differentiated, the elements' nominal-law powers, and the chunk's EA,
energy-balance and noise sums.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.monitor``. The arguments
travel in records (``Smoothing``, ``NominalLaws``, ``EnergyWindows``, ``ChunkSignals``, ``ChunkOutputs``).
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from ea_gym._kernels.activity import trapezoid_area
from ea_gym._kernels.smoothing import LANES, filter_lanes


class Smoothing(NamedTuple):
    """``filter_lanes``' coefficients: the window's moments, the smoothing and the derivative filters."""

    moments: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
    smoother: tuple[np.ndarray, np.ndarray, np.ndarray]
    differentiator: tuple[np.ndarray, np.ndarray, np.ndarray]


class NominalLaws(NamedTuple):
    """The monitored elements' nominal laws (``element_powers``), E elements over nx states."""

    #: (nx,) the factor turning each measured signal into its energy variable.
    scale: np.ndarray
    #: (bonds, nx) and (bonds,): z = Cy x + Dy u, the bond values from the states and the load.
    Cy: np.ndarray
    Dy: np.ndarray
    #: (bonds,) what the constant sources add to each bond value.
    constant: np.ndarray
    #: (E,) each element's effort and flow bond and the sign of its power.
    effort: np.ndarray
    flow: np.ndarray
    sign: np.ndarray
    #: (n_I, 3) (channel, element index, inertance) of each I element; only their laws differentiate.
    inertia: np.ndarray


class EnergyWindows(NamedTuple):
    """How a chunk's samples are summed (``chunk_statistics``)."""

    #: sample period (s).
    h: float
    #: samples per sub-window.
    n_sub: int
    #: sub-windows per balance window.
    n_balance: int
    #: element indices of the components and of the sources.
    components: np.ndarray
    sources: np.ndarray


class ChunkSignals(NamedTuple):
    """A chunk's signals of N systems, L + 1 samples each."""

    #: (N, nx, L + 1) the measured and the reference model's signals.
    measured: np.ndarray
    reference: np.ndarray
    #: (N, L + 1) the source's value.
    load: np.ndarray


class ChunkOutputs(NamedTuple):
    """``monitor_chunk``'s outputs, written for the part's systems."""

    #: (2N, E, n_sub) EA in J, N real then N reference rows.
    ea: np.ndarray
    #: (N, n_balances) the balance residual in J; (N, n_balances, C, C) and (N, n_balances, C) its gram and cross in J^2.
    residual: np.ndarray
    gram: np.ndarray
    cross: np.ndarray
    #: (N, 2, nx) the noise sums.
    noise: np.ndarray
    #: (N, nx, L + 1) the smoothed measured signals.
    signals: np.ndarray


@numba.njit(cache=True)
def copy(source: np.ndarray, start: int, target: np.ndarray, offset: int) -> None:
    """target[offset:] = source[start:] for as many samples as fit."""
    count = min(len(source) - start, len(target) - offset)
    values, into = source[start : start + count], target[offset : offset + count]
    for t in range(count):  # unsigned offsets: a signed index costs a negative-index check at every access
        into[np.uint64(t)] = values[np.uint64(t)]


@numba.njit(cache=True)
def same(a: np.ndarray, b: np.ndarray, start: int) -> bool:
    """Whether a[start:] equals b[start:]."""
    for t in range(start, len(a)):
        if a[t] != b[t]:
            return False
    return True


@numba.njit(cache=True)
def load_sources(rows: np.ndarray, channel: int, skip: int) -> tuple[np.ndarray, np.ndarray]:
    """For each row, the first row whose ``channel`` equals its own from ``skip`` on (itself if none
    does), and the distinct rows: the rows before it and, in a batch of real then reference rows,
    its twin half a batch before are compared, which is where the load repeats."""
    M = rows.shape[0]
    source = np.empty(M, dtype=np.int64)
    distinct = np.empty(M, dtype=np.int64)
    count = 0
    for m in range(M):
        twin = m - M // 2
        if m > 0 and same(rows[m, channel], rows[m - 1, channel], skip):
            source[m] = source[m - 1]
        elif M % 2 == 0 and twin >= 0 and same(rows[m, channel], rows[twin, channel], skip):
            source[m] = source[twin]
        else:
            source[m] = m
            distinct[count] = m
            count += 1
    return source, distinct[:count]


@numba.njit(cache=True)
def smooth_rows(
    rows: np.ndarray, skip: int, cut: int, smoothing: Smoothing, inertia: np.ndarray, smooth: np.ndarray, slope: np.ndarray
) -> None:
    """The filters on rows (M, nx + 1, T): every signal filtered from sample ``skip`` on, outputs from ``cut`` on.

    Args:
        smoothing: the smoothing and derivative filters.
        inertia: (channel, element index, inertance) of each I element; only their laws differentiate.
        smooth, slope: written: the smoothed signals (M, nx + 1, T - skip - cut) and the I elements'
            flow derivatives (M, n_I, T - skip - cut).
    """
    M, channels, T = rows.shape
    length = T - skip
    load = channels - 1
    # the candidates of one system, and a system's real and reference rows, share the source's
    # signal: each distinct one is filtered once
    source, distinct = load_sources(rows, load, skip)
    # the signals to filter, channel after channel: every row's measured ones, then the distinct loads
    count = M * load + len(distinct)
    signal_row, signal_channel = np.empty(count, dtype=np.int64), np.empty(count, dtype=np.int64)
    for c in range(load):
        signal_row[c * M : (c + 1) * M] = np.arange(M)
        signal_channel[c * M : (c + 1) * M] = c
    signal_row[M * load :] = distinct
    signal_channel[M * load :] = load
    differentiated = np.full(channels, -1)  # each channel's I element (index into ``inertia``), -1: none
    for i in range(len(inertia)):
        differentiated[int(inertia[i, 0])] = i
    # LANES signals side by side, time first: the filter's recursion runs across them in SIMD (LANES, a
    # constant, lets the compiler unroll it: fewer lanes where there are fewer signals ran 6 % slower at
    # N = 256); the lanes past the last signal filter stale ones, whose outputs are discarded
    x = np.zeros((length, LANES))
    filtered = np.empty((length, LANES))
    derivative = np.empty((length, LANES))
    for g0 in range(0, count, LANES):
        lanes = min(LANES, count - g0)
        differentiate = False
        # the copies indexed by unsigned offsets: a signed index costs a negative-index check at every access
        for b in range(lanes):
            m, c = signal_row[g0 + b], signal_channel[g0 + b]
            signal, lane = rows[m, c, skip:], np.uint64(b)
            for t in range(length):
                x[np.uint64(t), lane] = signal[np.uint64(t)]
            differentiate |= differentiated[c] >= 0
        filter_lanes(x, cut, smoothing.moments, smoothing.smoother, smoothing.differentiator, differentiate, filtered, derivative)
        for b in range(lanes):
            m, c, lane = signal_row[g0 + b], signal_channel[g0 + b], np.uint64(b)
            out = smooth[m, c]
            for t in range(length - cut):
                out[np.uint64(t)] = filtered[np.uint64(cut + t), lane]
            if differentiated[c] >= 0:
                out = slope[m, differentiated[c]]
                for t in range(length - cut):
                    out[np.uint64(t)] = derivative[np.uint64(cut + t), lane]
    for m in range(M):
        if source[m] != m:
            copy(smooth[source[m], load], 0, smooth[m, load], 0)


@numba.njit(cache=True)
def element_powers(smooth: np.ndarray, slope: np.ndarray, laws: NominalLaws, power: np.ndarray) -> None:
    """Nominal-law power (M, E, L) of every monitored element, written to ``power``, in W.

    An I element's is I0 f df/dt from its own flow and derivative ``slope`` (M, n_I, L); the others'
    are their bond values' product, with the arithmetic of the matrix product (z = Cy x + Dy u summed over x in order, x =
    ``scale`` x the smoothed signals (M, nx + 1, L), u their last channel, the load), plus ``constant``, what the
    constant sources add to each bond value.
    """
    scale, Cy, Dy, constant, effort, flow, sign, inertia = laws
    M, channels, L = smooth.shape
    nx = channels - 1
    own = np.zeros(len(effort), dtype=np.bool_)
    for k in range(len(inertia)):
        own[int(inertia[k, 1])] = True
    # time innermost, so that the loops vectorize
    ze = np.empty(L)
    zf = np.empty(L)
    for m in range(M):
        u = smooth[m, nx]
        for e in range(len(effort)):
            if own[e]:
                continue
            a, b, sg = effort[e], flow[e], sign[e]
            ze[:] = constant[a]
            zf[:] = constant[b]
            for s in range(nx):
                ca, cb, c = Cy[a, s], Cy[b, s], scale[s]
                for t in range(L):
                    x = smooth[m, s, t] * c
                    ze[t] += ca * x
                    zf[t] += cb * x
            for t in range(L):
                power[m, e, t] = (ze[t] + Dy[a] * u[t]) * (sg * (zf[t] + Dy[b] * u[t]))
        for k in range(len(inertia)):
            channel, element, inertance = int(inertia[k, 0]), int(inertia[k, 1]), inertia[k, 2]
            for t in range(L):
                power[m, element, t] = inertance * smooth[m, channel, t] * slope[m, k, t]


@numba.njit(cache=True)
def chunk_statistics(
    power: np.ndarray, smooth: np.ndarray, raw: np.ndarray, windows: EnergyWindows, inertia: np.ndarray
) -> tuple[bool, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``ea_gym.diagnosis.monitor.Monitor.update``'s per-chunk outputs from the powers and smoothed signals of N real then N reference rows.

    Args:
        power: element powers (2N, E, L + 1) in W; smooth: smoothed signals (2N, nx + 1, L + 1).
        raw: the measured signals after the chunk's first sample, (N, nx, L).
        windows: the sums' windows; inertia: (channel, element index, inertance) of each I element.

    Returns:
        finite (whether every power is finite), EA (2N, E, n_sub) in J, balance residual (N, n_balances)
        in J, gram (N, n_balances, C, C) and cross (N, n_balances, C) in J^2, noise sums (N, 2, nx).
    """
    finite, ea, energy = sub_window_energies(power, smooth, windows.h, windows.n_sub, inertia)
    balance = energy_balances(energy, windows.components, windows.sources)
    residual, gram, cross = balance_statistics(energy, balance, windows.components, windows.n_balance)
    return finite, ea, residual, gram, cross, noise_sums(raw, smooth)


@numba.njit(cache=True)
def sub_window_energies(
    power: np.ndarray, smooth: np.ndarray, h: float, n_sub: int, inertia: np.ndarray
) -> tuple[bool, np.ndarray, np.ndarray]:
    """Whether every power (M, E, T) in W is finite, and per row, element and sub-window of ``n_sub``
    intervals its EA (M, E, n_sub) and its signed energy (eq 3), both in J; an I element's energy is
    the change of its kinetic energy, exact and free of the derivative's noise."""
    M, E, T = power.shape
    subs = (T - 1) // n_sub
    infinite = False
    for value in power.reshape(-1):  # one flat loop: it vectorises
        infinite |= not np.isfinite(value)
    ea = np.empty((M, E, subs))
    energy = np.empty((M, E, subs))
    one = np.uint64(1)
    for m in range(M):
        for e in range(E):
            p = power[m, e]
            for s in range(subs):
                # EA and signed energy in one pass over the samples (two passes cost a third more); the
                # sub-window indexed by unsigned offsets, free of the negative-index check at every load
                window = p[s * n_sub : (s + 1) * n_sub + 1]
                absolute = 0.0
                signed = 0.0
                for j in range(n_sub):
                    t = np.uint64(j)
                    absolute += trapezoid_area(window[t], window[t + one], h)
                    signed += 0.5 * (window[t] + window[t + one]) * h
                ea[m, e, s] = absolute
                energy[m, e, s] = signed
        for k in range(len(inertia)):
            channel, element, half_inertance = int(inertia[k][0]), int(inertia[k][1]), 0.5 * inertia[k][2]
            f = smooth[m, channel]
            for s in range(subs):
                energy[m, element, s] = half_inertance * (f[(s + 1) * n_sub] ** 2 - f[s * n_sub] ** 2)
    return not infinite, ea, energy


@numba.njit(cache=True)
def energy_balances(energy: np.ndarray, components: np.ndarray, sources: np.ndarray) -> np.ndarray:
    """Per row and sub-window, the energy the sources deliver less the energy the components absorb (J), (M, subs)."""
    M, _, subs = energy.shape
    balance = np.empty((M, subs))
    for m in range(M):
        for s in range(subs):
            delivered = 0.0
            for k in sources:
                delivered += energy[m, k, s]
            absorbed = 0.0
            for k in components:
                absorbed += energy[m, k, s]
            balance[m, s] = delivered - absorbed
    return balance


@numba.njit(cache=True)
def balance_statistics(
    energy: np.ndarray, balance: np.ndarray, components: np.ndarray, n_balance: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per system and balance window of ``n_balance`` sub-windows: the residual R of the energy balance,
    real (the first N rows) less reference (the last N), in J, and E_i E_j, E_i R in J^2 with E_i the
    energy component i absorbs: (N, n_balances), (N, n_balances, C, C), (N, n_balances, C)."""
    n = len(balance) // 2
    balances = balance.shape[1] // n_balance
    C = len(components)
    residual = np.zeros((n, balances))
    gram = np.empty((n, balances, C, C))
    cross = np.empty((n, balances, C))
    stored = np.empty(C)
    for m in range(n):
        for b in range(balances):
            for s in range(b * n_balance, (b + 1) * n_balance):
                residual[m, b] += balance[m, s] - balance[n + m, s]  # the reference's own error cancels
            for i in range(C):
                stored[i] = 0.0
                for s in range(b * n_balance, (b + 1) * n_balance):
                    stored[i] += energy[m, components[i], s]
            for i in range(C):
                for j in range(C):
                    gram[m, b, i, j] = stored[i] * stored[j]
                cross[m, b, i] = stored[i] * residual[m, b]
    return residual, gram, cross


@numba.njit(cache=True)
def noise_sums(raw: np.ndarray, smooth: np.ndarray) -> np.ndarray:
    """Per system and measured signal, sum (raw - smoothed)^2 and sum raw^2 over the chunk, (N, 2, nx);
    ``raw`` (N, nx, L) follows the chunk's first sample, ``smooth`` (2N, nx + 1, L + 1) includes it."""
    n, nx, L = raw.shape
    noise = np.empty((n, 2, nx))
    for m in range(n):
        for c in range(nx):
            error, power_sum = 0.0, 0.0  # in registers: the array entries would be reloaded at every sample
            for t in range(L):
                error += (raw[m, c, t] - smooth[m, c, t + 1]) ** 2
                power_sum += raw[m, c, t] ** 2
            noise[m, 0, c], noise[m, 1, c] = error, power_sum
    return noise


@numba.njit(cache=True)
def padded_chunk(
    measured: np.ndarray, reference: np.ndarray, load: np.ndarray, context: np.ndarray, start: int, stop: int, padded: np.ndarray
) -> None:
    """Real then reference rows of systems [start, stop) (2 (stop - start), nx + 1, H + L + 1) with the
    load as last channel, written to ``padded``, each led by its H samples of smoothing context:
    ``context`` (2N, nx + 1, H), N real then N reference rows, or where it is NaN the chunk mirrored
    about its first sample. Those systems' ``context`` becomes their next chunk's."""
    n, nx, T = measured.shape
    H = context.shape[2]
    k = stop - start
    for i in range(2 * k):
        m = start + i % k
        real = i < k
        for c in range(nx + 1):
            x = load[m] if c == nx else (measured[m, c] if real else reference[m, c])
            y, previous = padded[i, c], context[m if real else n + m, c]
            mirror = x[1 : H + 1]  # x[H - j] at H - 1 - j
            for j in range(H):
                at = np.uint64(j)
                y[at] = mirror[np.uint64(H - 1 - j)] if np.isnan(previous[at]) else previous[at]
            copy(x, 0, y, H)
            copy(x, T - H - 1, previous, 0)


def monitor_chunk(
    start: int, stop: int, signals: ChunkSignals, context: np.ndarray, smoothing: Smoothing, laws: NominalLaws, windows: EnergyWindows,
    outputs: ChunkOutputs,
) -> bool:
    """``ea_gym.diagnosis.monitor.Monitor.update`` for systems [start, stop) of N: their real and reference
    rows padded with their context (``padded_chunk``), smoothed (``smooth_rows``), their elements'
    powers (``element_powers``) and the chunk's statistics (``chunk_statistics``); a system's results
    do not depend on the others', so parts of the systems run on several threads (GIL released).

    Args:
        signals: the chunk's signals; context: as in ``padded_chunk``.
        outputs: written for the part's systems.

    Returns:
        whether every power of the part is finite.
    """
    # the records cross into compiled code as plain tuples (``monitor_chunk_step``)
    return monitor_chunk_step(start, stop, tuple(signals), context, tuple(smoothing), tuple(laws), tuple(windows), tuple(outputs))


@numba.njit(cache=True, nogil=True)
def monitor_chunk_step(
    start: int, stop: int, signals: tuple, context: np.ndarray, smoothing: tuple, laws: tuple, windows: tuple, outputs: tuple
) -> bool:
    """``monitor_chunk``, compiled. The records come as plain tuples of their fields (or as the records):
    numba types a plain tuple's fields in compiled code and a named tuple's in Python, which cost 3 us a
    call here (of ~12 us at N = 1); they are named again here, which costs nothing."""
    smoothing, laws, windows, outputs = Smoothing(*smoothing), NominalLaws(*laws), EnergyWindows(*windows), ChunkOutputs(*outputs)
    measured, reference, load = signals
    n, nx, T = measured.shape
    H = context.shape[2]
    inertia = laws.inertia
    # blocks of LANES systems: their real and reference rows fill the filter's lanes twice and their
    # loads once, and a block's working arrays stay in the core's cache
    block = min(stop - start, LANES)
    padded = np.empty((2 * block, nx + 1, H + T))
    smooth = np.empty((2 * block, nx + 1, T))
    slope = np.empty((2 * block, len(inertia), T))
    power = np.empty((2 * block, len(laws.effort), T))
    finite = True
    for first in range(start, stop, block):
        last = min(first + block, stop)
        k = last - first
        rows = slice(0, 2 * k)
        padded_chunk(measured, reference, load, context, first, last, padded[rows])
        smooth_rows(padded[rows], 0, H, smoothing, inertia, smooth[rows], slope[rows])
        element_powers(smooth[rows], slope[rows], laws, power[rows])
        finite_block, block_ea, block_residual, block_gram, block_cross, block_noise = chunk_statistics(
            power[rows], smooth[rows], measured[first:last, :, 1:], windows, inertia
        )
        finite &= finite_block
        outputs.ea[first:last] = block_ea[:k]
        outputs.ea[n + first : n + last] = block_ea[k:]
        outputs.residual[first:last] = block_residual
        outputs.gram[first:last] = block_gram
        outputs.cross[first:last] = block_cross
        outputs.noise[first:last] = block_noise
        outputs.signals[first:last] = smooth[:k, :nx]
    return finite
