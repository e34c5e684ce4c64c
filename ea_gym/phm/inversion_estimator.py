"""The "ea_inversion" estimator: the paper's EA inversion behind the ``ParameterEstimator`` seam (paper 3.3, 4.4).

It inverts each ``InversionConfig.window`` of signals (:class:`~ea_gym.phm.inversion.EAInversion`),
warm-started from the hypothesis's previous value, and filters successive windows with a causal
median: its estimate describes the parameter ``InversionTiming.lag`` seconds before the step's end.
Its evidence is minus the running average of each hypothesis's log fit cost. Its prognosis is the
trend of its recent estimates extrapolated to the limits (``TrendPrognosis``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numba
import numpy as np

from ea_gym.diagnosis.database import classes_of
from ea_gym.diagnosis.monitor import Monitor
from ea_gym.energy import window_samples
from ea_gym.models import SystemModel
from ea_gym.phm.config import ChainTiming, InversionConfig, PHMConfig
from ea_gym.phm.estimation import ParameterEstimates, StepSignals
from ea_gym.phm.history import push_window, rows_of
from ea_gym.phm.inversion import EAInversion
from ea_gym.phm.prognosis import TrendPrognosis
from ea_gym.phm.registry import EstimationStages, register_estimator


@numba.njit(cache=True)
def push_median(raw: np.ndarray, rows: np.ndarray, columns: np.ndarray, values: np.ndarray, median: np.ndarray) -> None:
    """Push ``values`` (K,) into the windows raw[rows, columns] (N, D, W) and write each window's
    ``np.nanmedian`` to median[rows, columns]: the mean of the two middle values when an even number
    are finite, NaN when none is. In place (the fancy-indexed numpy form copies every window twice)."""
    W = raw.shape[2]
    finite = np.empty(W)
    for k in range(len(rows)):
        window = raw[rows[k], columns[k]]
        for t in range(W - 1):
            window[t] = window[t + 1]
        window[W - 1] = values[k]
        count = 0
        for t in range(W):
            v = window[t]
            if not np.isnan(v):
                # insertion sort: the windows are a few values long
                i = count
                while i > 0 and finite[i - 1] > v:
                    finite[i] = finite[i - 1]
                    i -= 1
                finite[i] = v
                count += 1
        if count == 0:
            median[rows[k], columns[k]] = np.nan
        elif count % 2 == 1:
            median[rows[k], columns[k]] = finite[count // 2]
        else:
            median[rows[k], columns[k]] = (finite[count // 2 - 1] + finite[count // 2]) / 2.0


@dataclass(frozen=True)
class InversionTiming:
    """When the EA inversion's estimates come and what they describe.

    Attributes:
        steps: updates per inversion window (the estimator starts after so many).
        median: successive windows' estimates in the causal median.
        lag: a filtered estimate describes the middle of its inversion window, and a causal median of
            successive windows the middle of their span: so many seconds before the step's end.
    """

    steps: int
    median: int
    lag: float

    @property
    def correlated(self) -> int:
        """Successive estimates sharing their windows' data and the median's: so many are not independent."""
        return self.steps + self.median - 1


def inversion_timing(config: InversionConfig, timing: ChainTiming) -> InversionTiming:
    """The EA inversion's timing under its ``config`` and the chain's ``timing``."""
    steps = window_samples(config.window, timing.step)
    median = config.median
    return InversionTiming(steps=steps, median=median, lag=0.5 * (steps + median - 1) * timing.update_time)


@dataclass
class InversionState:
    """Per system (N) and degradable parameter (D).

    Attributes:
        steps: updates since the last reset, (N,).
        signals: raw measured signals of the inversion window, its smoothing context before it and as
            much again (so that the state it starts from is smoothed with samples on both sides), (N, nx, S).
        load: the load and its rate over the same samples, (N, 2, S).
        raw: the last ``median`` window estimates of each hypothesis, NaN where none, (N, D, W).
        estimates: their median (nominal before the first), (N, D).
        fit: running average of each hypothesis's log fit cost, "none" first, NaN before the first, (N, D + 1).
        nominal: the degradable parameters' nominal values, where the estimates start, (D,).
    """

    steps: np.ndarray
    signals: np.ndarray
    load: np.ndarray
    raw: np.ndarray
    estimates: np.ndarray
    fit: np.ndarray
    nominal: np.ndarray

    @classmethod
    def new(cls, n: int, states: int, samples: int, median: int, nominal: np.ndarray) -> InversionState:
        D = len(nominal)
        state = cls(
            steps=np.empty(n, dtype=int), signals=np.empty((n, states, samples)), load=np.empty((n, 2, samples)),
            raw=np.empty((n, D, median)), estimates=np.empty((n, D)), fit=np.empty((n, D + 1)), nominal=nominal,
        )
        state.reset()
        return state

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Start over for all systems, or for those where the boolean mask (N,) is true."""
        rows = rows_of(systems)
        self.steps[rows] = 0
        self.signals[rows] = 0.0
        self.load[rows] = 0.0
        self.raw[rows] = np.nan
        self.estimates[rows] = self.nominal
        self.fit[rows] = np.nan


class EAInversionEstimator:
    """The EA inversion behind the ``ParameterEstimator`` seam (paper 3.3, 4.4).

    After an alarm every hypothesis the chain names is inverted at every step over the last
    ``InversionConfig.window`` seconds; each starts from its nominal value (a fault is young when it is
    detected) and follows its own estimates from window to window. The nominal model's fit, the
    evidence for "none", is computed on the same window at every step.

    Args:
        model: the monitored system.
        monitor: the chain's monitor, whose denoising and nominal laws the inversion repeats.
        config: the inversion's settings.
        timing: the chain's step and clock.
        n_systems: N.
    """

    def __init__(self, model: SystemModel, monitor: Monitor, config: InversionConfig, timing: ChainTiming, n_systems: int):
        self.model = model
        self.monitor = monitor
        self.config = config
        self.n = n_systems
        self.inversion = EAInversion(monitor, config)
        self.degradable: tuple[str, ...] = classes_of(model)[1:]
        self.timing = inversion_timing(config, timing)
        self.lag = self.timing.lag
        self.warmup_steps = self.timing.steps
        self.degradable_index = np.array([model.parameter_names.index(p) for p in self.degradable])
        nominal = model.parameter_vector()[self.degradable_index]
        step_samples = window_samples(timing.step, monitor.h)
        # the inversion window, the candidates' smoothing context before it, and as much again
        samples = self.timing.steps * step_samples + 2 * monitor.config.smoothing + 1
        self.state = InversionState.new(n_systems, len(model.state_names), samples, self.timing.median, nominal)

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Start over for all systems (None), or for those where the boolean mask (N,) is true."""
        self.state.reset(systems)

    def record_adjustment(self, systems: np.ndarray, parameters: np.ndarray, changes: np.ndarray) -> None:
        """Shift the estimates of hypothesis ``parameters[k]`` of system ``systems[k]`` by ``changes[k]``."""
        s = self.state
        s.raw[systems, parameters] += np.asarray(changes, dtype=float)[:, None]
        s.estimates[systems, parameters] += changes

    def restart(self, systems: np.ndarray, parameters: np.ndarray) -> None:
        """Start hypothesis ``parameters[k]`` of system ``systems[k]`` afresh: from nominal, its median emptied."""
        self.state.raw[systems, parameters] = np.nan

    def update(self, signals: StepSignals, alarm: np.ndarray, suspects: np.ndarray) -> ParameterEstimates:
        """Buffer the step's signals and invert the window of every suspect of the systems in alarm."""
        s = self.state
        s.steps = s.steps + 1
        s.signals = push_window(s.signals, signals.measured[..., 1:])
        s.load = push_window(s.load, np.stack([signals.load, signals.load_rate], axis=1)[..., 1:])
        # nothing to estimate before an alarm: the chain then believes the nominal values
        ready = (s.steps >= self.timing.steps) & alarm
        chosen = np.zeros((self.n, len(self.degradable)), dtype=bool)
        if np.any(ready):
            chosen = suspects & ready[:, None]
            self._invert(chosen, ready)
        nothing = np.full(chosen.shape, np.nan)
        return ParameterEstimates(
            value=s.estimates.copy(), variance=nothing, drift=nothing, drift_variance=nothing, covariance=nothing, log_evidence=-s.fit,
            estimated=chosen, time=np.repeat((signals.t - self.timing.lag)[:, None], chosen.shape[1], axis=1),
        )

    def _invert(self, chosen: np.ndarray, ready: np.ndarray) -> None:
        """Invert the window of every chosen (system, hypothesis) and of the nominal model; update the median and the fits."""
        s = self.state
        inversion = self.inversion
        systems = np.flatnonzero(ready)
        c = self.monitor.config.smoothing
        signals, load = s.signals[systems], s.load[systems][..., c:]
        start = self.monitor.state_filter(signals[..., : 2 * c + 1])[..., c]
        # the measured EA is recomputed over one contiguous stretch, processed exactly as the
        # candidates' signals are: weakly identifiable parameters (a light damper) feel any mismatch
        power, _ = self.monitor.powers(np.concatenate([signals[..., c:], load[:, :1]], axis=1), c)
        measured = inversion.signature(power)
        # "none": any one degradable parameter at its nominal value, the others nominal too
        nominal_cost = inversion.fit_cost(
            np.full(len(systems), self.degradable_index[0]), np.full(len(systems), s.nominal[0]), start, load[:, 0], load[:, 1], measured
        )
        rows, columns = np.nonzero(chosen)
        at = np.searchsorted(systems, rows)  # each (system, hypothesis) pair's row among the ready systems
        # a fault is young when it is detected: a hypothesis without an estimate starts from nominal
        previous = s.raw[rows, columns, -1]
        previous = np.where(np.isnan(previous), s.nominal[columns], previous)
        values, cost = inversion.estimate(
            self.degradable_index[columns], start[at], load[at, 0], load[at, 1], measured[at], previous=previous,
        )
        # running average of each hypothesis's log fit cost, "none" first (the floor keeps noise-free fits finite)
        pairs = (np.concatenate([systems, rows]), np.concatenate([np.zeros(len(systems), dtype=int), columns + 1]))
        log_cost = np.log(np.concatenate([nominal_cost, cost]) + 1e-12)
        fit = s.fit[pairs]
        s.fit[pairs] = np.where(np.isnan(fit), log_cost, fit + self.config.fit_smoothing * (log_cost - fit))
        push_median(s.raw, rows, columns, np.ascontiguousarray(values, dtype=float), s.estimates)


@register_estimator("ea_inversion")
def ea_inversion_stages(model: SystemModel, monitor: Monitor, config: PHMConfig, n_systems: int) -> EstimationStages:
    """The EA inversion (``config.inversion``) and the trend of its recent estimates (``config.extrapolation``)."""
    estimator = EAInversionEstimator(model, monitor, config.inversion, config.timing, n_systems)
    history_length = int(round(config.extrapolation.span / config.timing.update_time)) + 1
    # successive estimates share their windows' data and the median's: so many are not independent
    extrapolation = replace(config.extrapolation, correlated=estimator.timing.correlated)
    return EstimationStages(estimator, TrendPrognosis(model, estimator.degradable, extrapolation, history_length, n_systems))
