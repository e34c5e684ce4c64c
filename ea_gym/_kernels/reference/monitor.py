"""The monitor's chunk (``ea_gym._kernels.monitor``): the rows padded with their smoothing context, smoothed
and differentiated, the elements' nominal-law powers, and the chunk's EA, energy balances and noise sums.
The smoothing meets the kernel's to a few ulps (``reference.smoothing``); what follows it is numpy's
arithmetic in the kernel's order."""

from __future__ import annotations

import numpy as np

from ea_gym._kernels.monitor import ChunkOutputs, ChunkSignals, EnergyWindows, NominalLaws, Smoothing
from ea_gym._kernels.reference.smoothing import filter_lanes


def copy(source: np.ndarray, start: int, target: np.ndarray, offset: int) -> None:
    """target[offset:] = source[start:] for as many samples as fit."""
    count = min(len(source) - start, len(target) - offset)
    target[offset : offset + count] = source[start : start + count]


def same(a: np.ndarray, b: np.ndarray, start: int) -> bool:
    """Whether a[start:] equals b[start:]."""
    return bool(np.array_equal(a[start:], b[start:]))


def load_sources(rows: np.ndarray, channel: int, skip: int) -> tuple[np.ndarray, np.ndarray]:
    """For each row the row whose ``channel`` (from ``skip`` on) it takes: its predecessor's, else its twin's
    half a batch before (an even batch of real then reference rows), else its own; and the rows that are their own."""
    M = len(rows)
    source = np.arange(M)
    for m in range(1, M):
        twin = m - M // 2
        if same(rows[m, channel], rows[m - 1, channel], skip):
            source[m] = source[m - 1]
        elif M % 2 == 0 and twin >= 0 and same(rows[m, channel], rows[twin, channel], skip):
            source[m] = source[twin]
    return source, np.flatnonzero(source == np.arange(M))


def smooth_rows(
    rows: np.ndarray, skip: int, cut: int, smoothing: Smoothing, inertia: np.ndarray, smooth: np.ndarray, slope: np.ndarray
) -> None:
    """Every signal of rows (M, nx + 1, T) filtered from sample ``skip`` on, outputs from ``cut`` on, into
    smooth (M, nx + 1, T - skip - cut); the I elements' channels (``inertia``) differentiated into slope."""
    M, channels, T = rows.shape
    signals = rows[..., skip:].reshape(M * channels, T - skip).T
    filtered, derivative = np.empty_like(signals), np.empty_like(signals)
    filter_lanes(signals, cut, *smoothing, len(inertia) > 0, filtered, derivative)
    smooth[:] = filtered[cut:].T.reshape(M, channels, -1)
    for k, channel in enumerate(inertia[:, 0].astype(int)):
        slope[:, k] = derivative[cut:].T.reshape(M, channels, -1)[:, channel]


def element_powers(smooth: np.ndarray, slope: np.ndarray, laws: NominalLaws, power: np.ndarray) -> None:
    """Nominal-law power (M, E, L) of every element: the product of its bond values z = Cy (scale x) + Dy u
    + constant (summed over x in order), signed; an I element's I0 f df/dt from its flow and ``slope``."""
    scale, Cy, Dy, constant, effort, flow, sign, inertia = laws
    nx = smooth.shape[1] - 1
    z = np.broadcast_to(constant[None, :, None], (len(smooth), len(constant), smooth.shape[2])).copy()
    for s in range(nx):
        z += Cy[None, :, s, None] * (smooth[:, None, s] * scale[s])
    z += Dy[None, :, None] * smooth[:, None, nx]
    power[:] = z[:, effort] * (sign[None, :, None] * z[:, flow])
    for k, (channel, element, inertance) in enumerate(inertia):
        power[:, int(element)] = inertance * smooth[:, int(channel)] * slope[:, k]


def sub_window_energies(power: np.ndarray, smooth: np.ndarray, h: float, n_sub: int, inertia: np.ndarray) -> tuple[bool, np.ndarray, np.ndarray]:
    """Whether every power is finite; per row, element and sub-window of ``n_sub`` intervals its EA and
    signed energy by the trapezoid, added in time order; an I element's energy its kinetic energy's change."""
    subs = (power.shape[2] - 1) // n_sub
    ea, energy = np.zeros(power.shape[:2] + (subs,)), np.zeros(power.shape[:2] + (subs,))
    for j in range(n_sub):
        left, right = power[..., j : subs * n_sub : n_sub], power[..., j + 1 : subs * n_sub + 1 : n_sub]
        ea += 0.5 * (np.abs(left) + np.abs(right)) * h
        energy += 0.5 * (left + right) * h
    for channel, element, inertance in inertia:
        f = smooth[:, int(channel), : subs * n_sub + 1 : n_sub]
        energy[:, int(element)] = 0.5 * inertance * (f[:, 1:] ** 2 - f[:, :-1] ** 2)
    return bool(np.isfinite(power).all()), ea, energy


def energy_balances(energy: np.ndarray, components: np.ndarray, sources: np.ndarray) -> np.ndarray:
    """Per row and sub-window the sources' energy less the components', each added in order."""
    delivered, absorbed = np.zeros(energy[:, 0].shape), np.zeros(energy[:, 0].shape)
    for k in sources:
        delivered += energy[:, k]
    for k in components:
        absorbed += energy[:, k]
    return delivered - absorbed


def balance_statistics(
    energy: np.ndarray, balance: np.ndarray, components: np.ndarray, n_balance: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per system and balance window: the residual R, real (first N rows) less reference, and E_i E_j, E_i R
    with E_i the energy component i absorbs, each summed over the window's sub-windows in order."""
    n = len(balance) // 2
    balances = balance.shape[1] // n_balance
    residual = np.zeros((n, balances))
    stored = np.zeros((n, len(components), balances))
    for j in range(n_balance):
        residual += balance[:n, j : balances * n_balance : n_balance] - balance[n:, j : balances * n_balance : n_balance]
        stored += energy[:n][:, components, j : balances * n_balance : n_balance]
    stored = stored.transpose(0, 2, 1)
    return residual, stored[..., :, None] * stored[..., None, :], stored * residual[..., None]


def noise_sums(raw: np.ndarray, smooth: np.ndarray) -> np.ndarray:
    """Per system and signal sum (raw - smoothed)^2 and sum raw^2 (in time order), (N, 2, nx)."""
    n, nx, L = raw.shape
    noise = np.zeros((n, 2, nx))
    for t in range(L):
        noise[:, 0] += (raw[..., t] - smooth[:n, :nx, t + 1]) ** 2
        noise[:, 1] += raw[..., t] ** 2
    return noise


def chunk_statistics(
    power: np.ndarray, smooth: np.ndarray, raw: np.ndarray, windows: EnergyWindows, inertia: np.ndarray
) -> tuple[bool, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """finite, EA (2N, E, subs), balance residual, gram and cross (N, ...), noise sums (N, 2, nx)."""
    finite, ea, energy = sub_window_energies(power, smooth, windows.h, windows.n_sub, inertia)
    balance = energy_balances(energy, windows.components, windows.sources)
    residual, gram, cross = balance_statistics(energy, balance, windows.components, windows.n_balance)
    return finite, ea, residual, gram, cross, noise_sums(raw, smooth)


def padded_chunk(
    measured: np.ndarray, reference: np.ndarray, load: np.ndarray, context: np.ndarray, start: int, stop: int, padded: np.ndarray
) -> None:
    """Real then reference rows of systems [start, stop), load last, into ``padded``, each led by its H samples
    of ``context`` (2N, nx + 1, H) or, where that is NaN, the chunk mirrored about its first sample; those
    systems' context becomes their chunk's last H samples before its end."""
    n, _, T = measured.shape
    H = context.shape[2]
    part = np.arange(start, stop)
    signals = np.concatenate([np.concatenate([measured, load[:, None]], 1), np.concatenate([reference, load[:, None]], 1)])
    rows = np.concatenate([part, n + part])
    previous = context[rows]
    padded[..., :H] = np.where(np.isnan(previous), signals[rows][..., H:0:-1], previous)
    padded[..., H:] = signals[rows]
    context[rows] = signals[rows][..., T - H - 1 : T - 1]


def monitor_chunk_step(
    start: int, stop: int, signals: ChunkSignals, context: np.ndarray, smoothing: Smoothing, laws: NominalLaws, windows: EnergyWindows,
    outputs: ChunkOutputs,
) -> bool:
    """Systems [start, stop) of N: padded, smoothed, their powers and the chunk's statistics into ``outputs``;
    whether every power is finite."""
    measured, reference, load = signals
    n, nx, T = measured.shape
    k, H = stop - start, context.shape[2]
    padded = np.empty((2 * k, nx + 1, H + T))
    padded_chunk(measured, reference, load, context, start, stop, padded)
    smooth, slope = np.empty((2 * k, nx + 1, T)), np.empty((2 * k, len(laws.inertia), T))
    smooth_rows(padded, 0, H, smoothing, laws.inertia, smooth, slope)
    power = np.empty((2 * k, len(laws.effort), T))
    element_powers(smooth, slope, laws, power)
    finite, ea, residual, gram, cross, noise = chunk_statistics(power, smooth, measured[start:stop, :, 1:], windows, laws.inertia)
    outputs.ea[start:stop], outputs.ea[n + start : n + stop] = ea[:k], ea[k:]
    outputs.residual[start:stop], outputs.gram[start:stop], outputs.cross[start:stop] = residual, gram, cross
    outputs.noise[start:stop], outputs.signals[start:stop] = noise, smooth[:k, :nx]
    return finite
