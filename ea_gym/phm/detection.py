"""Detection: relative EA residuals against thresholds calibrated on fault-free runs, with persistence.

Detection compares, element by element, the EA residual summed over the last ``DetectorConfig.window``
seconds with the reference EA over the same span; the threshold is calibrated on fault-free runs at
the same noise level (:func:`calibrate_thresholds`), and so does the energy-balance residual relative
to the dissipators' EA (where a dissipator's fault shows); an alarm needs ``persistence`` steps in a
row.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ea_gym._kernels.detection import detect
from ea_gym.diagnosis.database import draw_loads
from ea_gym.diagnosis.monitor import Monitor
from ea_gym.energy import window_samples
from ea_gym.models import SystemModel
from ea_gym.numerics import TINY
from ea_gym.phm.config import DetectorConfig, PHMConfig
from ea_gym.phm.history import MonitorHistory, rows_of
from ea_gym.sensors import Sensors, add_sensor_noise
from ea_gym.threads import over_rows


def relative_residuals(ea: np.ndarray, ea_reference: np.ndarray, balance: np.ndarray, dissipated: np.ndarray) -> np.ndarray:
    """Detection statistics: (..., E + 1).

    Args:
        ea, ea_reference: real and reference EA of every element summed over the EA window (J), (..., E).
        balance: the energy-balance residual, real minus reference, summed over the balance window (J), (...).
        dissipated: the dissipators' reference EA over the balance window (J), (...): a dissipator's
            fault leaves that share of its dissipation unaccounted for, while barely changing any
            element's EA.

    Returns:
        (ea - ea_reference) / ea_reference per element, then balance / dissipated.
    """
    relative = (ea - ea_reference) / np.maximum(ea_reference, TINY)
    return np.concatenate([relative, (balance / np.maximum(dissipated, TINY))[..., None]], axis=-1)


@dataclass
class DetectionState:
    """Per system: consecutive steps above threshold (N,), the alarm (N,) and its time (s, NaN before), (N,)."""

    above: np.ndarray
    alarm: np.ndarray
    detection_time: np.ndarray

    @classmethod
    def new(cls, n: int) -> DetectionState:
        state = cls(above=np.empty(n, dtype=int), alarm=np.empty(n, dtype=bool), detection_time=np.empty(n))
        state.reset()
        return state

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Start over for all systems, or for those where the boolean mask (N,) is true."""
        rows = rows_of(systems)
        self.above[rows] = 0
        self.alarm[rows] = False
        self.detection_time[rows] = np.nan


class Detector:
    """The alarm of N systems from the monitor's history.

    Args:
        thresholds: threshold of every element's relative EA residual and of the energy balance's, (E + 1,).
        config: detection settings.
        monitor: the monitor whose outputs the history holds.
        step: seconds of signal per update.
        n_systems: N.
    """

    def __init__(self, thresholds: np.ndarray, config: DetectorConfig, monitor: Monitor, step: float, n_systems: int):
        self.thresholds = np.asarray(thresholds, dtype=float)
        self.config = config
        self.step_samples = window_samples(step, monitor.h)
        self.window_subs = window_samples(config.window, monitor.config.sub_window)
        self.balance_steps = window_samples(config.balance_span, step)
        # samples each statistic needs before it means anything: its whole span
        self.span_samples = np.append(np.full(len(monitor.elements), self.window_subs * monitor.n_sub), self.balance_steps * self.step_samples)
        self.state = DetectionState.new(n_systems)

    def update(self, history: MonitorHistory) -> np.ndarray:
        """The statistic (N, E + 1) after the newest step: relative EA residual of every element and relative
        energy-balance residual over the detection window (``relative_residuals``, 0 until its window is
        full); raises the alarm of systems above threshold long enough. Compiled, numpy's sums to the bit."""
        s = self.state
        statistic = np.empty((len(history.time), len(self.thresholds)))
        ea, ea_reference, balance, dissipated, steps, time = (
            history.ea, history.ea_reference, history.balance, history.dissipated, history.steps, history.time
        )

        def detect_rows(start: int, stop: int) -> None:
            detect(
                start, stop, ea, ea_reference, self.window_subs, balance, dissipated, steps, self.step_samples, self.span_samples,
                self.thresholds, self.config.persistence, time, TINY, s.above, s.alarm, s.detection_time, statistic,
            )

        over_rows(detect_rows, len(statistic))
        return statistic


def calibrate_thresholds(model: SystemModel, config: PHMConfig, rng: np.random.Generator) -> np.ndarray:
    """Detection thresholds from fault-free runs under random loads at ``config.timing.noise``, (E + 1,).

    Where the load is measured with noise (``config.timing.load_noise`` > 0), the reference model runs on the
    load as measured (as the chain's does: the harness drives it with the recorded load) and the monitor reads
    that load as the source's value: the noise passes through the model's dynamics into the reference signals,
    and every element's EA residual gains a part the sensors' noise does not make. The thresholds rise with it,
    and a fault must be that much larger to be detected (the joint filter's estimates do not depend on it).
    """
    from ea_gym.bondgraph.simulation import simulate_batch

    d = config.detector
    timing = config.timing
    h = 1.0 / timing.sample_rate
    runs = d.calibration_runs
    loads = draw_loads(model, runs, rng)
    t = np.arange(int(round(d.calibration_duration * timing.sample_rate)) + 1) * h
    u = np.stack([load.value(t) for load in loads])
    du = np.stack([load.derivative(t) for load in loads])
    nominal = np.repeat(model.parameter_vector()[None], runs, 0)
    states = simulate_batch(model.state_space, h, *model.source_inputs(u, du), nominal, np.zeros((runs, len(model.state_names))))
    monitor = Monitor(model, h, config.monitor, runs)
    clean = Sensors(model).measure(nominal, states, 0.0, rng)
    step = window_samples(timing.step, h)
    subs = window_samples(config.detector.window, config.monitor.sub_window)
    measured_load, reference = u, clean
    if timing.load_noise > 0:  # each step's load read with noise of its RMS, its rate the central difference
        measured_load = np.concatenate([add_sensor_noise(u[:, s : s + step], timing.load_noise, rng) for s in range(0, len(t), step)], -1)
        rate = np.gradient(measured_load, h, axis=-1)
        reference_states = simulate_batch(
            model.state_space, h, *model.source_inputs(measured_load, rate), nominal, np.zeros((runs, len(model.state_names)))
        )
        reference = Sensors(model).measure(nominal, reference_states, 0.0, rng)
    windows = []
    for start in range(0, len(t) - 1, step):
        part = slice(start, start + step + 1)
        noisy = add_sensor_noise(clean[..., part], timing.noise, rng)
        windows.append(monitor.update(noisy, reference[..., part], measured_load[:, part]))
    # the balance windows are whole sub-windows: spread each over its sub-windows to align the sums
    per_sub = window_samples(config.monitor.balance_window, config.monitor.sub_window)
    balance = np.concatenate([w.balance for w in windows], -1).repeat(per_sub, -1) / per_sub
    ea, ref = np.concatenate([w.ea for w in windows], -1), np.concatenate([w.ea_reference for w in windows], -1)
    balance_subs = window_samples(d.balance_span, config.monitor.sub_window)

    def sums(x: np.ndarray, span: int) -> np.ndarray:  # every window of ``span`` sub-windows, first axis
        return np.moveaxis(sliding_window_view(x, span, axis=-1).sum(-1), -1, 0)

    # each statistic's threshold is its own maximum: the EA and balance windows need not be aligned
    dissipated = ref[:, monitor.component_index[monitor.dissipators]].sum(1)
    ea_statistic = relative_residuals(sums(ea, subs), sums(ref, subs), sums(balance, subs), sums(dissipated, subs))
    balance_statistic = relative_residuals(
        sums(ea, balance_subs), sums(ref, balance_subs), sums(balance, balance_subs), sums(dissipated, balance_subs)
    )
    largest = np.append(np.abs(ea_statistic[..., :-1]).max(axis=(0, 1)), np.abs(balance_statistic[..., -1]).max())
    return np.maximum(d.margin * largest, d.floor)
