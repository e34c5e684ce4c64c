"""The PHM chain's settings: one frozen section per stage, a timing record they share, and ``PHMConfig`` gathering them.

Each stage reads its own section and the shared :class:`ChainTiming` only. ``PHMConfig``'s fields:

* ``timing`` (:class:`ChainTiming`): step, clock, sample rate and noise level, read by every stage;
* ``estimator_kind``: the parameter estimator's name in :mod:`~ea_gym.phm.registry`;
* ``monitor`` (``ea_gym.diagnosis.monitor.MonitorConfig``): the EA monitor's signal processing;
* ``detector`` (:class:`DetectorConfig`): :mod:`~ea_gym.phm.detection` and its thresholds' calibration;
* ``isolation`` (:class:`IsolationConfig`): :mod:`~ea_gym.phm.isolation`, the network, the balance evidence, the fusion;
* ``inversion`` (:class:`InversionConfig`): the "ea_inversion" estimator (:mod:`~ea_gym.phm.inversion_estimator`);
* ``tracking`` (:class:`TrackingConfig`): the "tracking" estimator (:mod:`~ea_gym.phm.tracking`);
* ``joint`` (:class:`JointFilterConfig`): the "joint" estimator (:mod:`~ea_gym.phm.joint`), which also runs beside
  any other (``JointFilterConfig.beside``) for every part's health;
* ``extrapolation`` (:class:`ExtrapolationConfig`): :mod:`~ea_gym.phm.prognosis`, the estimate carried to the limits;
* ``fit`` (:class:`ModelFitConfig`): :mod:`~ea_gym.phm.fit`, whether the model explains the data at all.

An estimator's section is read only when that estimator is chosen (the joint filter's also when it runs beside). Example::

    from ea_gym.phm import ChainTiming, IsolationConfig, PHMConfig

    config = PHMConfig(timing=ChainTiming(sample_rate=200.0, noise=0.01), isolation=IsolationConfig(confidence=0.9))

This module imports no stage: the stages, the estimator registry and the chain import it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ea_gym.diagnosis.monitor import MonitorConfig

#: most samples the threshold calibration may simulate, its runs together (each sample holds every state, signal and
#: element power of a run: about 0.6 GB at this bound)
MAX_CALIBRATION_SAMPLES = 10_000_000


@dataclass(frozen=True)
class ChainTiming:
    """The timing and noise level of the signals the chain receives, shared by every stage.

    Attributes:
        step: seconds of signal per update (an environment step's window).
        step_time: seconds of (degradation) time an update stands for, the clock of the prognosis;
            None: equal to ``step`` (continuous operation).
        sample_rate: Hz.
        noise: sensor noise, fraction of each measured signal's RMS over a step (the detection
            thresholds are calibrated for it, the tracking filters expect it).
        load_noise: the load measurement's noise, fraction of the load's RMS over a step: the joint filter
            carries it as errors in variables (:mod:`~ea_gym.phm.joint`), and the detection thresholds are
            calibrated with the reference model driven by a load measured so (the reference model runs on the
            measured load: its noise reaches every element's reference EA, :func:`~ea_gym.phm.calibrate_thresholds`).
    """

    step: float = 1.0
    step_time: float | None = None
    sample_rate: float = 100.0
    noise: float = 0.0
    load_noise: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.load_noise) and self.load_noise >= 0):
            raise ValueError(f"load_noise must be a finite fraction >= 0 of the load's RMS, got {self.load_noise!r}")
        samples = self.step * self.sample_rate
        if not (samples > 0.5 and abs(samples - round(samples)) <= 1e-9 * max(1.0, samples)):
            raise ValueError(
                f"sample_rate: {self.sample_rate:g} Hz gives {samples:g} samples per {self.step:g} s step of the PHM chain; "
                f"expected a whole number >= 1 of samples per step (a multiple of {1 / self.step:g} Hz)"
            )

    @property
    def update_time(self) -> float:
        """Seconds of the prognosis clock per update: ``step_time``, or ``step`` when it is None."""
        return self.step if self.step_time is None else self.step_time


@dataclass(frozen=True)
class DetectorConfig:
    """Settings of the detection (:mod:`~ea_gym.phm.detection`) and of its thresholds' calibration.

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
class IsolationConfig:
    """Settings of the isolation (:mod:`~ea_gym.phm.isolation`): the network's frames, the energy balance's
    evidence and their fusion with the estimator's.

    Attributes:
        frame: isolation frame (s); must equal the frame the classifier was trained on.
        smoothing: weight of the newest frame in the running average of class probabilities.
        network_floor: added to the network's share of every class before it is weighed by the fit
            evidence, so that a network unsure of a small fault cannot veto the hypothesis the EA fits.
        confidence: the suspect's share of the fault classes' belief above which only its parameter is
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

    frame: float = 20.0
    smoothing: float = 0.2
    network_floor: float = 0.1
    confidence: float = 0.75
    balance_evidence_span: float = 10.0
    balance_inflation: float = 4.0


@dataclass(frozen=True)
class InversionConfig:
    """Settings of the EA inversion (the "ea_inversion" estimator, :mod:`~ea_gym.phm.inversion_estimator`).

    Attributes:
        window: inversion window t1 - t0 (s).
        grid: candidates per pass from the full range.
        passes: passes from the full range (each narrows the grid to two steps around the best candidate).
        margin: how far beyond the safe limits the first grid reaches, as a fraction of their span.
        warm_span: half-width of the first grid around the previous estimate, fraction of the safe
            span, when there is one: parameters change little from one window to the next, and the
            bound keeps a weakly identifiable hypothesis from leaping to explain noise or another
            component's fault.
        warm_grid: candidates per pass from a warm start (the previous value and one either side: the
            parabola through their costs gives the estimate).
        warm_passes: passes from a warm start.
        reach: how many grid steps beyond the outer candidates the estimate may go, when the best
            candidate is an outer one and the cost is convex there: the vertex of the parabola through
            the three outer candidates (a Newton step). A weakly identifiable parameter's cost is flat
            and noisy around its previous estimate; stopping at the best candidate then makes the
            estimate crawl one grid step per window behind the parameter. On the spring-mass-damper
            (300 episodes, corrective band policy) a reach of 1 cut the light damper's failures from 5 to
            2 and the episode cost from 97.7 to 94.4; 2 gave 3 failures, 96.7.
        median: length of the (causal) median filter over successive estimates (paper 4.4).
        balance_share: the energy-balance mismatch is relative to the dissipators' EA plus this share of
            all the components' EA: the balance is where a dissipator's fault shows, but its end points
            carry the stored energies' errors, which should not outweigh a good EA match.
        fit_smoothing: weight of the newest step in the running average of each hypothesis's log fit
            cost (the estimator's isolation evidence).
    """

    window: float = 3.0
    grid: int = 9
    passes: int = 3
    margin: float = 0.5
    warm_span: float = 0.05
    warm_grid: int = 3
    warm_passes: int = 1
    reach: float = 1.0
    median: int = 3
    balance_share: float = 0.2
    fit_smoothing: float = 0.3

    def __post_init__(self) -> None:
        for name in ("grid", "warm_grid"):  # the parabola through the best candidate needs two neighbours
            if not (isinstance(getattr(self, name), int) and getattr(self, name) >= 3):
                raise ValueError(f"inversion.{name} must be an integer >= 3 (candidates per pass), got {getattr(self, name)!r}")
        if not (math.isfinite(self.reach) and self.reach >= 0):
            raise ValueError(f"inversion.reach must be a finite number of grid steps >= 0, got {self.reach!r}")


@dataclass(frozen=True)
class TrackingConfig:
    """Settings of the tracking filters (the "tracking" estimator, :mod:`~ea_gym.phm.tracking`); parameter
    quantities relative to the parameter's nominal value.

    Attributes:
        theta_noise: random-walk std of theta, per sqrt(s) (1/sqrt(s)).
        parameter_theta_noise: (parameter name, std) pairs replacing ``theta_noise`` for those
            parameters, where their wear's own random walk is known (the environment's ``WearConfig``).
        drift_noise: random-walk std of the drift, per sqrt(s) (1/s^1.5): how fast a wear rate may change.
        state_noise: each energy variable's process-noise variance per sample, as a multiple of its
            measurement noise variance (covers the Hermite input's and the midpoint hold's small errors).
        theta_prior: std of theta at the start (the part is nominal, up to its tolerance of 2 %).
        drift_prior: std of the drift at the start (1/s): of the order of the wear rates a part may
            already have (see the module docstring for why neither may be tighter).
        evidence_memory: time constant (s) of the log-likelihoods' forgetting (the isolation evidence):
            20 s, so that a noisy stretch fades and a fault's evidence of the last frame or so decides
            (chosen with the route's evidence weights, ``ea_gym.phm.tracking.TRACKING_WEIGHTS``); inf: none.
        min_noise: floor of the measurement noise fraction, which keeps noise-free signals well posed.
    """

    theta_noise: float = 1e-4
    parameter_theta_noise: tuple[tuple[str, float], ...] = ()
    drift_noise: float = 4e-5
    state_noise: float = 0.0
    theta_prior: float = 0.02
    drift_prior: float = 1e-3
    evidence_memory: float = 20.0
    min_noise: float = 1e-4

    def __post_init__(self) -> None:
        for name in ("theta_noise", "drift_noise", "state_noise", "theta_prior", "drift_prior", "min_noise"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"TrackingConfig.{name} must be finite and >= 0, got {value!r}")
        for name, value in self.parameter_theta_noise:
            if not (isinstance(name, str) and math.isfinite(value) and value >= 0):
                raise ValueError(f"TrackingConfig.parameter_theta_noise must be (name, finite std >= 0) pairs, got {(name, value)!r}")
        if not self.evidence_memory > 0:
            raise ValueError(f"TrackingConfig.evidence_memory must be > 0 s, got {self.evidence_memory!r}")


@dataclass(frozen=True)
class JointFilterConfig:
    """Settings of the joint filter (the "joint" estimator, :mod:`~ea_gym.phm.joint`): one filter per system over
    the energy variables, every degradable parameter and its drift. Parameter quantities are relative to
    the parameter's nominal value, priors and thresholds to its safe span (upper - lower limit).

    Attributes:
        state_noise: each energy variable's process-noise variance per sample, as a multiple of its
            measurement noise variance: none, as the tracking filters (the filter's model is the
            plant's own discretization).
        theta_noise: each parameter's random-walk std, per sqrt(s) (1/sqrt(s)); drift_noise: each drift's,
            per sqrt(s) (1/s^1.5), how fast a wear rate may change: the tracking filters' values
            (``TrackingConfig``, measured on issue 17's ramps), not chosen again for the joint filter.
        theta_prior: std of each parameter at the start, fraction of its safe span: a machine's part may
            sit anywhere in the middle half of its range (uniform there: std 0.144 of the span).
        drift_prior: std of each drift at the start (1/s, relative to nominal).
        bound_margin: the estimates are held within the safe limits widened by this fraction of the span
            on either side (a part past its limit must still be seen past it).
        degrading_rate: a part is degrading when its drift exceeds this fraction of its safe span per
            second (its probability: P(|drift| > rate) under the filter's Gaussian). 1.5e-3: 2.5 x the
            drift's std on healthy spring-mass-damper records (5-6.5e-4 of the span per s, solve_ivp,
            1 % noise, seeds 100 and 101, not the tests') and 1.6 x the largest healthy |drift| there
            (9.3e-4); a part reaching its limit from nominal within minutes (the environment's wear, 0.5-1.5 %
            of the way per s) drifts several times faster.
        min_noise: floor of the measurement noise fraction, which keeps noise-free signals well posed.
        onset_allowance, onset_threshold: the allowance k and threshold h (both in standard deviations) of the
            CUSUM of each parameter's normalized corrections that re-opens its drift when a wear starts or its rate
            jumps (:mod:`~ea_gym.phm.joint`, "Wear onsets"): 0.5 and 5, Page's classic pair (about 900 steps
            between false re-openings for corrections of std 1; the healthy records' std is 0.92-1.05). Of the
            pairs (0.25, 4), (0.5, 4), (0.25, 5) and (0.5, 5) on the scipy-ODE records of two and three parts
            ramping (seeds 0-4, spring-mass-damper, RLC circuit, DC motor; the drift re-opened to its prior),
            (0.5, 5) named the set right the most often; inf: never re-opened.
        commissioned_prior: the smallest prior std of a commissioned part (``PHMChain.commission``), fraction of its
            safe span: a long healthy record pins a value to a few thousandths of the span, tighter than the part
            stays put between the record and the run or than the model itself holds; 0.01 is the accuracy the
            commissioning is asked for (issue 30), and a filter started tighter than its start is right takes
            the offset for a drift.
        commissioned_drift_prior: the std of a commissioned part's drift at the start, fraction of its degrading rate
            (``degrading_rate`` x span): the machine was just seen healthy, so its parts start unlikely to be
            degrading (0.5: probability 0.05), where ``drift_prior`` says they may already be wearing (probability
            0.55-0.76 on the built-ins: a part whose drift the data tells slowly, the DC motor's J, crossed
            ``name_probability`` for a few seconds on a commissioned healthy machine).
        beside: run the joint filter beside whichever estimator ``PHMConfig.estimator_kind`` chooses (where it is
            not the joint filter itself): it gives every part's health (``HealthStatus.parts``) and the
            model-fit test's innovations. False: only the chosen estimator runs, ``HealthStatus.parts`` is None
            unless that is the joint filter (the v0 environments: their episodes stay as they were).
        name_probability: a part is named degrading (``PartHealth.named``) when its probability of degrading
            reaches it. 0.9: above the probability the drift's prior alone gives (P(|drift| > rate) with the
            drift at 0 and its prior's std: 0.55-0.76 on the built-ins), which a part whose drift the data barely
            tells keeps for a while (the DC motor's J while bm starts wearing: up to 0.72); at 0.5 such parts were
            named in up to 12 % of the steps. A drifting part's probability is above 0.98 once its drift is learnt.
        release_probability: a named part stays named until its probability of degrading falls below it (0.5: until
            it is more likely steady than degrading). A part wearing at twice ``degrading_rate`` whose drift the
            data tells to a quarter of itself hovers about ``name_probability``; without the hysteresis (a release
            at 0.9) the spring-mass-damper's set of two wearing parts was named exactly in 0.925 of the steps (the
            test's seeds), with it 0.966.
    """

    state_noise: float = 0.0
    theta_noise: float = 1e-4
    drift_noise: float = 4e-5
    theta_prior: float = 0.15
    drift_prior: float = 1e-3
    bound_margin: float = 0.5
    degrading_rate: float = 1.5e-3
    min_noise: float = 1e-4
    onset_allowance: float = 0.5
    onset_threshold: float = 5.0
    commissioned_prior: float = 0.01
    commissioned_drift_prior: float = 0.5
    beside: bool = True
    name_probability: float = 0.9
    release_probability: float = 0.5

    def __post_init__(self) -> None:
        names = ("state_noise", "theta_noise", "drift_noise", "theta_prior", "drift_prior", "bound_margin", "degrading_rate", "min_noise",
                 "commissioned_prior", "commissioned_drift_prior")
        for name in names:
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"JointFilterConfig.{name} must be finite and >= 0, got {value!r}")
        if not (math.isfinite(self.onset_allowance) and self.onset_allowance >= 0):
            raise ValueError(f"JointFilterConfig.onset_allowance must be finite and >= 0, got {self.onset_allowance!r}")
        if not self.onset_threshold > 0:
            raise ValueError(f"JointFilterConfig.onset_threshold must be > 0 (inf: never), got {self.onset_threshold!r}")
        if not isinstance(self.beside, bool):
            raise ValueError(f"JointFilterConfig.beside must be True or False, got {self.beside!r}")
        if not 0 < self.name_probability <= 1:
            raise ValueError(f"JointFilterConfig.name_probability must be in (0, 1], got {self.name_probability!r}")
        if not 0 < self.release_probability <= self.name_probability:
            raise ValueError(
                f"JointFilterConfig.release_probability must be in (0, name_probability = {self.name_probability!r}], "
                f"got {self.release_probability!r}"
            )


@dataclass(frozen=True)
class ExtrapolationConfig:
    """Settings of the prognosis: the extrapolation of an estimate to the safe limits (:mod:`~ea_gym.phm.prognosis`).

    Attributes:
        degree: polynomial degree (the paper uses 1).
        span: the fit uses the estimates of the last ``span`` seconds.
        min_points: fewer estimates than this give no prediction.
        confidence: two-sided confidence of the interval (normal quantile of the trend's uncertainty).
        horizon: predictions further than this ahead are reported as inf (s).
        correlated: how many consecutive estimates share data (overlapping windows, a running median):
            their errors are correlated, the fit has that many times fewer independent points, and its
            covariance is scaled up by as much.
    """

    degree: int = 1
    span: float = 30.0
    min_points: int = 5
    confidence: float = 0.95
    horizon: float = 2000.0
    correlated: int = 1


@dataclass(frozen=True)
class ModelFitConfig:
    """Settings of the model-fit test (:mod:`~ea_gym.phm.fit`): the estimator's normalized innovations squared
    (NIS) over a window against their chi-square band.

    Attributes:
        enabled: run the test; without it the chain gives its diagnosis whatever the data. The v0
            environments leave it off (their episodes stay as they were).
        window: span of the NIS sum (s, rounded to whole steps): 10 s holds 2000 terms at 100 Hz and two
            signals, a band of +-6 % at 0.99, and is short beside the records' tens of seconds.
        probability: the band's probability under a model that fits (two-sided, chi-square with the
            window's degrees of freedom).
        tolerance: the band's upper edge is multiplied by it (30: an edge of ~32 NIS per degree of
            freedom). A model that fits is still not exact: the tracked parameter lags a fast wear or a
            repair's jump, and a real sensor's noise is not a fixed fraction of each step's RMS (the
            filters' assumption). Measured at 1 % noise: exact-model records 0.97-1.05; today's
            scenarios up to 2.4 (paper_fig10's repair); a k ramp of 10 % in 35 s with the noise a fraction
            of the whole record's RMS, 11. The misfits of a unit, a time base or a C element's form
            (``experiments/studies/model_fit.py``, 4 systems x 10 records): 139 and more (dc_motor's
            time base; the others 1.8e3 and more). The edge sits between, ~3 x above the first and ~4 x
            below the weakest misfit.
        persistence: consecutive steps whose window is above (within) the band before the verdict
            becomes "does not fit" ("fits"): one noisy window flips nothing.
    """

    enabled: bool = True
    window: float = 10.0
    probability: float = 0.99
    tolerance: float = 30.0
    persistence: int = 3

    def __post_init__(self) -> None:
        if not (math.isfinite(self.window) and self.window > 0):
            raise ValueError(f"fit.window must be a finite number of seconds > 0, got {self.window!r}")
        if not 0 < self.probability < 1:
            raise ValueError(f"fit.probability must be in (0, 1), got {self.probability!r}")
        if not (math.isfinite(self.tolerance) and self.tolerance >= 1):
            raise ValueError(f"fit.tolerance must be a finite factor >= 1, got {self.tolerance!r}")
        if not (isinstance(self.persistence, int) and self.persistence >= 1):
            raise ValueError(f"fit.persistence must be an integer >= 1 (steps), got {self.persistence!r}")


@dataclass(frozen=True)
class PHMConfig:
    """The whole chain's settings: the shared timing and a section per stage.

    Attributes:
        timing: step, clock, sample rate and noise level of the chain's signals.
        estimator_kind: the parameter estimator and its prognosis, a name registered in
            :mod:`~ea_gym.phm.registry` (checked when the chain is built): "tracking", a Kalman filter
            per hypothesis tracking the parameter and its drift, the drift carried to the limits;
            "ea_inversion", the paper's EA inversion with a median filter, its trend extrapolated;
            "joint", one filter per system over the states, every degradable parameter and its drift.
        monitor: the EA monitor's signal processing.
        detector: the residual detection and its calibration.
        isolation: the network's frames, the balance evidence and the fusion.
        inversion: the EA inversion (read by the "ea_inversion" estimator).
        tracking: the tracking filters (read by the "tracking" estimator).
        joint: the joint filter (the "joint" estimator, and beside any other: ``JointFilterConfig.beside``).
        extrapolation: the prognosis's extrapolation to the safe limits.
        fit: the model-fit test; while the model does not fit, no part is isolated and no End of Life given.
    """

    timing: ChainTiming = field(default_factory=ChainTiming)
    estimator_kind: str = "tracking"
    monitor: MonitorConfig = field(default_factory=MonitorConfig)
    detector: DetectorConfig = field(default_factory=DetectorConfig)
    isolation: IsolationConfig = field(default_factory=IsolationConfig)
    inversion: InversionConfig = field(default_factory=InversionConfig)
    tracking: TrackingConfig = field(default_factory=TrackingConfig)
    joint: JointFilterConfig = field(default_factory=JointFilterConfig)
    extrapolation: ExtrapolationConfig = field(default_factory=ExtrapolationConfig)
    fit: ModelFitConfig = field(default_factory=ModelFitConfig)

    def __post_init__(self) -> None:
        samples = self.detector.calibration_runs * self.detector.calibration_duration * self.timing.sample_rate
        if samples > MAX_CALIBRATION_SAMPLES:  # checked before the calibration allocates them (1e6 Hz asked for 86 GiB)
            raise ValueError(
                f"sample_rate: {self.timing.sample_rate:g} Hz makes the threshold calibration simulate {samples:g} samples "
                f"({self.detector.calibration_runs} runs of {self.detector.calibration_duration:g} s); at most "
                f"{MAX_CALIBRATION_SAMPLES} (a sample rate of at most "
                f"{MAX_CALIBRATION_SAMPLES / (self.detector.calibration_runs * self.detector.calibration_duration):g} Hz)"
            )
