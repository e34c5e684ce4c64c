"""The PHM chain on Energy Activity, online and batched over N systems (paper section 3, Fig 5).

Each ``update`` takes one step of signals (measured, reference, load) for every system and returns its
health: EA, EAI and residuals of every element, the detection alarm, the class probabilities of the
isolation network, the estimate of every degradable parameter (each as if it alone were faulty), the
isolated parameter's estimate and its End of Life and RUL with an interval.

Detection compares, element by element, the EA residual summed over the last ``detector.window``
seconds with the reference EA over the same span; the threshold is calibrated on fault-free runs at
the same noise level (``calibrate_thresholds``), and so does the energy-balance residual relative to the
dissipators' EA (where a dissipator's fault shows); an alarm needs ``persistence`` steps in a row.
Isolation weighs three kinds of evidence. The network's probabilities are averaged (exponentially) over
the frames seen since the alarm; the EA inversion, run for every hypothesis "parameter j alone has
changed", says how well each hypothesis explains the measured EA (its fit cost; the nominal model's,
simulated and processed exactly like the candidates, for "none"); and the energy balance of the last
few seconds, regressed on the energies the components absorb, says how much worse it is explained
with component j's column alone (``balance_chi_square``). The belief in class j is the network's
share of it (plus a floor) times c_min / c_j, the running ratio of the best fit cost to j's, times
exp(-(chi2_j - chi2_min) / 2), deflated: a network that cannot yet tell a small fault apart does not
outvote a hypothesis that the EA fits a hundred times better, and a young storage fault (which the
balance pins to a tenth of a per cent) is not taken for the light damper, whose EA fit it can mimic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numba
import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.diagnosis.database import classes_of, draw_loads
from ea_gym.diagnosis.features import frame_features
from ea_gym.diagnosis.monitor import Monitor, MonitorConfig, MonitorWindow
from ea_gym.energy import activity_index, window_samples
from ea_gym.models import SystemModel
from ea_gym.numerics import TINY
from ea_gym.prognosis import (
    EAParameterEstimator,
    EstimatorConfig,
    ExtrapolationConfig,
    predict_end_of_life,
)
from ea_gym.sensors import add_sensor_noise, measure


@dataclass(frozen=True)
class DetectorConfig:
    """Residual detection.

    Attributes:
        window: span of the EA residual sums compared with the threshold (s).
        balance_span: span of the energy-balance residual sum (s, a whole number of steps): its noise
            grows slower than a dissipator's fault, so a longer span sees a smaller fault (at 1 % noise
            the threshold is about 18 % of the light damper's dissipation over 20 s, 8 % over 60 s),
            later (the sum describes the middle of its span).
        persistence: consecutive steps above threshold that raise the alarm.
        margin: threshold = margin x the largest statistic seen in fault-free calibration runs.
        floor: smallest threshold (relative EA residual), for noise-free signals.
        calibration_runs: fault-free runs simulated for the calibration.
        calibration_duration: their length (s).
    """

    window: float = 5.0
    balance_span: float = 60.0
    persistence: int = 3
    margin: float = 1.25
    floor: float = 1e-3
    calibration_runs: int = 8
    calibration_duration: float = 180.0

    def __post_init__(self) -> None:
        if self.calibration_duration < max(self.window, self.balance_span):
            raise ValueError(
                f"detector.calibration_duration ({self.calibration_duration} s) must be at least its window "
                f"({self.window} s) and balance_span ({self.balance_span} s)"
            )


@dataclass(frozen=True)
class PHMConfig:
    """The whole chain's settings.

    Attributes:
        step: seconds of signal per update (an environment step's window).
        step_time: seconds of (degradation) time an update stands for, the clock of the prognosis;
            None: equal to ``step`` (continuous operation).
        sample_rate: Hz.
        noise: sensor noise, fraction of each measured signal's RMS over a step.
        frame: isolation frame (s); must equal the frame the classifier was trained on.
        isolation_smoothing: weight of the newest frame in the running average of class probabilities.
        fit_smoothing: weight of the newest step in the running average of each hypothesis's log fit cost.
        network_floor: added to the network's share of every class before it is weighed by the fit
            evidence, so that a network unsure of a small fault cannot veto the hypothesis the EA fits.
        isolation_confidence: the suspect's share of the fault classes' belief above which only its parameter is
            estimated (below it, every degradable parameter is, so that a change of suspect finds a
            history) and its End of Life predicted.
        balance_evidence_span: span (s, a whole number of steps) of the energy-balance regression that
            weighs the hypotheses (``balance_chi_square``): short, so that a young storage fault (detected
            at a fraction of a per cent) is not averaged away with the fault-free time before it.
        balance_inflation: the balance evidence's chi-squares are divided by it. The residual's noise is
            correlated over the smoothing filter's span, so the regression's own variance understates
            it: fault-free runs at 1 % noise give chi-squares 2.3 x their degrees of freedom over 10 s;
            4 was the best of 1, 2 and 4 on development episodes (decision cost).
    """

    step: float = 1.0
    step_time: float | None = None
    sample_rate: float = 100.0
    noise: float = 0.0
    frame: float = 20.0
    isolation_smoothing: float = 0.2
    fit_smoothing: float = 0.3
    network_floor: float = 0.1
    isolation_confidence: float = 0.75
    balance_evidence_span: float = 10.0
    balance_inflation: float = 4.0
    monitor: MonitorConfig = field(default_factory=MonitorConfig)
    detector: DetectorConfig = field(default_factory=DetectorConfig)
    estimator: EstimatorConfig = field(default_factory=EstimatorConfig)
    extrapolation: ExtrapolationConfig = field(default_factory=ExtrapolationConfig)


@dataclass(frozen=True)
class HealthStatus:
    """The chain's output after one update, one row per system.

    Attributes:
        t: time since the last reset at the end of the step (s), (N,).
        ea, ea_reference, residual: EA of every element over the step and its residual (J), (N, E).
        eai, eai_reference: EAI of every component over the step, (N, C).
        statistic: relative EA residual of every element over the detection window, (N, E).
        alarm: a fault has been detected, (N,); detection_time: when (s), NaN before.
        probabilities: the newest frame's isolation class probabilities, (N, K) ("none" = 1 before an
            alarm and until a full frame).
        diagnosis: the chain's belief ("none" = 1 before the alarm), (N, K): the network's running
            average since the alarm weighed by the EA fit of each hypothesis.
        isolated: class index of the isolated parameter, 0 while none, (N,).
        estimates: estimate of every degradable parameter, (N, D), each as if it alone were faulty.
        estimate: the isolated parameter's filtered estimate, NaN while none, (N,); it describes the
            parameter ``PHMChain.estimate_lag`` seconds before ``t``.
        eol, eol_low, eol_high: End of Life and interval (s), inf while no trend reaches a limit, (N,).
    """

    t: np.ndarray
    ea: np.ndarray
    ea_reference: np.ndarray
    residual: np.ndarray
    eai: np.ndarray
    eai_reference: np.ndarray
    statistic: np.ndarray
    alarm: np.ndarray
    detection_time: np.ndarray
    probabilities: np.ndarray
    diagnosis: np.ndarray
    isolated: np.ndarray
    estimates: np.ndarray
    estimate: np.ndarray
    eol: np.ndarray
    eol_low: np.ndarray
    eol_high: np.ndarray

    @property
    def rul(self) -> np.ndarray:
        """Point RUL and its interval (s), (N, 3); inf where no End of Life is predicted."""
        return np.stack([self.eol, self.eol_low, self.eol_high], axis=1) - self.t[:, None]


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


def balance_chi_square(gram: np.ndarray, cross: np.ndarray, square: np.ndarray, windows: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """How much worse the energy balance is explained under each isolation class, (N, 1 + D).

    The balance residual R of every balance window (real minus reference, J) is regressed on the
    energies the components absorb in it: a fault of component i with relative coefficient change
    beta_i adds beta_i E_i. "None" keeps no column, "degradable parameter j alone has changed" its
    component's column alone. The chi-square of a class is the rise of the residual sum of squares
    over the full regression's, in units of the full regression's residual variance.

    Args:
        gram: sum over the windows of E_i E_j, (N, C, C) in J^2.
        cross: sum of E_i R, (N, C) in J^2.
        square: sum of R^2, (N,) in J^2.
        windows: number of windows summed, (N,).
        columns: each degradable parameter's component column, -1 for one that is no component's: such
            a hypothesis cannot be judged by the balance and gets the smallest chi-square (no evidence).
    """
    C = gram.shape[-1]
    # a pseudo-inverse: a component the span barely excites drops out instead of taking a ridge's bias
    explained = np.einsum("ni,nij,nj->n", cross, np.linalg.pinv(gram, rcond=1e-12, hermitian=True), cross)
    variance = np.maximum(square - explained, TINY) / np.maximum(windows - C, 1)
    diagonal = np.diagonal(gram, axis1=-2, axis2=-1)
    single = cross**2 / np.maximum(diagonal, TINY)  # explained by one column alone
    chi2 = np.empty((len(square), 1 + len(columns)))
    chi2[:, 0] = explained
    chi2[:, 1:] = explained[:, None] - np.where(columns >= 0, single[:, columns], explained[:, None])
    chi2 = np.maximum(chi2, 0.0) / variance[:, None]
    chi2[:, 1:] = np.where(columns >= 0, chi2[:, 1:], chi2.min(1, keepdims=True))
    return chi2


@numba.njit(cache=True)
def _push_median(raw: np.ndarray, rows: np.ndarray, columns: np.ndarray, values: np.ndarray, median: np.ndarray) -> None:
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


def _push(buffer: np.ndarray, new: np.ndarray) -> np.ndarray:
    """Append ``new`` (..., k) along the last axis and drop as many of the oldest entries; returns the buffer.

    The buffer is a window on the last axis of a backing array twice its length (its ``base``, made
    at the first push): each push slides the window on, and only when it reaches the backing
    array's end are its entries moved back to the start. The history is then copied once per
    buffer length's worth of pushes instead of at every push, and no array is allocated.
    """
    k, T = new.shape[-1], buffer.shape[-1]
    backing = buffer.base
    if not _is_window(buffer, backing):
        backing = np.empty(buffer.shape[:-1] + (2 * T,), dtype=buffer.dtype)
        backing[..., :T] = buffer
        buffer = backing[..., :T]
    start = (buffer.ctypes.data - backing.ctypes.data) // buffer.itemsize + k
    if start + T > backing.shape[-1]:
        # the entries kept lie past T - k, clear of where they go: no overlap
        backing[..., : T - k] = buffer[..., k:]
        start = 0
    window = backing[..., start : start + T]
    window[..., T - k :] = new
    return window


def _is_window(buffer: np.ndarray, backing: np.ndarray | None) -> bool:
    """Whether ``buffer`` is a window on the last axis of a backing array ``_push`` made: C-contiguous, twice its length."""
    return (
        backing is not None
        and backing.flags.c_contiguous
        and backing.dtype == buffer.dtype
        and backing.shape[:-1] == buffer.shape[:-1]
        and backing.strides == buffer.strides
        and backing.shape[-1] == 2 * buffer.shape[-1]
    )


class PHMChain:
    """The online chain for N systems of one model.

    Args:
        model: the monitored system (nominal values, safe limits).
        classifier: the isolation network (its classes are "none" then the degradable parameters).
        thresholds: detection threshold of every element's relative EA residual, (E,).
        config: chain settings.
        n_systems: N.
    """

    def __init__(self, model: SystemModel, classifier: FaultClassifier, thresholds: np.ndarray, config: PHMConfig, n_systems: int = 1):
        self.model = model
        self.config = config
        self.n = n_systems
        self.h = 1.0 / config.sample_rate
        self.classifier = classifier
        self.classes = classes_of(model)
        if tuple(classifier.classes) != self.classes:
            raise ValueError(f"classifier classes {classifier.classes} do not match the model's {self.classes}")
        self.monitor = Monitor(model, self.h, config.monitor, n_systems)
        self.estimator = EAParameterEstimator(self.monitor, config.estimator)
        self.thresholds = np.asarray(thresholds, dtype=float)
        self.degradable = self.classes[1:]
        self._degradable_index = np.array([model.parameter_names.index(p) for p in self.degradable])
        self._nominal = model.parameter_vector()[self._degradable_index]  # of the degradable parameters
        self.step_samples = window_samples(config.step, self.h)
        self.frame_steps = window_samples(config.frame, config.step)
        self.detect_subs = window_samples(config.detector.window, config.monitor.sub_window)
        self.balance_steps = window_samples(config.detector.balance_span, config.step)
        self._dissipators = self.monitor._component_index[self.monitor.dissipators]  # element indices
        self.evidence_steps = window_samples(config.balance_evidence_span, config.step)
        self.regression_steps = max(self.frame_steps, self.evidence_steps)
        self.balance_windows_per_step = self.step_samples // (self.monitor.n_sub * self.monitor.n_balance)
        # each degradable parameter's column in the balance regression (-1: not a component's)
        self._balance_column = np.array([self.monitor.components.index(p) if p in self.monitor.components else -1 for p in self.degradable])
        self.estimate_steps = window_samples(config.estimator.window, config.step)
        self.median_length = config.estimator.median
        self.step_time = config.step if config.step_time is None else config.step_time
        # a filtered estimate describes the middle of its inversion window, and a causal median of
        # successive windows the middle of their span
        self.estimate_lag = 0.5 * (self.estimate_steps + self.median_length - 1) * self.step_time
        self.history_length = int(round(config.extrapolation.span / self.step_time)) + 1
        # successive estimates share their windows' data and the median's: so many are not independent
        self.extrapolation = replace(config.extrapolation, correlated=self.estimate_steps + self.median_length - 1)
        self.reset()

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Start over for all systems, or for those where the boolean mask is true."""
        E, C, nx = len(self.monitor.elements), len(self.monitor.components), len(self.model.state_names)
        D = len(self.degradable)
        subs = self.frame_steps * (self.step_samples // self.monitor.n_sub)
        # raw signals for the inversion: its window, the candidates' smoothing context before it, and
        # as much again so that the state it starts from is smoothed with samples on both sides
        signal_samples = self.estimate_steps * self.step_samples + 2 * self.monitor.config.smoothing + 1
        # each entry's shape after the system axis and its initial value (its dtype: int, bool or float)
        initial = {
            "time": ((), 0.0),
            "steps": ((), 0),
            "ea": ((E, subs), 0.0),
            "ea_reference": ((E, subs), 0.0),
            # the isolation frame and the balance evidence need only their sums: one entry per step
            "gram": ((C, C, self.regression_steps), 0.0),
            "cross": ((C, self.regression_steps), 0.0),
            # the balance statistic's sums per step over its span, and the balance evidence's sum of squares
            "balance": ((self.balance_steps,), 0.0),
            "balance_square": ((self.evidence_steps,), 0.0),
            "dissipated": ((self.balance_steps,), 0.0),
            "noise": ((2, nx, self.frame_steps), 0.0),
            "signals": ((nx, signal_samples), 0.0),
            "load": ((2, signal_samples), 0.0),
            "above": ((), 0),
            "alarm": ((), False),
            "detection_time": ((), np.nan),
            "probability_average": ((len(self.classes),), 0.0),
            "raw": ((D, self.median_length), np.nan),
            "estimates": ((D,), self._nominal),
            "history_t": ((self.history_length,), np.nan),
            "history": ((D, self.history_length), np.nan),
            "fit": ((D + 1,), np.nan),
            "estimated": ((D,), False),
            "isolated": ((), 0),
            "confident": ((), False),
        }
        if systems is None:
            self.state = {key: np.full((self.n, *shape), value) for key, (shape, value) in initial.items()}
            self.monitor.reset()
            return
        # the rows are written in place, with no fresh array of their size (a good share of the
        # systems is reset at every step under random actions)
        rows = np.flatnonzero(systems)
        for key, (_, value) in initial.items():
            self.state[key][rows] = value
        self.monitor.reset(systems)

    def record_adjustment(self, systems: np.ndarray, parameters: np.ndarray, changes: np.ndarray) -> None:
        """Log maintenance that moved degradable parameter ``parameters[k]`` (index into ``degradable``) of
        system ``systems[k]`` (distinct systems) by ``changes[k]`` (its SI unit) before the next update.

        The estimates so far are shifted by the change, as if it had always been there: the trend the
        prognosis extrapolates stays the wear's, now from the adjusted value, instead of reading the
        correction as a reversal of the wear.
        """
        s = self.state
        for key in ("raw", "history"):
            s[key][systems, parameters] += np.asarray(changes, dtype=float)[:, None]
        s["estimates"][systems, parameters] += changes

    def update(self, measured: np.ndarray, reference: np.ndarray, load: np.ndarray, load_rate: np.ndarray) -> HealthStatus:
        """Process one step.

        Args:
            measured: noisy measured signals (flows of I, displacements of C), (N, nx, L + 1).
            reference: the reference model's signals, same shape.
            load, load_rate: the source's value and time derivative, (N, L + 1).
        """
        s = self.state
        window: MonitorWindow = self.monitor.update(measured, reference, load)
        s["time"] = s["time"] + self.step_time
        s["steps"] = s["steps"] + 1
        for key, value in (("ea", window.ea), ("ea_reference", window.ea_reference)):
            s[key] = _push(s[key], value)
        s["gram"] = _push(s["gram"], window.gram.sum(axis=1)[..., None])
        s["cross"] = _push(s["cross"], window.cross.sum(axis=1)[..., None])
        s["balance"] = _push(s["balance"], window.balance.sum(-1)[:, None])
        s["balance_square"] = _push(s["balance_square"], (window.balance**2).sum(-1)[:, None])
        s["dissipated"] = _push(s["dissipated"], window.ea_reference[:, self._dissipators].sum((1, 2))[:, None])
        s["noise"] = _push(s["noise"], window.noise[..., None])
        s["signals"] = _push(s["signals"], measured[..., 1:])
        s["load"] = _push(s["load"], np.stack([load, load_rate], axis=1)[..., 1:])

        ea, ea_ref = window.ea.sum(-1), window.ea_reference.sum(-1)
        components = self.monitor._component_index
        eai = np.stack(list(activity_index(dict(enumerate(ea[:, components].T))).values()), axis=1)
        eai_ref = np.stack(list(activity_index(dict(enumerate(ea_ref[:, components].T))).values()), axis=1)

        statistic = self._statistic()
        above = np.any(np.abs(statistic) > self.thresholds, axis=1)
        s["above"] = np.where(above, s["above"] + 1, 0)
        new_alarm = ~s["alarm"] & (s["above"] >= self.config.detector.persistence)
        s["detection_time"] = np.where(new_alarm, s["time"], s["detection_time"])
        s["alarm"] = s["alarm"] | new_alarm

        probabilities = self._classify()
        estimates = self._estimate()
        diagnosis = self._isolate()
        estimate, eol = self._prognose(estimates)
        return HealthStatus(
            t=s["time"].copy(), ea=ea, ea_reference=ea_ref, residual=ea - ea_ref, eai=eai, eai_reference=eai_ref,
            statistic=statistic, alarm=s["alarm"].copy(), detection_time=s["detection_time"].copy(),
            probabilities=probabilities, diagnosis=diagnosis, isolated=s["isolated"].copy(), estimates=estimates, estimate=estimate,
            eol=eol[:, 0], eol_low=eol[:, 1], eol_high=eol[:, 2],
        )

    @property
    def statistic_names(self) -> tuple[str, ...]:
        """What the columns of ``HealthStatus.statistic`` (and the thresholds) watch."""
        return (*self.monitor.elements, "energy balance")

    def _statistic(self) -> np.ndarray:
        """Relative EA residual of every element and relative energy-balance residual over the detection window, (N, E + 1)."""
        s = self.state
        statistic = relative_residuals(
            s["ea"][..., -self.detect_subs :].sum(-1), s["ea_reference"][..., -self.detect_subs :].sum(-1),
            s["balance"].sum(-1), s["dissipated"].sum(-1),
        )
        full = np.append(np.full(statistic.shape[1] - 1, self.detect_subs * self.monitor.n_sub), self.balance_steps * self.step_samples)
        return np.where((s["steps"] * self.step_samples)[:, None] >= full, statistic, 0.0)

    def _classify(self) -> np.ndarray:
        """The newest frame's network class probabilities (N, K); updates their running average."""
        s = self.state
        probabilities = np.zeros((self.n, len(self.classes)))
        probabilities[:, 0] = 1.0
        # isolation only matters once a fault is detected, and needs a full frame
        counted = (s["steps"] >= self.frame_steps) & s["alarm"]
        if np.any(counted):
            noise = s["noise"][counted].sum(-1)
            frame = self.monitor.frame_of(
                s["ea"][counted], s["ea_reference"][counted],
                s["gram"][counted, ..., -self.frame_steps :].sum(-1), s["cross"][counted, ..., -self.frame_steps :].sum(-1), noise,
            )
            features = frame_features(frame, self.classifier.variant, self.model.excitation_bandwidth)
            probabilities[counted] = self.classifier.predict_proba(features)
        # an exponential average over the frames since the alarm: later frames, with the fault grown,
        # outweigh the first ambiguous ones
        weight = self.config.isolation_smoothing
        s["probability_average"][counted] += weight * (probabilities[counted] - s["probability_average"][counted])
        return probabilities

    def _isolate(self) -> np.ndarray:
        """The chain's belief (N, K) from the network's average, the hypotheses' fit costs and the balance; sets the suspect."""
        s = self.state
        K = len(self.classes)
        total = s["probability_average"].sum(1, keepdims=True)
        # before the network's first frame its belief is uniform: the fits alone decide
        network = np.where(total > 0, s["probability_average"] / np.where(total > 0, total, 1.0), 1.0 / K)
        fit = s["fit"]
        evidence = np.exp(np.min(fit, axis=1, initial=np.inf, where=np.isfinite(fit))[:, None] - fit)
        evidence = np.where(np.isfinite(evidence), evidence, 1.0)  # a hypothesis not yet fitted: no evidence either way
        belief = (network + self.config.network_floor) * evidence * self._balance_evidence()
        believed = s["alarm"] & (np.any(np.isfinite(fit[:, 1:]), axis=1) | (total[:, 0] > 0))
        diagnosis = np.where(believed[:, None], belief / belief.sum(1, keepdims=True), np.eye(K)[0])
        isolated = np.where(believed, 1 + np.argmax(diagnosis[:, 1:], axis=1), 0)
        # a new suspect not estimated at this step has stale estimates: start it afresh
        changed = np.flatnonzero((isolated != s["isolated"]) & (isolated > 0))
        changed = changed[~s["estimated"][changed, isolated[changed] - 1]]
        s["raw"][changed, isolated[changed] - 1] = np.nan
        s["isolated"] = isolated
        # the alarm already says there is a fault: confidence is the suspect's share among the fault classes
        share = diagnosis[np.arange(self.n), isolated] / np.maximum(diagnosis[:, 1:].sum(1), TINY)
        s["confident"] = (isolated > 0) & (share >= self.config.isolation_confidence)
        return diagnosis

    def _balance_evidence(self) -> np.ndarray:
        """Likelihood ratio (N, K) of each class to the best one from the energy balance of the last ``balance_evidence_span``."""
        s = self.state
        evidence = np.ones((self.n, len(self.classes)))
        rows = np.flatnonzero(s["alarm"])
        if len(rows) == 0:
            return evidence
        span = self.evidence_steps
        chi2 = balance_chi_square(
            s["gram"][rows, ..., -span:].sum(-1), s["cross"][rows, ..., -span:].sum(-1), s["balance_square"][rows].sum(-1),
            np.minimum(s["steps"][rows], span) * self.balance_windows_per_step, self._balance_column,
        )
        # the residual's noise is correlated across windows (the smoothing filter spans several), so
        # the regression's own variance understates it: chi-squares are deflated by a calibrated factor
        evidence[rows] = np.exp(-0.5 * (chi2 - chi2.min(1, keepdims=True)) / self.config.balance_inflation)
        return evidence

    def _estimate(self) -> np.ndarray:
        """Latest filtered EA-inversion estimate of every degradable parameter, (N, D).

        After an alarm every degradable parameter is estimated at every step (each as if it alone were
        faulty) until the isolation is confident of a suspect; from then on the suspect alone, and the
        others keep their last value. Each starts from its nominal value (a fault is young when it is
        detected) and follows its own estimates from window to window. The nominal model's fit, the
        evidence for "none", is computed on the same window at every step.
        """
        s = self.state
        D = len(self.degradable)
        # nothing to estimate before an alarm: the chain then believes the nominal values
        ready = (s["steps"] >= self.estimate_steps) & s["alarm"]
        s["estimated"] = np.zeros((self.n, D), dtype=bool)
        if not np.any(ready):
            return s["estimates"].copy()
        # every parameter until the isolation is confident of a suspect, then the suspect alone
        chosen = np.where(s["confident"][:, None], np.arange(D) == s["isolated"][:, None] - 1, True) & ready[:, None]
        systems = np.flatnonzero(ready)
        c = self.monitor.config.smoothing
        signals, load = s["signals"][systems], s["load"][systems][..., c:]
        start = self.monitor.state_filter(signals[..., : 2 * c + 1])[..., c]
        # the measured EA is recomputed over one contiguous stretch, processed exactly as the
        # candidates' signals are: weakly identifiable parameters (a light damper) feel any mismatch
        power, _ = self.monitor.powers(np.concatenate([signals[..., c:], load[:, :1]], axis=1), c)
        measured = self.estimator.signature(power)
        # "none": any one degradable parameter at its nominal value, the others nominal too
        nominal_cost = self.estimator.fit_cost(
            np.full(len(systems), self._degradable_index[0]), np.full(len(systems), self._nominal[0]), start, load[:, 0], load[:, 1], measured
        )
        rows, columns = np.nonzero(chosen)
        at = np.searchsorted(systems, rows)  # each (system, hypothesis) pair's row among the ready systems
        raw = s["raw"]
        # a fault is young when it is detected: a hypothesis without an estimate starts from nominal
        previous = raw[rows, columns, -1]
        previous = np.where(np.isnan(previous), self._nominal[columns], previous)
        values, cost = self.estimator.estimate(
            self._degradable_index[columns], start[at], load[at, 0], load[at, 1], measured[at], previous=previous,
        )
        # running average of each hypothesis's log fit cost, "none" first (the floor keeps noise-free fits finite)
        pairs = (np.concatenate([systems, rows]), np.concatenate([np.zeros(len(systems), dtype=int), columns + 1]))
        log_cost = np.log(np.concatenate([nominal_cost, cost]) + 1e-12)
        fit = s["fit"][pairs]
        s["fit"][pairs] = np.where(np.isnan(fit), log_cost, fit + self.config.fit_smoothing * (log_cost - fit))
        s["estimated"] = chosen
        _push_median(raw, rows, columns, np.ascontiguousarray(values, dtype=float), s["estimates"])
        fresh = np.full((self.n, D), np.nan)
        fresh[rows, columns] = s["estimates"][rows, columns]
        s["history"] = _push(s["history"], fresh[..., None])
        s["history_t"] = _push(s["history_t"], (s["time"] - self.estimate_lag)[:, None])
        return s["estimates"].copy()

    def _prognose(self, estimates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s = self.state
        estimate = np.full(self.n, np.nan)
        eol = np.full((self.n, 3), math.inf)
        isolated = s["confident"]  # no End of Life for a suspect the isolation is unsure of
        if not np.any(isolated):
            return estimate, eol
        rows = np.flatnonzero(isolated)
        estimate[rows] = estimates[rows, s["isolated"][rows] - 1]
        for i in rows:
            d = s["isolated"][i] - 1
            history = s["history"][i, d]
            valid = np.isfinite(history)
            prediction = predict_end_of_life(
                s["history_t"][i, valid], history[valid], self.model.safe_limits[self.degradable[d]],
                float(s["time"][i]), self.extrapolation,
            )
            if prediction is not None:
                eol[i] = (prediction.eol, prediction.eol_low, prediction.eol_high)
        return estimate, eol


def calibrate_thresholds(model: SystemModel, config: PHMConfig, rng: np.random.Generator) -> np.ndarray:
    """Detection thresholds from fault-free runs under random loads at ``config.noise``, (E,)."""
    from ea_gym.bondgraph.simulation import simulate_batch

    d = config.detector
    h = 1.0 / config.sample_rate
    runs = d.calibration_runs
    loads = draw_loads(model, runs, rng)
    t = np.arange(int(round(d.calibration_duration * config.sample_rate)) + 1) * h
    u = np.stack([load.value(t) for load in loads])
    du = np.stack([load.derivative(t) for load in loads])
    nominal = np.repeat(model.parameter_vector()[None], runs, 0)
    states = simulate_batch(model.state_space, h, u[..., None], du[..., None], nominal, np.zeros((runs, len(model.state_names))))
    monitor = Monitor(model, h, config.monitor, runs)
    clean = measure(monitor, nominal, states, 0.0, rng)
    step = window_samples(config.step, h)
    subs = window_samples(config.detector.window, config.monitor.sub_window)
    windows = []
    for start in range(0, len(t) - 1, step):
        part = slice(start, start + step + 1)
        noisy = add_sensor_noise(clean[..., part], config.noise, rng)
        windows.append(monitor.update(noisy, clean[..., part], u[:, part]))
    # the balance windows are whole sub-windows: spread each over its sub-windows to align the sums
    per_sub = window_samples(config.monitor.balance_window, config.monitor.sub_window)
    balance = np.concatenate([w.balance for w in windows], -1).repeat(per_sub, -1) / per_sub
    ea, ref = np.concatenate([w.ea for w in windows], -1), np.concatenate([w.ea_reference for w in windows], -1)
    balance_subs = window_samples(d.balance_span, config.monitor.sub_window)

    def sums(x: np.ndarray, span: int) -> np.ndarray:  # every window of ``span`` sub-windows, first axis
        return np.moveaxis(sliding_window_view(x, span, axis=-1).sum(-1), -1, 0)

    # each statistic's threshold is its own maximum: the EA and balance windows need not be aligned
    dissipated = ref[:, monitor._component_index[monitor.dissipators]].sum(1)
    ea_statistic = relative_residuals(sums(ea, subs), sums(ref, subs), sums(balance, subs), sums(dissipated, subs))
    balance_statistic = relative_residuals(
        sums(ea, balance_subs), sums(ref, balance_subs), sums(balance, balance_subs), sums(dissipated, balance_subs)
    )
    largest = np.append(np.abs(ea_statistic[..., :-1]).max(axis=(0, 1)), np.abs(balance_statistic[..., -1]).max())
    return np.maximum(d.margin * largest, d.floor)


@dataclass(frozen=True)
class ChainRun:
    """A scenario run through the chain: the statuses of every step and the ground truth."""

    statuses: list[HealthStatus]
    t: np.ndarray  # end of every step (s)
    true_parameters: np.ndarray  # at the end of every step, (steps, P)
    residual_series: np.ndarray  # EA residual of every element per sub-window, (E, n_sub_total)


def run_scenario(scenario, chain: PHMChain, rng: np.random.Generator, progress=None) -> ChainRun:
    """Simulate ``scenario``'s plant and the reference model and feed them step by step through ``chain`` (N = 1)."""
    from ea_gym.plant import run_model

    model = scenario.model
    t = scenario.times()
    load = scenario.make_load()
    plant = run_model(model, t, load, scenario.parameters_at, scenario.initial_state_vector())
    reference = run_model(model, t, load, None, scenario.initial_state_vector())
    nominal = model.parameter_vector()[None]
    clean = measure(chain.monitor, plant.parameters[None], plant.states[None], 0.0, rng)
    expected = measure(chain.monitor, nominal, reference.states[None], 0.0, rng)
    u, du = load.value(t)[None], load.derivative(t)[None]
    step = chain.step_samples
    statuses, residuals = [], []
    chain.reset()
    starts = range(0, len(t) - step, step)
    for start in starts if progress is None else progress(starts):
        part = slice(start, start + step + 1)
        noisy = add_sensor_noise(clean[..., part], chain.config.noise, rng)
        status = chain.update(noisy, expected[..., part], u[:, part], du[:, part])
        statuses.append(status)
        residuals.append(chain.state["ea"][0, :, -(step // chain.monitor.n_sub):] - chain.state["ea_reference"][0, :, -(step // chain.monitor.n_sub):])
    ends = np.array([s.t[0] for s in statuses])
    index = np.round(ends * scenario.sample_rate).astype(int)
    return ChainRun(statuses=statuses, t=ends, true_parameters=plant.parameters[index], residual_series=np.concatenate(residuals, -1))


def build_chain(
    model: SystemModel, config: PHMConfig, classifier: FaultClassifier, rng: np.random.Generator, n_systems: int = 1
) -> PHMChain:
    """A chain for ``model`` with its detection thresholds calibrated at ``config.noise``."""
    return PHMChain(model, classifier, calibrate_thresholds(model, config, rng), config, n_systems)


def classifier_for(model: SystemModel, rng: np.random.Generator, path: str | None = None) -> FaultClassifier:
    """The isolation network: from ``path``, else the one shipped for the model, else trained now."""
    from ea_gym.diagnosis.training import (
        load_shipped_classifier,
        shipped_classifier_path,
        train_isolation,
    )

    if path is not None:
        return FaultClassifier.load(path)
    if shipped_classifier_path(model.name).is_file():
        return load_shipped_classifier(model.name)
    return train_isolation(model, rng, variants=("strong",)).classifiers["strong"]
