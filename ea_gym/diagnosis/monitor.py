"""Measurement, denoising and Energy Activity of the real and the reference system (paper 3.1).

Sensors measure each storage element's co-energy side: the flow of every I element (a velocity, a
current) and the displacement q of every C element (a position, a charge), with Gaussian noise whose
std is a fraction of the signal's RMS over the window. A Savitzky-Golay filter smooths them and gives
their time derivatives. It is zero-phase, and the reference model's signals pass through exactly the
same filter, so what magnitude distortion remains cancels in the residuals (the paper's 3.2 warning).

"Real" element powers apply the nominal constitutive laws to the denoised measurements (eq 6/7): an I
element's power is I0 f df/dt, a C element's is e(q) dq/dt with e = k0 q or q / C0, and the R
elements and sources get their effort and flow from the nominal junction structure. A parameter
fault then breaks the power balance of the junction structure by exactly sum_i beta_i P_i, where
beta_i is the relative deviation of component i's coefficient: the monitor also accumulates the
least-squares statistics of that balance residual against every component's power.

Everything is batched over N systems; time is the last axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ea_gym.bondgraph.elements import Kind
from ea_gym.bondgraph.equations import bond_powers
from ea_gym.diagnosis.features import Frame
from ea_gym.diagnosis.smoothing import SavitzkyGolay
from ea_gym.energy import _interval_activity, _sum_windows, window_samples
from ea_gym.models import SystemModel


@dataclass(frozen=True)
class MonitorConfig:
    """Signal processing settings.

    Attributes:
        sub_window: EA integration window Delta t of eq 4 (s); the residual series has one value per sub-window.
        smoothing: Savitzky-Golay window (samples, odd).
        polyorder: Savitzky-Golay polynomial order.
        balance_window: span (s, a multiple of ``sub_window``) of the energy balances regressed on the
            component energies; longer spans beat the noise of the kinetic-energy end points.
        state_polyorder: polynomial order of the smoother that estimates a state from samples on both
            sides (the EA inversion's starting point): a higher order keeps the load's faster components.
    """

    sub_window: float = 0.1
    smoothing: int = 51
    polyorder: int = 3
    balance_window: float = 0.1
    state_polyorder: int = 7


@dataclass(frozen=True)
class MonitorWindow:
    """What one chunk of samples yields, per system.

    Attributes:
        ea: real EA per element and sub-window (J), (N, E, n_sub); elements in ``Monitor.elements`` order.
        ea_reference: the reference model's, same shape.
        gram: E_i E_j per balance window, E_i the energy component i absorbs in it (J^2), (N, n_balances, C, C).
        cross: E_i R, R the energy-balance residual of the window, real minus reference (J^2), (N, n_balances, C).
        balance: R per balance window (J), (N, n_balances).
        signals: the denoised measured signals at every sample, (N, nx, L + 1).
        noise: sum over the chunk of (raw - denoised)^2 and of raw^2 per measured signal, (N, 2, nx).
    """

    ea: np.ndarray
    ea_reference: np.ndarray
    gram: np.ndarray
    cross: np.ndarray
    balance: np.ndarray
    signals: np.ndarray
    noise: np.ndarray


def add_sensor_noise(signals: np.ndarray, fraction: float | np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Add white Gaussian noise of std ``fraction`` x the RMS of each signal over its time axis.

    ``fraction`` may be an array broadcasting against ``signals`` (one level per system).
    """
    if np.all(np.asarray(fraction) == 0):
        return signals
    rms = np.sqrt(np.mean(signals**2, axis=-1, keepdims=True))
    return signals + fraction * rms * rng.standard_normal(signals.shape)


class Monitor:
    """Streams measured and reference signals through denoising, nominal-law power and EA.

    Args:
        model: the monitored system (its nominal values are the reference laws).
        sample_period: seconds between samples.
        config: signal processing settings.
        n_systems: batch size N.
    """

    def __init__(self, model: SystemModel, sample_period: float, config: MonitorConfig = MonitorConfig(), n_systems: int = 1):
        self.filter = SavitzkyGolay(config.smoothing, config.polyorder, sample_period)
        self.state_filter = SavitzkyGolay(config.smoothing, config.state_polyorder, sample_period)
        self.model = model
        self.h = sample_period
        self.config = config
        self.n_sub = window_samples(config.sub_window, sample_period)
        self.n_balance = window_samples(config.balance_window, config.sub_window)
        self.n_systems = n_systems
        space = model.state_space
        elements = model.graph.elements
        self.elements = tuple(n for n, e in elements.items() if not e.kind.is_junction)
        self.components = model.rco_elements
        self._component_index = np.array([self.elements.index(c) for c in self.components])
        inertias = [n for n in self.components if elements[n].kind is Kind.I]
        if not inertias:
            raise ValueError(f"model {model.name!r} has no I element, whose EA residual the isolation uses")
        self._inertia_index = self.elements.index(inertias[0])
        self._source_index = np.array([self.elements.index(s) for s in space.input_names])
        nominal = model.parameter_vector()
        mats = space.matrices(nominal)
        self._Cy, self._Dy = mats.Cy, mats.Dy
        # per state: the nominal factor turning the measured signal into the energy variable
        self._to_state = np.array(
            [nominal[space.parameter_names.index(s)] if elements[s].kind is Kind.I else 1.0 for s in space.state_names]
        )
        # I elements: P = I0 f df/dt from their own flow; the junction structure would give their
        # effort by closing the power balance, which would hide the fault in it
        self._inertance = {
            name: (j, nominal[space.parameter_names.index(name)])
            for j, name in enumerate(space.state_names)
            if elements[name].kind is Kind.I
        }
        self._context: np.ndarray | None = None  # last samples of the previous chunk, real then reference

    def measurement_matrix(self, parameters: np.ndarray) -> np.ndarray:
        """Rows map energy variables to measured signals under true ``parameters`` (..., P): (..., nx, nx)."""
        space = self.model.state_space
        diagonal = np.ones(np.shape(parameters)[:-1] + (len(space.state_names),))
        for j, name in enumerate(space.state_names):
            if self.model.graph.elements[name].kind is Kind.I:
                diagonal[..., j] = 1.0 / parameters[..., space.parameter_names.index(name)]
        return diagonal[..., :, None] * np.eye(len(space.state_names))

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Forget the smoothing context of all systems, or of those where the boolean mask is true."""
        if systems is None or self._context is None:
            self._context = None
        else:
            self._context[np.concatenate([systems, systems])] = np.nan

    def _with_context(self, signals: np.ndarray) -> np.ndarray:
        """Prepend the previous chunk's last samples; a fresh system gets its chunk mirrored about its first sample."""
        mirrored = signals[..., 1 : self.config.smoothing + 1][..., ::-1]
        if self._context is None:
            context = mirrored
        else:
            context = np.where(np.isnan(self._context), mirrored, self._context)
        return np.concatenate([context, signals], axis=-1)

    def powers(self, signals: np.ndarray, start: int) -> tuple[np.ndarray, np.ndarray]:
        """Nominal-law power of every element (..., E, L + 1) and the denoised signals (..., nx + 1, L + 1).

        ``signals`` (..., nx + 1, T) hold the measured flows of I and displacements of C, then the
        source's value; the samples before ``start`` are smoothing context only. The load passes
        through the same linear filter as the measurements, so the filtered signals still obey the
        model's equations and the nominal energy balance holds exactly in a fault-free run.
        """
        # the outputs from ``start`` on need the samples from ``start - half`` on only: the filter's
        # interior and end rows give them exactly as on the whole signal
        half = self.filter.half
        skip = start - half if start >= half and signals.shape[-1] - start >= half + 1 else 0
        lead, channels = signals.shape[:-2], signals.shape[-2]
        rows = signals[..., skip:].reshape((-1, channels, signals.shape[-1] - skip))
        cut = start - skip
        flat = np.empty(rows.shape[:-1] + (rows.shape[-1] - cut,))
        flat[:, :-1] = self.filter(rows[:, :-1])[..., cut:]
        # the source's signal is often the same in consecutive rows (the candidates of one system): filtered once
        load = rows[:, -1]
        fresh = np.ones(len(load), dtype=bool)
        fresh[1:] = np.any(load[1:] != load[:-1], axis=-1)
        if np.count_nonzero(fresh) < 0.75 * len(load):
            flat[:, -1] = self.filter(load[fresh])[np.cumsum(fresh) - 1, cut:]
        else:
            flat[:, -1] = self.filter(load)[:, cut:]
        smooth = flat.reshape(lead + flat.shape[-2:])
        inertia_channels = [j for j, _ in self._inertance.values()]
        slope = self.filter(rows[:, inertia_channels], deriv=1)[..., cut:].reshape(lead + (len(inertia_channels), -1))  # only I laws differentiate
        names, effort, flow, sign = self.model.state_space.element_bonds()
        power = bond_powers(flat, self._to_state, self._Cy, np.ascontiguousarray(self._Dy[:, 0]), effort, flow, sign)
        power = power.reshape(lead + power.shape[-2:])
        order = [names.index(name) for name in self.elements]
        if order != list(range(len(names))):
            power = power[..., order, :]
        for k, (name, (j, inertance)) in enumerate(self._inertance.items()):
            power[..., self.elements.index(name), :] = inertance * smooth[..., j, :] * slope[..., k, :]
        return power, smooth

    def update(self, measured: np.ndarray, reference: np.ndarray, load: np.ndarray) -> MonitorWindow:
        """Process one chunk of L intervals (L + 1 samples, the first shared with the previous chunk).

        Args:
            measured: noisy measured signals, (N, nx, L + 1).
            reference: the reference model's signals, same shape and meaning.
            load: the source's value, (N, L + 1).
        """
        if measured.shape[-1] <= self.config.smoothing:
            raise ValueError(
                f"a chunk of {measured.shape[-1]} samples must be longer than the smoothing window ({self.config.smoothing})"
            )
        both = np.concatenate([measured, reference], axis=0)
        both = np.concatenate([both, np.concatenate([load, load], axis=0)[:, None]], axis=1)
        padded = self._with_context(both)
        start = padded.shape[-1] - both.shape[-1]
        power, smooth = self.powers(padded, start)
        self._context = both[..., -self.config.smoothing - 1 : -1]
        n = len(measured)
        areas = _interval_activity(power, self.h)
        ea = _sum_windows(areas, self.n_sub)[0]
        energy = self._signed_energy(power, smooth)
        balance = energy[:, self._source_index].sum(axis=1) - energy[:, self._component_index].sum(axis=1)
        residual = _sum_windows(balance[:n] - balance[n:], self.n_balance)[0]  # the reference's own error cancels
        stored = _sum_windows(energy[:n, self._component_index], self.n_balance)[0]  # (n, C, n_balances)
        gram = np.einsum("nis,njs->nsij", stored, stored)
        cross = np.einsum("nis,ns->nsi", stored, residual)
        raw = measured[..., 1:]
        noise = np.stack([((raw - smooth[:n, :-1, 1:]) ** 2).sum(-1), (raw**2).sum(-1)], axis=1)
        return MonitorWindow(
            ea=ea[:n], ea_reference=ea[n:], gram=gram, cross=cross, balance=residual, signals=smooth[:n, :-1], noise=noise
        )

    def _signed_energy(self, power: np.ndarray, smooth: np.ndarray) -> np.ndarray:
        """Energy absorbed by every element in every sub-window (J, eq 3), (..., E, n_sub).

        An I element's is the change of its kinetic energy, I0 (f_end^2 - f_start^2) / 2, exact and free
        of the derivative's noise; the others integrate their power by the trapezoidal rule.
        """
        trapezoids = 0.5 * (power[..., :-1] + power[..., 1:]) * self.h
        energy = _sum_windows(trapezoids, self.n_sub)[0]
        for name, (j, inertance) in self._inertance.items():
            edges = smooth[..., j, :: self.n_sub]
            energy[..., self.elements.index(name), :] = 0.5 * inertance * np.diff(edges**2, axis=-1)
        return energy

    def frame(self, windows: list[MonitorWindow]) -> Frame:
        """Join consecutive chunks' outputs into one isolation frame."""
        return self.frame_of(
            np.concatenate([w.ea for w in windows], axis=-1),
            np.concatenate([w.ea_reference for w in windows], axis=-1),
            sum(w.gram.sum(axis=1) for w in windows),
            sum(w.cross.sum(axis=1) for w in windows),
            sum(w.noise for w in windows),
        )

    def frame_of(self, ea: np.ndarray, ea_reference: np.ndarray, gram: np.ndarray, cross: np.ndarray, noise: np.ndarray) -> Frame:
        """An isolation frame from EA per sub-window (N, E, F) and the summed statistics of its chunks."""
        return Frame(
            ea=ea,
            ea_reference=ea_reference,
            gram=gram,
            cross=cross,
            noise=np.sqrt(noise[:, 0] / np.maximum(noise[:, 1], 1e-300)),
            sub_window=self.config.sub_window,
            component_index=self._component_index,
            inertia_index=self._inertia_index,
        )
