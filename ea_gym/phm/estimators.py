"""The estimator kinds (``PHMConfig.estimator_kind``): each builds the chain's parameter estimator and
the prognosis stage that reads it.

* "ea_inversion": the paper's route, the EA inversion with a causal median
  (:class:`~ea_gym.phm.estimation.EAInversionEstimator`), its recent estimates' polynomial trend
  extrapolated to the limits (:class:`~ea_gym.phm.prognosis.TrendPrognosis`).
* "tracking": a bank of Kalman filters, one per hypothesis, tracking each parameter and its drift
  (:class:`~ea_gym.tracking.TrackingEstimator`), the drift carried to the limits with its covariance
  (:class:`~ea_gym.phm.prognosis.DriftPrognosis`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from ea_gym.diagnosis.monitor import Monitor
from ea_gym.models import SystemModel
from ea_gym.phm.estimation import EAInversionEstimator, ParameterEstimator
from ea_gym.phm.prognosis import DriftPrognosis, PrognosisStage, TrendPrognosis

if TYPE_CHECKING:
    from ea_gym.phm.config import PHMConfig


@dataclass(frozen=True)
class EstimationStages:
    """An estimator kind's two stages: the parameter estimator and the prognosis that reads its output."""

    estimator: ParameterEstimator
    prognosis: PrognosisStage


def ea_inversion_stages(model: SystemModel, monitor: Monitor, config: PHMConfig, n_systems: int) -> EstimationStages:
    """The EA inversion and the trend of its recent estimates."""
    estimator = EAInversionEstimator(model, monitor, config, n_systems)
    history_length = int(round(config.extrapolation.span / config.update_time)) + 1
    # successive estimates share their windows' data and the median's: so many are not independent
    extrapolation = replace(config.extrapolation, correlated=estimator.timing.correlated)
    return EstimationStages(estimator, TrendPrognosis(model, estimator.degradable, extrapolation, history_length, n_systems))


def tracking_stages(model: SystemModel, monitor: Monitor, config: PHMConfig, n_systems: int) -> EstimationStages:
    """The tracking filter bank and its drift carried to the limits."""
    from ea_gym.tracking import TrackingEstimator

    estimator = TrackingEstimator.from_chain(model, monitor, config, n_systems)
    return EstimationStages(estimator, DriftPrognosis(model, estimator.degradable, config.extrapolation, estimator.diffusion, n_systems))


#: estimator kind -> its stages' builder (called with the model, the chain's monitor, the chain's settings and N)
ESTIMATORS: dict[str, Callable[[SystemModel, Monitor, PHMConfig, int], EstimationStages]] = {
    "ea_inversion": ea_inversion_stages,
    "tracking": tracking_stages,
}


def make_stages(kind: str, model: SystemModel, monitor: Monitor, config: PHMConfig, n_systems: int) -> EstimationStages:
    """The chain's estimator of ``kind`` (``PHMConfig.estimator_kind``, a key of ``ESTIMATORS``) and its prognosis."""
    if kind not in ESTIMATORS:
        raise ValueError(f"estimator_kind must be one of {sorted(ESTIMATORS)}, got {kind!r}")
    return ESTIMATORS[kind](model, monitor, config, n_systems)
