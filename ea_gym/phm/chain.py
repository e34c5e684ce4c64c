"""The PHM chain on Energy Activity, online and batched over N systems (paper section 3, Fig 5).

Each ``update`` takes one step of signals (measured, reference, load) for every system and passes it
through the stages: the monitor (EA, EAI and residuals of every element), detection (the alarm),
the isolation network, the parameter estimator (every degradable parameter, each as if it alone were
faulty), the model-fit test on its innovations, the fusion of their evidence (the suspect and the
chain's belief) and the prognosis (the suspect's End of Life and RUL with an interval). Beside them
(``JointFilterConfig.beside``, on by default) the joint filter (:mod:`~ea_gym.phm.joint`) estimates every
part at once with its drift: every part's health (:class:`PartHealth`: its value, its probability of
degrading, whether it is named degrading and its own End of Life), the set of degrading parts rather
than one suspect; the model-fit test then reads the joint filter's innovations. While the model is not
known to fit the data, no part is isolated or named and no End of Life given. It returns a
:class:`HealthStatus`, the typed record of the step that reporting reads. Each stage keeps its own
per-system state.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.diagnosis.database import classes_of
from ea_gym.diagnosis.monitor import Monitor, MonitorWindow
from ea_gym.energy import step_activity_index, window_samples
from ea_gym.models import SystemModel
from ea_gym.phm.config import PHMConfig
from ea_gym.phm.detection import Detector
from ea_gym.phm.estimation import ParameterEstimates, StepSignals
from ea_gym.phm.fit import ModelFit, ModelFitTest
from ea_gym.phm.history import MonitorHistory
from ea_gym.phm.isolation import Isolation
from ea_gym.phm.joint import JointFilter
from ea_gym.phm.prognosis import DriftPrognosis, EndOfLife
from ea_gym.phm.registry import make_stages
from ea_gym.sensors import Sensors


@dataclass(frozen=True)
class PartHealth:
    """Every degradable part of N systems after one update, from the joint filter; columns in ``names`` order
    (``PHMChain.degradable``).

    Attributes:
        names: the parts (degradable parameters), D of them.
        t: the time the values describe, the step's end (s), (N,).
        value: each part's estimate (its SI unit), (N, D); std: its standard deviation, NaN where none (a filter the data threw off), (N, D).
        degrading: each part's probability of degrading (its drift beyond ``JointFilterConfig.degrading_rate``
            of its safe span per second), in [0, 1], (N, D).
        named: the part is judged degrading: its ``degrading`` reached ``JointFilterConfig.name_probability`` and has
            not fallen below ``release_probability`` since; False everywhere while the model is not known to fit
            (``HealthStatus.model_fit``), (N, D).
        eol, eol_low, eol_high: each named part's End of Life and its interval (s): its value and drift carried
            to the safe limit it heads for (``ea_gym.phm.prognosis.drift_end_of_life``); inf where the part is
            not named or does not reach a limit within ``ExtrapolationConfig.horizon``, (N, D).
    """

    names: tuple[str, ...]
    t: np.ndarray
    value: np.ndarray
    std: np.ndarray
    degrading: np.ndarray
    named: np.ndarray
    eol: np.ndarray
    eol_low: np.ndarray
    eol_high: np.ndarray

    @property
    def rul(self) -> np.ndarray:
        """Each part's RUL, point, low and high (s), (N, D, 3); inf where it has no End of Life."""
        return np.stack([self.eol, self.eol_low, self.eol_high], axis=-1) - self.t[:, None, None]

    @property
    def machine_rul(self) -> np.ndarray:
        """The machine's RUL (s), (N, 3): the row of the part whose End of Life comes soonest, inf where none has one."""
        rul = self.rul
        soonest = np.take_along_axis(rul, np.argmin(self.eol, axis=1)[:, None, None], axis=1)[:, 0]
        return np.where(np.isfinite(soonest[:, :1]), soonest, np.inf)


@dataclass(frozen=True)
class HealthStatus:
    """The chain's output after one update, one row per system.

    Attributes:
        t: time since the last reset at the end of the step (s), (N,).
        ea, ea_reference, residual: EA of every element over the step and its residual (J), (N, E).
        sub_residual: the EA residual of every element per sub-window of the step (J), (N, E, S).
        eai, eai_reference: EAI of every component over the step, (N, C).
        statistic: relative EA residual of every element over the detection window, (N, E).
        alarm: a fault has been detected, (N,); detection_time: when (s), NaN before.
        probabilities: the newest frame's isolation class probabilities, (N, K) ("none" = 1 before an
            alarm and until a full frame).
        counted: whether the newest frame entered the network's running average (alarm raised and a
            full frame seen), (N,).
        diagnosis: the chain's belief ("none" = 1 before the alarm), (N, K): the network's running
            average since the alarm weighed by the estimator's and the energy balance's evidence.
        isolated: class index of the isolated parameter, 0 while none (and while the model is not known
            to fit: ``model_fit``), (N,).
        confidence: the suspect's share of the fault classes' belief, 0 while none, (N,); confident:
            at or above ``IsolationConfig.confidence`` (only then is an End of Life predicted).
        estimates: estimate of every degradable parameter, (N, D), each as if it alone were faulty.
        estimation: the estimator's whole output (variances, evidence, which it updated, the times its
            values describe).
        estimate: the isolated parameter's filtered estimate, NaN while none, (N,); it describes the
            parameter ``PHMChain.estimate_lag`` seconds before ``t``.
        eol, eol_low, eol_high: End of Life and interval (s), inf where none is predicted, (N,).
        end_of_life: each system's prediction with what it extrapolates (a trend fit or a tracked
            drift), None where none was made.
        model_fit: the model-fit test's verdict ("model does not fit" instead of a diagnosis); None where
            the test is off (``ModelFitConfig.enabled``) or neither the estimator nor a joint filter beside it
            has innovations.
        parts: every part's health from the joint filter; None where the chain runs without one (an
            estimator other than "joint" and ``JointFilterConfig.beside`` False).
    """

    t: np.ndarray
    ea: np.ndarray
    ea_reference: np.ndarray
    residual: np.ndarray
    sub_residual: np.ndarray
    eai: np.ndarray
    eai_reference: np.ndarray
    statistic: np.ndarray
    alarm: np.ndarray
    detection_time: np.ndarray
    probabilities: np.ndarray
    counted: np.ndarray
    diagnosis: np.ndarray
    isolated: np.ndarray
    confidence: np.ndarray
    confident: np.ndarray
    estimates: np.ndarray
    estimation: ParameterEstimates
    estimate: np.ndarray
    eol: np.ndarray
    eol_low: np.ndarray
    eol_high: np.ndarray
    end_of_life: Sequence[EndOfLife | None]
    model_fit: ModelFit | None = None
    parts: PartHealth | None = None

    @property
    def rul(self) -> np.ndarray:
        """Point RUL and its interval (s), (N, 3); inf where no End of Life is predicted."""
        rul = np.empty((len(self.t), 3))  # filled column by column: np.stack's checks cost more than the copies
        rul[:, 0], rul[:, 1], rul[:, 2] = self.eol, self.eol_low, self.eol_high
        rul -= self.t[:, None]
        return rul


class PHMChain:
    """The online chain for N systems of one model.

    Args:
        model: the monitored system (nominal values, safe limits).
        classifier: the isolation network (its classes are "none" then the degradable parameters).
        thresholds: detection threshold of every element's relative EA residual and of the energy balance's, (E + 1,).
        config: chain settings.
        n_systems: N.
    """

    def __init__(self, model: SystemModel, classifier: FaultClassifier, thresholds: np.ndarray, config: PHMConfig, n_systems: int = 1):
        self.model = model
        self.config = config
        self.n = n_systems
        timing = config.timing
        self.h = 1.0 / timing.sample_rate
        self.classifier = classifier
        self.classes = classes_of(model)
        if tuple(classifier.classes) != self.classes:
            raise ValueError(f"classifier classes {classifier.classes} do not match the model's {self.classes}")
        self.degradable = self.classes[1:]
        # the healthy machine's whole parameter vectors, (N, P): the reference model is simulated with them
        self.reference_parameters = np.repeat(model.parameter_vector()[None], n_systems, axis=0)
        self.sensors = Sensors(model)  # how the plant and the reference are measured
        self.monitor = Monitor(model, self.h, config.monitor, n_systems)
        self.step_samples = window_samples(timing.step, self.h)
        self.step_time = timing.update_time
        self.detector = Detector(thresholds, config.detector, self.monitor, timing.step, n_systems)
        self.thresholds = self.detector.thresholds
        # the estimator and the prognosis that reads it come together (``PHMConfig.estimator_kind``, ``ea_gym.phm.registry``)
        stages = make_stages(model, self.monitor, config, n_systems)
        self.estimator, self.prognosis = stages.estimator, stages.prognosis
        # every part's health: the joint filter, the estimator itself where it is one, else one beside it (or none)
        self.joint: JointFilter | None = None
        if isinstance(self.estimator, JointFilter):
            self.joint = self.estimator
        elif config.joint.beside:
            self.joint = JointFilter(model, timing.sample_rate, timing.noise, n_systems, config=config.joint, load_noise=timing.load_noise)
        self._beside = self.joint is not None and self.joint is not self.estimator
        self.part_prognosis = None if self.joint is None else DriftPrognosis(
            model, self.joint.degradable, config.extrapolation, self.joint.diffusion, n_systems
        )
        innovations = self.joint if self.joint is not None else stages.innovations  # the filter that explains every part
        self._named = np.zeros((n_systems, len(self.degradable)), dtype=bool)  # each part named degrading, before the fit's veto
        self.innovations = innovations if config.fit.enabled else None
        self.fit = None if self.innovations is None else ModelFitTest(config.fit, timing, n_systems)
        self.isolation = Isolation(classifier, self.monitor, config.isolation, timing, self.classes, n_systems, stages.weights)
        self.frame_steps = self.isolation.frame_steps
        if tuple(self.estimator.degradable) != self.degradable:
            raise ValueError(f"the estimator's parameters {self.estimator.degradable} are not the classifier's {self.degradable}")
        self.estimate_steps, self.estimate_lag = self.estimator.warmup_steps, self.estimator.lag
        self._dissipators = self.monitor.component_index[self.monitor.dissipators]  # element indices
        self.history = MonitorHistory.new(
            n_systems, len(self.monitor.elements), len(self.monitor.components), len(model.state_names),
            subs=self.frame_steps * (self.step_samples // self.monitor.n_sub), frame_steps=self.frame_steps,
            regression_steps=max(self.frame_steps, self.isolation.evidence_steps), balance_steps=self.detector.balance_steps,
            evidence_steps=self.isolation.evidence_steps,
        )

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Start over for all systems, or for those where the boolean mask (N,) is true."""
        self.history.reset(systems)
        self.detector.state.reset(systems)
        self.isolation.state.reset(systems)
        self.estimator.reset(systems)
        if self._beside and self.joint is not None:
            self.joint.reset(systems)
        self._named[slice(None) if systems is None else np.asarray(systems, dtype=bool)] = False
        self.prognosis.reset(systems)
        self.monitor.reset(systems)
        if self.fit is not None:
            self.fit.reset(systems)

    def commission(self, values: np.ndarray, systems: np.ndarray | None = None, std: np.ndarray | None = None) -> None:
        """Make ``values`` each machine's healthy values of its degradable parts (``degradable`` order, SI): the faults
        sought are departures from them (``ea_gym.phm.commission`` fits them from healthy signals).

        ``reference_parameters`` takes them (the reference model must be simulated with these parameter vectors),
        the joint filter starts over around them with ``std`` as each part's prior std, floored at
        ``JointFilterConfig.commissioned_prior`` of its safe span (None: the floor), and the machines start over
        (``reset``); later resets keep them.

        Args:
            values: (N, D) for all N machines, or (M, D) for the M where the boolean mask ``systems`` (N,) is true.
            systems: which machines; None: all.
            std: the values' standard deviations, shaped as ``values``.
        """
        rows = np.ones(self.n, dtype=bool) if systems is None else np.asarray(systems, dtype=bool)
        if rows.shape != (self.n,):
            raise ValueError(f"systems must be a boolean mask of the {self.n} machines, got shape {rows.shape}")
        shape = (int(rows.sum()), len(self.degradable))
        values = np.asarray(values, dtype=float)
        if values.shape != shape:
            raise ValueError(f"values must be (M, D) = {shape}: the {', '.join(self.degradable)} of each machine commissioned, got {values.shape}")
        if not np.all(np.isfinite(values) & (values > 0)):
            raise ValueError(f"values must be finite and > 0, got {values.tolist()}")
        limits = np.array([self.model.safe_limits[name] for name in self.degradable], dtype=float)
        floor = self.config.joint.commissioned_prior * (limits[:, 1] - limits[:, 0])
        prior = np.maximum(floor, floor if std is None else np.asarray(std, dtype=float))
        if self.joint is not None:
            self.joint.commission(values, prior, rows)
        columns = [self.model.parameter_names.index(name) for name in self.degradable]
        parameters = self.reference_parameters[rows]
        parameters[:, columns] = values
        self.reference_parameters[rows] = parameters
        self.reset(rows)

    def record_adjustment(self, systems: np.ndarray, parameters: np.ndarray, changes: np.ndarray) -> None:
        """Log maintenance that moved degradable parameter ``parameters[k]`` (index into ``degradable``) of
        system ``systems[k]`` (distinct systems) by ``changes[k]`` (its SI unit) before the next update.

        The estimates so far are shifted by the change, as if it had always been there: the trend the
        prognosis extrapolates stays the wear's, now from the adjusted value, instead of reading the
        correction as a reversal of the wear.
        """
        self.estimator.record_adjustment(systems, parameters, changes)
        if self._beside and self.joint is not None:
            self.joint.record_adjustment(systems, parameters, changes)
        self.prognosis.record_adjustment(systems, parameters, changes)

    def update(self, measured: np.ndarray, reference: np.ndarray, load: np.ndarray, load_rate: np.ndarray) -> HealthStatus:
        """Process one step.

        Args:
            measured: noisy measured signals (flows of I, displacements of C), (N, nx, L + 1).
            reference: the reference model's signals, same shape.
            load, load_rate: the source's value and time derivative, (N, L + 1).
        """
        window = self.monitor.update(measured, reference, load)
        history = self.history
        history.record(window, self.step_time, self._dissipators)
        statistic = self.detector.update(history)
        alarm = self.detector.state.alarm
        probabilities = self.isolation.classify(history, alarm)
        suspects = self.isolation.suspects(len(self.degradable))
        signals = StepSignals(measured=measured, load=load, load_rate=load_rate, t=history.time)
        estimates = self.estimator.update(signals, alarm, suspects)
        if self.joint is None:
            joint_estimates = None
        elif self._beside:
            joint_estimates = self.joint.update(signals, alarm, suspects)
        else:
            joint_estimates = estimates
        fusion = self.isolation.fuse(alarm, estimates.log_evidence, estimates.estimated, self.isolation.balance_evidence(history, alarm))
        if len(fusion.restarted):  # most steps none: nothing to tell the estimator
            self.estimator.restart(fusion.restarted, fusion.isolated[fusion.restarted] - 1)
        isolated, confidence, confident = fusion.isolated, fusion.confidence, fusion.confident
        model_fit, withheld = None, None
        if self.fit is not None and self.innovations is not None:
            model_fit = self.fit.update(self.innovations.innovations(), history.time)
            withheld = model_fit.withheld  # "the model does not fit" (or not yet known) instead of a diagnosis
            isolated, confidence, confident = np.where(withheld, 0, isolated), np.where(withheld, 0.0, confidence), confident & ~withheld
        prognosis = self.prognosis.update(estimates, isolated, confident, history.time)
        parts = None
        if joint_estimates is not None and self.part_prognosis is not None:
            parts = self._part_health(self.part_prognosis, joint_estimates, withheld, history.time)
        ea, ea_ref, eai, eai_ref = self._activity_index(window)
        return HealthStatus(
            t=history.time.copy(), ea=ea, ea_reference=ea_ref, residual=ea - ea_ref, sub_residual=window.ea - window.ea_reference,
            eai=eai, eai_reference=eai_ref, statistic=statistic, alarm=alarm.copy(),
            detection_time=self.detector.state.detection_time.copy(), probabilities=probabilities,
            counted=self.isolation.counted(history, alarm), diagnosis=fusion.belief, isolated=isolated,
            confidence=confidence, confident=confident, estimates=estimates.value, estimation=estimates,
            estimate=prognosis.estimate, eol=prognosis.eol, eol_low=prognosis.eol_low, eol_high=prognosis.eol_high,
            end_of_life=prognosis.end_of_life, model_fit=model_fit, parts=parts,
        )

    def _part_health(self, prognosis: DriftPrognosis, estimates: ParameterEstimates, withheld: np.ndarray | None, t: np.ndarray) -> PartHealth:
        """Every part's health from the joint filter's ``estimates``: named from when its probability of degrading reaches
        ``JointFilterConfig.name_probability`` until it falls below ``release_probability``, unless the model-fit
        test withholds the diagnosis (``withheld`` (N,), None: the test is off), and each named part's End of Life
        (``prognosis``)."""
        assert estimates.degrading is not None  # the joint filter always gives it
        config = self.config.joint
        self._named = np.where(self._named, estimates.degrading >= config.release_probability, estimates.degrading >= config.name_probability)
        named = self._named if withheld is None else self._named & ~withheld[:, None]
        eol, eol_low, eol_high = prognosis.every_part(estimates, named)
        std = np.sqrt(np.where(estimates.variance >= 0, estimates.variance, np.nan))  # negative: a filter the data threw off
        return PartHealth(
            names=self.degradable, t=t.copy(), value=estimates.value, std=std, degrading=estimates.degrading,
            named=named, eol=eol, eol_low=eol_low, eol_high=eol_high,
        )

    def _activity_index(self, window: MonitorWindow) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every element's real and reference EA over the step (N, E) and the EAI of every component of each (N, C)."""
        return step_activity_index(window.ea, window.ea_reference, self.monitor.component_index, self.monitor.components)

    @property
    def statistic_names(self) -> tuple[str, ...]:
        """What the columns of ``HealthStatus.statistic`` (and the thresholds) watch."""
        return (*self.monitor.elements, "energy balance")
