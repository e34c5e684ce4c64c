"""Running signals through a chain: a scenario's simulation, or signals recorded elsewhere, whole or
streamed (:class:`StreamingChain`)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ea_gym.bondgraph.simulation import simulate_measured
from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.energy import window_samples
from ea_gym.measurements import Measurements
from ea_gym.models import SystemModel
from ea_gym.numerics import TINY
from ea_gym.phm.chain import HealthStatus, PHMChain
from ea_gym.phm.config import ChainTiming, PHMConfig
from ea_gym.phm.thresholds import thresholds_for
from ea_gym.plant import Trajectory, run_model
from ea_gym.scenario import Scenario
from ea_gym.sensors import Sensors, add_sensor_noise

#: wraps the iterable of step starts, e.g. in a progress bar
Progress = Callable[[Iterable[int]], Iterable[int]]


@dataclass(frozen=True)
class ChainRun:
    """A run through the chain: the statuses of every step and, for a scenario, the ground truth.

    Attributes:
        statuses: the chain's record of every step.
        t: end of every step (s), (steps,).
        true_parameters: the plant's parameters at the end of every step, (steps, P); None for
            recorded measurements, whose truth is unknown.
        residual_series: EA residual of every element per sub-window (J), (E, sub-windows of the run).
    """

    statuses: list[HealthStatus]
    t: np.ndarray
    true_parameters: np.ndarray | None
    residual_series: np.ndarray

    @classmethod
    def of(cls, statuses: list[HealthStatus], true_parameters: np.ndarray | None = None) -> ChainRun:
        """The run of the statuses of one system (N = 1)."""
        if not statuses:
            raise ValueError("a run needs at least one status")
        ends = np.array([s.t[0] for s in statuses])
        residuals = np.concatenate([s.sub_residual[0] for s in statuses], -1)
        return cls(statuses=statuses, t=ends, true_parameters=true_parameters, residual_series=residuals)


def fitted_initial_state(chain: PHMChain, measured: np.ndarray, load: np.ndarray, load_rate: np.ndarray) -> np.ndarray:
    """The reference model's energy variables at the first sample that best explain the signals given, (N, nx).

    The reference model is each system's healthy machine, ``chain.reference_parameters`` (N, P): the nominal values,
    or those its commissioning found (``PHMChain.commission``). Least squares over the window (N, nx, T): the measured
    signals minus the model's response to the load from rest, against its free responses from a unit value of each
    energy variable, each signal weighed by the inverse of its RMS (the sensor noise scales with it). Started from one
    noisy sample instead, a lightly damped reference rings against the plant for tens of seconds (the
    spring-mass-damper's free oscillation decays in 2 m / b = 40 s), and detection reads that as a fault.
    """
    n, nx, samples = measured.shape
    space, h = chain.model.state_space, chain.h
    reference = chain.reference_parameters
    forced, _ = simulate_measured(space, h, *chain.model.source_inputs(load, load_rate), reference, np.zeros((n, nx)), chain.sensors.gain(reference))
    rest = np.zeros((nx, samples, space.n_inputs))
    states = np.empty((n, nx))
    free = None
    for k in range(n):
        if free is None or not np.array_equal(reference[k], reference[k - 1]):  # most rows share one machine: simulated once
            machine = np.repeat(reference[k][None], nx, 0)
            free, _ = simulate_measured(space, h, rest, rest, machine, np.eye(nx), chain.sensors.gain(machine))  # (state, signal, sample)
        weight = 1.0 / np.maximum(np.sqrt(np.mean(measured[k] ** 2, axis=-1)), TINY)
        design = (free * weight[None, :, None]).reshape(nx, -1).T
        target = ((measured[k] - forced[k]) * weight[:, None]).reshape(-1)
        states[k] = np.linalg.lstsq(design, target, rcond=None)[0]
    return states


def reference_signals(chain: PHMChain, load: np.ndarray, load_rate: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The reference model's signals under the load (N, nx, T) from energy variables ``start`` (N, nx), and its energy
    variables at the last sample (N, nx): each system's healthy machine, ``chain.reference_parameters``."""
    reference = chain.reference_parameters
    return simulate_measured(
        chain.model.state_space, chain.h, *chain.model.source_inputs(load, load_rate), reference, start, chain.sensors.gain(reference)
    )


def fitted_reference(chain: PHMChain, measured: np.ndarray, load: np.ndarray, load_rate: np.ndarray) -> np.ndarray:
    """The reference model's signals under the load, (N, nx, T), started from the state fitted to the first step
    (:func:`fitted_initial_state`)."""
    first = slice(0, chain.step_samples + 1)
    start = fitted_initial_state(chain, measured[..., first], load[:, first], load_rate[:, first])
    return reference_signals(chain, load, load_rate, start)[0]


def measured_load(load: np.ndarray, fraction: float, step: int, rng: np.random.Generator) -> np.ndarray:
    """The load as a sensor reads it, (..., T): white noise of std ``fraction`` x the load's RMS over each run of ``step``
    samples (``ChainTiming.load_noise``' definition; the chain's step), drawn from ``rng``; the load itself for 0."""
    if fraction == 0:
        return load
    return np.concatenate([add_sensor_noise(load[..., s : s + step], fraction, rng) for s in range(0, load.shape[-1], step)], -1)


def run_signals(
    chain: PHMChain,
    measured: np.ndarray,
    load: np.ndarray,
    load_rate: np.ndarray,
    reference: np.ndarray | None = None,
    noise: Callable[[np.ndarray], np.ndarray] | None = None,
    progress: Progress | None = None,
) -> list[HealthStatus]:
    """Feed signals sampled at the chain's sample rate through ``chain`` (reset first), one step at a time.

    Args:
        measured: measured signals (flows of I, displacements of C), (N, nx, T): recorded, or a
            simulation's clean signals with ``noise``.
        load, load_rate: the source's value and time derivative, (N, T).
        reference: the reference model's signals, as ``measured``; None: :func:`fitted_reference`.
        noise: adds sensor noise to each step's chunk (its first sample shared with the previous one),
            None for recorded signals.
        progress: wraps the step starts.

    Returns:
        the chain's status after every whole step.
    """
    n, nx = chain.n, len(chain.model.state_names)
    if measured.ndim != 3 or measured.shape[:2] != (n, nx):
        raise ValueError(f"measured must be (N, nx, T) = ({n}, {nx}, T) signals, got shape {measured.shape}")
    if load.shape != (n, measured.shape[2]) or load_rate.shape != load.shape:
        raise ValueError(f"load and load_rate must be (N, T) = {(n, measured.shape[2])}, got {load.shape} and {load_rate.shape}")
    reference = fitted_reference(chain, measured, load, load_rate) if reference is None else reference
    step = chain.step_samples
    statuses = []
    chain.reset()
    starts: Iterable[int] = range(0, measured.shape[2] - step, step)
    for start in starts if progress is None else progress(starts):
        part = slice(start, start + step + 1)
        chunk = measured[..., part] if noise is None else noise(measured[..., part])
        statuses.append(chain.update(chunk, reference[..., part], load[:, part], load_rate[:, part]))
    return statuses


def _plant_signals(scenario: Scenario, sensors: Sensors, rng: np.random.Generator) -> tuple[Trajectory, np.ndarray]:
    """The scenario's plant simulated, and its sensors' clean signals, (1, nx, T)."""
    plant = run_model(scenario.model, scenario.times(), scenario.make_load(), scenario.parameters_at, scenario.initial_state_vector())
    return plant, sensors.measure(plant.parameters[None], plant.states[None], 0.0, rng)


def run_scenario(scenario: Scenario, chain: PHMChain, rng: np.random.Generator, progress: Progress | None = None) -> ChainRun:
    """Simulate ``scenario``'s plant (its true load, every fault profile) and feed it step by step through ``chain`` (N = 1)
    beside the reference model (``chain.reference_parameters``, from the scenario's initial state).

    The chain reads the load as its sensor does: with the scenario's ``load_noise`` (:func:`measured_load`), its
    derivative then the central difference of the noisy samples, as a record's (:class:`StreamingChain`); exactly without
    it. The reference model is driven by the load the chain reads.
    """
    t = scenario.times()
    load = scenario.make_load()
    plant, clean = _plant_signals(scenario, chain.sensors, rng)
    read, read_rate = load.value(t)[None], load.derivative(t)[None]
    if scenario.load_noise > 0:
        read = measured_load(read, scenario.load_noise, chain.step_samples, rng)
        read_rate = np.gradient(read, chain.h, axis=-1)
    expected, _ = reference_signals(chain, read, read_rate, scenario.initial_state_vector()[None])
    statuses = run_signals(
        chain, clean, read, read_rate, expected,
        noise=lambda chunk: add_sensor_noise(chunk, chain.config.timing.noise, rng), progress=progress,
    )
    index = np.round(np.array([s.t[0] for s in statuses]) * scenario.sample_rate).astype(int)
    return ChainRun.of(statuses, plant.parameters[index])


def scenario_measurements(scenario: Scenario, rng: np.random.Generator) -> Measurements:
    """What the sensors of ``scenario``'s plant record: its load with the scenario's load noise and every storage element's
    signal with its sensor noise (each std a fraction of the signal's RMS over each step of ``ChainTiming().step``)."""
    h = 1.0 / scenario.sample_rate
    plant, clean = _plant_signals(scenario, Sensors(scenario.model), rng)
    step = window_samples(ChainTiming().step, h)
    noisy = np.concatenate([add_sensor_noise(clean[..., s : s + step], scenario.noise, rng) for s in range(0, clean.shape[-1], step)], -1)
    load = measured_load(scenario.make_load().value(plant.t), scenario.load_noise, step, rng)
    return Measurements(t=plant.t, load=load, signals=noisy[0].T)


class StreamingChain:
    """The chain on one machine's recorded signals, fed in chunks of any length as they arrive.

    The reference model (the healthy machine: ``chain.reference_parameters``) runs alongside, driven by the recorded load and started
    from the state that best explains the first step (:func:`fitted_initial_state`). The load's
    derivative is its central difference (one-sided at the record's ends), so the load between samples
    is the cubic through them (Catmull-Rom). A step is processed once the sample after its end has
    arrived (the derivative there needs it); ``finish`` processes the last one at the record's end. The
    statuses do not depend on how the record is chunked.

    Args:
        chain: for one system (N = 1); it is reset. Its sample rate is the record's.
    """

    def __init__(self, chain: PHMChain):
        if chain.n != 1:
            raise ValueError(f"a stream feeds one system; the chain has {chain.n}")
        chain.reset()
        self.chain = chain
        self.statuses: list[HealthStatus] = []
        self.start_time: float | None = None
        nx = len(chain.model.state_names)
        # the samples from the one before the next step's start on (that one: the derivative's)
        self._load = np.empty(0)
        self._signals = np.empty((nx, 0))
        self._received = 0  # samples fed so far
        self._first = 0  # record index of the buffer's first sample
        self._last_time: float | None = None  # of the last sample fed (s)
        self._reference_state: np.ndarray | None = None  # the reference model's energy variables at the next step's start
        self._finished = False

    @property
    def received(self) -> int:
        """Samples fed so far."""
        return self._received

    def feed(self, t: ArrayLike, load: ArrayLike, signals: ArrayLike) -> list[HealthStatus]:
        """Append samples to the record and run every step they complete.

        Args:
            t: their times (s), (T,), continuing the record at the chain's sample period.
            load: the load source's value (SI), (T,).
            signals: every storage element's measured signal (I: flow, C: displacement q) in
                ``model.state_names`` order, (T, nx).

        Returns:
            the status of every step completed, in order (none while a step is incomplete).
        """
        if self._finished:
            raise ValueError("the stream is finished; start a new one")
        t, load, signals = (np.asarray(x, dtype=float) for x in (t, load, signals))
        nx = self._signals.shape[0]
        if t.ndim != 1 or load.shape != t.shape or signals.shape != (len(t), nx):
            raise ValueError(f"t and load must be (T,) and signals (T, {nx}) = (T, nx); got {t.shape}, {load.shape}, {signals.shape}")
        bad = ~(np.isfinite(t) & np.isfinite(load) & np.isfinite(signals).all(1))
        if bad.any():
            raise ValueError(f"sample {self._received + int(np.argmax(bad))}: t, load and signals must be finite")
        self._check_times(t)
        if len(t):
            self.start_time = float(t[0]) if self.start_time is None else self.start_time
            self._last_time = float(t[-1])
        self._load = np.concatenate([self._load, load])
        self._signals = np.concatenate([self._signals, signals.T], 1)
        self._received += len(t)
        done = []
        step = self.chain.step_samples
        while self._next_start() + step + 1 < self._received:  # the sample after the step's end is in
            done.append(self._run_step())
        return done

    def finish(self) -> list[HealthStatus]:
        """Run the step that ends at the record's last sample, if the record completes it."""
        self._finished = True
        if self._next_start() + self.chain.step_samples + 1 == self._received:
            return [self._run_step()]
        return []

    def _next_start(self) -> int:
        """Record index of the next step's first sample."""
        return len(self.statuses) * self.chain.step_samples

    def _check_times(self, t: np.ndarray) -> None:
        """Each sample comes one sample period (within 1 %) after the one before, across chunks too."""
        h = self.chain.h
        previous = [] if self._last_time is None else [self._last_time]
        intervals = np.diff(np.concatenate([previous, t]))
        offset = len(t) - len(intervals)  # 1 at the record's start: its first sample ends no interval
        uneven = np.abs(intervals - h) > 0.01 * h
        if uneven.any():
            j = int(np.argmax(uneven))
            raise ValueError(
                f"sample {self._received + j + offset}: t = {t[j + offset]:.9g} s is {intervals[j]:.6g} s after the one "
                f"before; the chain samples every {h:g} s"
            )

    def _run_step(self) -> HealthStatus:
        """Run the next step through the chain and drop the samples no later step needs."""
        chain = self.chain
        start, step = self._next_start(), chain.step_samples
        offset = start - self._first  # the step's first sample in the buffer
        end = offset + step + 1
        # the derivative over the step, from the samples either side where the record has them
        context = slice(max(offset - 1, 0), min(end + 1, self._load.shape[0]))
        load_rate = np.gradient(self._load[context], chain.h)[offset - context.start :][: step + 1]
        load = self._load[offset:end]
        measured = self._signals[:, offset:end][None]
        if self._reference_state is None:
            self._reference_state = fitted_initial_state(chain, measured, load[None], load_rate[None])
        reference, self._reference_state = reference_signals(chain, load[None], load_rate[None], self._reference_state)
        status = chain.update(measured, reference, load[None], load_rate[None])
        self.statuses.append(status)
        keep = start + step - 1  # the next step's start and the sample before it
        self._load, self._signals = self._load[keep - self._first :], self._signals[:, keep - self._first :]
        self._first = keep
        return status


def check_duration(measurements: Measurements, config: PHMConfig) -> None:
    """Refuse a record that does not last one detection window (``DetectorConfig.window``), before any
    chain is built for it."""
    timing = config.timing
    needed = max(timing.step, config.detector.window)
    if measurements.duration < needed - 0.5 / timing.sample_rate:
        raise ValueError(
            f"measurements: the record lasts {measurements.duration:g} s; the chain needs at least {needed:g} s "
            f"(one detection window), i.e. {round(needed * timing.sample_rate) + 1} samples at {timing.sample_rate:g} Hz"
        )


def run_measurements(chain: PHMChain, measurements: Measurements, progress: Progress | None = None) -> ChainRun:
    """A machine's recorded ``measurements`` through ``chain`` (N = 1, at their sample rate), a step at a time.

    Raises:
        ValueError: the record does not last one detection window (:func:`check_duration`).
    """
    check_duration(measurements, chain.config)
    stream = StreamingChain(chain)
    step = chain.step_samples
    starts: Iterable[int] = range(0, len(measurements.t), step)
    for start in starts if progress is None else progress(starts):
        part = slice(start, start + step)
        stream.feed(measurements.t[part], measurements.load[part], measurements.signals[part])
    stream.finish()
    return ChainRun.of(stream.statuses)


def chain_sample_rate(record_rate: float, config: PHMConfig = PHMConfig()) -> float:
    """The sample rate (Hz) the chain runs a record of ``record_rate`` Hz at: the record's own where an EA sub-window
    (``MonitorConfig.sub_window``, 0.1 s) is a whole number of its samples (a multiple of 10 Hz), else the next
    multiple above it, which :func:`~ea_gym.measurements.resampled` brings the record to (no band is lost)."""
    per_sub_window = record_rate * config.monitor.sub_window
    if per_sub_window >= 1 and abs(per_sub_window - round(per_sub_window)) <= 1e-9 * per_sub_window:
        return record_rate
    return math.ceil(per_sub_window) / config.monitor.sub_window


def chain_config(sample_rate: float, noise: float, load_noise: float = 0.0) -> PHMConfig:
    """The chain's settings at ``sample_rate`` (Hz, a whole number of samples per sub-window), sensor ``noise`` and the load
    measurement's ``load_noise`` (fractions of each signal's RMS over a step, ``ChainTiming``): the defaults, with a
    smoothing window that fits a step (``MonitorConfig.fitting``: the default 51 samples above 50 Hz)."""
    timing = ChainTiming(sample_rate=sample_rate, noise=noise, load_noise=load_noise)
    monitor = PHMConfig().monitor.fitting(window_samples(timing.step, 1.0 / sample_rate))
    return PHMConfig(timing=timing, monitor=monitor)


def build_chain(
    model: SystemModel, config: PHMConfig, classifier: FaultClassifier, rng: np.random.Generator, n_systems: int = 1
) -> PHMChain:
    """A chain for ``model`` with its detection thresholds calibrated at ``config.timing.noise`` (or read from the cache: see
    :func:`~ea_gym.phm.thresholds.thresholds_for`)."""
    return PHMChain(model, classifier, thresholds_for(model, config, rng), config, n_systems)


def classifier_for(model: SystemModel, path: str | None = None) -> FaultClassifier:
    """The isolation network: from ``path``, else the one shipped for the model, else the cached one, else trained now
    and cached (:func:`~ea_gym.diagnosis.training.isolation_network`)."""
    from ea_gym.diagnosis.training import isolation_network

    return FaultClassifier.load(path) if path is not None else isolation_network(model)
