"""The PHM chain's settings, one frozen record with a section per stage."""

from __future__ import annotations

from dataclasses import dataclass, field

from ea_gym.diagnosis.monitor import MonitorConfig
from ea_gym.phm.detection import DetectorConfig
from ea_gym.phm.estimators import ESTIMATORS
from ea_gym.phm.inversion import EstimatorConfig
from ea_gym.phm.prognosis import ExtrapolationConfig
from ea_gym.phm.tracking import TrackingConfig


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
        estimator_kind: the parameter estimator and its prognosis (a key of ``ea_gym.phm.estimators.ESTIMATORS``):
            "tracking", a Kalman filter per hypothesis tracking the parameter and its drift, the drift
            carried to the limits; "ea_inversion", the paper's EA inversion with a median filter, its
            trend extrapolated.
        tracking: the tracking filters' settings (process noise, priors, the evidence's memory).
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
    estimator_kind: str = "tracking"
    monitor: MonitorConfig = field(default_factory=MonitorConfig)
    detector: DetectorConfig = field(default_factory=DetectorConfig)
    estimator: EstimatorConfig = field(default_factory=EstimatorConfig)
    extrapolation: ExtrapolationConfig = field(default_factory=ExtrapolationConfig)
    tracking: TrackingConfig = field(default_factory=TrackingConfig)

    def __post_init__(self) -> None:
        samples = self.step * self.sample_rate
        if not (samples > 0.5 and abs(samples - round(samples)) <= 1e-9 * max(1.0, samples)):
            raise ValueError(
                f"sample_rate: {self.sample_rate:g} Hz gives {samples:g} samples per {self.step:g} s step of the PHM chain; "
                f"expected a whole number >= 1 of samples per step (a multiple of {1 / self.step:g} Hz)"
            )
        if self.estimator_kind not in ESTIMATORS:
            raise ValueError(f"estimator_kind must be one of {', '.join(sorted(ESTIMATORS))}, got {self.estimator_kind!r}")

    @property
    def update_time(self) -> float:
        """Seconds of the prognosis clock per update: ``step_time``, or ``step`` when it is None."""
        return self.step if self.step_time is None else self.step_time
