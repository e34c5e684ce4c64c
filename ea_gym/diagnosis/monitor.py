"""Measurement, denoising and Energy Activity of the real and the reference system (paper 3.1).

The monitor takes what the sensors (``ea_gym.sensors.Sensors``) measure: the flow of every I element
(a velocity, a current) and the displacement q of every C element (a position, a charge), with
Gaussian noise whose std is a fraction of the signal's RMS over the window. A Savitzky-Golay filter smooths them and gives
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

from collections.abc import Iterable
from dataclasses import dataclass, replace

import numpy as np

from ea_gym._kernels.features import relative_noise
from ea_gym._kernels.monitor import ChunkOutputs, ChunkSignals, EnergyWindows, NominalLaws, Smoothing, element_powers, monitor_chunk, smooth_rows
from ea_gym.bondgraph.elements import Kind
from ea_gym.diagnosis.features import Frame
from ea_gym.diagnosis.smoothing import SavitzkyGolay
from ea_gym.energy import window_samples
from ea_gym.models import SystemModel
from ea_gym.sensors import Sensors
from ea_gym.threads import over_rows


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

    def fitting(self, chunk_intervals: int) -> MonitorConfig:
        """These settings with a smoothing window that fits a chunk of ``chunk_intervals`` intervals (``Monitor.update``
        needs more samples than the window): ``smoothing`` where it fits, else the longest odd window that does (at a
        low sample rate, 50 Hz and a 1 s step: 49 samples). Raises ValueError where no window above
        ``state_polyorder`` fits."""
        if chunk_intervals + 1 > self.smoothing:
            return self
        window = chunk_intervals if chunk_intervals % 2 else chunk_intervals - 1
        if window <= self.state_polyorder:
            raise ValueError(
                f"a chunk of {chunk_intervals + 1} samples holds no smoothing window above the polynomial order "
                f"{self.state_polyorder}; expected at least {self.state_polyorder + 3} samples per step"
            )
        return replace(self, smoothing=window)


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


def _total(arrays: Iterable[np.ndarray]) -> np.ndarray:
    """The arrays summed in order (``sum``'s arithmetic: 0.0 plus the first, then the others)."""
    return np.asarray(sum(arrays, 0.0))


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
        self.component_index = np.array([self.elements.index(c) for c in self.components])
        # positions in ``components`` of the R elements (all components if there is none): their EA is
        # the scale of the energy-balance residual, where a dissipator's fault shows
        dissipators = [j for j, c in enumerate(self.components) if elements[c].kind is Kind.R]
        self.dissipators = np.array(dissipators or range(len(self.components)))
        inertias = [n for n in self.components if elements[n].kind is Kind.I]
        if not inertias:
            raise ValueError(f"model {model.name!r} has no I element, whose EA residual the isolation uses")
        self.inertia_index = self.elements.index(inertias[0])
        self._source_index = np.array([self.elements.index(s) for s in space.input_names])
        nominal = model.parameter_vector()
        mats = space.matrices(nominal)
        self._Cy, self._Dy = mats.Cy, mats.Dy
        self._Dy0 = np.ascontiguousarray(mats.Dy[:, model.load_index])  # the load's column
        self._Dy_constant = mats.Dy @ model.constant_inputs()  # what the constant sources add to every bond
        self._buffers: dict[tuple, np.ndarray] = {}
        # per state: the nominal factor turning the measured signal into the energy variable
        self._to_state = Sensors(model).inverse_gain(nominal)
        # I elements: P = I0 f df/dt from their own flow; the junction structure would give their
        # effort by closing the power balance, which would hide the fault in it
        self._inertance = {
            name: (j, nominal[space.parameter_names.index(name)])
            for j, name in enumerate(space.state_names)
            if elements[name].kind is Kind.I
        }
        names, effort, flow, sign = space.element_bonds()
        order = [names.index(name) for name in self.elements]
        self._bonds = (effort[order], flow[order], sign[order])
        # (channel, element index, inertance) of every I element, as the compiled kernels take them
        self._inertia = np.array(
            [(j, self.elements.index(name), inertance) for name, (j, inertance) in self._inertance.items()], dtype=float
        ).reshape(-1, 3)
        self._context: np.ndarray | None = None  # last samples of the previous chunk, real then reference
        # the kernels' arguments: the filters' coefficients (``smooth_rows``), the nominal laws (``element_powers``)
        self._smoothing = Smoothing(self.filter.moments(), self.filter.lane_coefficients(0), self.filter.lane_coefficients(1))
        self._laws = NominalLaws(self._to_state, self._Cy, self._Dy0, self._Dy_constant, *self._bonds, self._inertia)

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Forget the smoothing context of all systems, or of those where the boolean mask is true."""
        if systems is None or self._context is None:
            self._context = None
        else:
            self._context[np.concatenate([systems, systems])] = np.nan

    def buffer(self, name: str, shape: tuple[int, ...]) -> np.ndarray:
        """A scratch array of ``shape``, kept between calls (fresh large arrays cost page faults each
        step); the next request for ``name`` and the same trailing shape overwrites it."""
        key = (name,) + shape[1:]
        buffer = self._buffers.get(key)
        if buffer is None or len(buffer) < shape[0]:
            buffer = self._buffers[key] = np.empty(shape)
        return buffer[: shape[0]]

    def powers(self, signals: np.ndarray, start: int, scratch: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Nominal-law power of every element (..., E, L + 1) in W and the denoised signals (..., nx + 1, L + 1).

        ``signals`` (..., nx + 1, T) hold the measured flows of I and displacements of C, then the
        source's value; the samples before ``start`` are smoothing context only. The load passes
        through the same linear filter as the measurements, so the filtered signals still obey the
        model's equations and the nominal energy balance holds exactly in a fault-free run.
        ``scratch``: the results live in buffers that the next call overwrites.
        """
        # the outputs from ``start`` on need the samples from ``start - half`` on only: the filter's
        # interior and end rows give them exactly as on the whole signal
        half = self.filter.half
        skip = start - half if start >= half and signals.shape[-1] - start >= half + 1 else 0
        if signals.shape[-1] - skip < self.filter.window:
            raise ValueError(f"signals of {signals.shape[-1] - skip} samples are shorter than the filter ({self.filter.window})")
        lead = signals.shape[:-2]
        rows = np.ascontiguousarray(signals, dtype=float).reshape((-1,) + signals.shape[-2:])
        power, smooth = self._powers(rows, skip, start - skip)
        if not scratch:
            power, smooth = power.copy(), smooth.copy()
        return power.reshape(lead + power.shape[-2:]), smooth.reshape(lead + smooth.shape[-2:])

    def _powers(self, rows: np.ndarray, skip: int, cut: int) -> tuple[np.ndarray, np.ndarray]:
        """``powers`` of rows (M, nx + 1, T) into scratch buffers, filtered from sample ``skip`` on, outputs from ``cut`` on."""
        M, channels, T = rows.shape
        L = T - skip - cut
        smooth = self.buffer("smooth", (M, channels, L))
        slope = self.buffer("slope", (M, len(self._inertia), L))
        power = self.buffer("power", (M, len(self.elements), L))
        smooth_rows(rows, skip, cut, self._smoothing, self._inertia, smooth, slope)
        element_powers(smooth, slope, self._laws, power)
        return power, smooth

    def update(self, measured: np.ndarray, reference: np.ndarray, load: np.ndarray) -> MonitorWindow:
        """Process one chunk of L intervals (L + 1 samples, the first shared with the previous chunk).

        The previous chunk's last samples lead each signal as smoothing context; a fresh system's
        chunk is mirrored about its first sample instead.

        Args:
            measured: noisy measured signals, (N, nx, L + 1).
            reference: the reference model's signals, same shape and meaning.
            load: the source's value, (N, L + 1).
        """
        S, half = self.config.smoothing, self.filter.half
        n, nx, T = measured.shape
        if T <= S:
            raise ValueError(f"a chunk of {T} samples must be longer than the smoothing window ({S})")
        # the filter's outputs at the chunk's samples reach half a window before it: so much context
        if self._context is None:
            self._context = np.full((2 * n, nx + 1, half), np.nan)
        measured, reference = np.ascontiguousarray(measured, dtype=float), np.ascontiguousarray(reference, dtype=float)
        load = np.ascontiguousarray(load, dtype=float)
        subs = (T - 1) // self.n_sub
        balances, C = subs // self.n_balance, len(self.components)
        ea = np.empty((2 * n, len(self.elements), subs))
        residual, gram, cross = np.empty((n, balances)), np.empty((n, balances, C, C)), np.empty((n, balances, C))
        noise, signals = np.empty((n, 2, nx)), np.empty((n, nx, T))
        finite: list[bool] = []
        smoothing, laws, context = self._smoothing, self._laws, self._context
        windows = EnergyWindows(self.h, self.n_sub, self.n_balance, self.component_index, self._source_index)
        chunk, outputs = ChunkSignals(measured, reference, load), ChunkOutputs(ea, residual, gram, cross, noise, signals)

        def chunk_rows(start: int, stop: int) -> None:
            finite.append(monitor_chunk(start, stop, chunk, context, smoothing, laws, windows, outputs))

        over_rows(chunk_rows, n)
        if not all(finite):
            raise ValueError("power contains NaN or inf; Energy Activity needs finite signals")
        return MonitorWindow(ea=ea[:n], ea_reference=ea[n:], gram=gram, cross=cross, balance=residual, signals=signals, noise=noise)

    def frame(self, windows: list[MonitorWindow]) -> Frame:
        """Join consecutive chunks' outputs into one isolation frame."""
        return self.frame_of(
            np.concatenate([w.ea for w in windows], axis=-1),
            np.concatenate([w.ea_reference for w in windows], axis=-1),
            _total(w.gram.sum(axis=1) for w in windows),
            _total(w.cross.sum(axis=1) for w in windows),
            _total(w.noise for w in windows),
        )

    def frame_of(self, ea: np.ndarray, ea_reference: np.ndarray, gram: np.ndarray, cross: np.ndarray, noise: np.ndarray) -> Frame:
        """An isolation frame from EA per sub-window (N, E, F) and the summed statistics of its chunks."""
        return Frame(
            ea=ea,
            ea_reference=ea_reference,
            gram=gram,
            cross=cross,
            noise=relative_noise(noise),
            sub_window=self.config.sub_window,
            component_index=self.component_index,
            inertia_index=self.inertia_index,
        )
