"""The estimator kinds (``PHMConfig.estimator_kind``): each builds the chain's parameter estimator and
the prognosis stage that reads it.

* "ea_inversion": the paper's route, the EA inversion with a causal median
  (:class:`~ea_gym.phm.estimation.EAInversionEstimator`), its recent estimates' polynomial trend
  extrapolated to the limits (:class:`~ea_gym.phm.prognosis.TrendPrognosis`).
* "tracking": a bank of Kalman filters, one per hypothesis, tracking each parameter and its drift
  (:class:`~ea_gym.phm.tracking.TrackingEstimator`), the drift carried to the limits with its covariance
  (:class:`~ea_gym.phm.prognosis.DriftPrognosis`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from ea_gym.diagnosis.monitor import Monitor
from ea_gym.models import SystemModel
from ea_gym.phm.estimation import EAInversionEstimator, ParameterEstimator
from ea_gym.phm.isolation import EvidenceWeights
from ea_gym.phm.prognosis import DriftPrognosis, PrognosisStage, TrendPrognosis
from ea_gym.phm.tracking import TrackingEstimator

if TYPE_CHECKING:
    from ea_gym.phm.config import PHMConfig


@dataclass(frozen=True)
class EstimationStages:
    """An estimator kind's stages: the parameter estimator, the prognosis that reads its output, and how
    much the isolation's other evidence (network, energy balance) counts beside its evidence."""

    estimator: ParameterEstimator
    prognosis: PrognosisStage
    weights: EvidenceWeights = EvidenceWeights()


def ea_inversion_stages(model: SystemModel, monitor: Monitor, config: PHMConfig, n_systems: int) -> EstimationStages:
    """The EA inversion and the trend of its recent estimates."""
    estimator = EAInversionEstimator(model, monitor, config, n_systems)
    history_length = int(round(config.extrapolation.span / config.update_time)) + 1
    # successive estimates share their windows' data and the median's: so many are not independent
    extrapolation = replace(config.extrapolation, correlated=estimator.timing.correlated)
    return EstimationStages(estimator, TrendPrognosis(model, estimator.degradable, extrapolation, history_length, n_systems))


#: The tracking route's isolation evidence. The filters' log-likelihoods forget with a 20 s memory (a
#: noisy stretch fades; ``TrackingConfig.evidence_memory``) and count 1/20 (the innovations' errors are correlated through model error);
#: the network counts 1/4 and the balance 1/10: at a dc_motor bm fault's alarm the balance alone put
#: 0.92 on K, an early network frame up to 1.00 on bm for a J fault. Chosen on random-load runs of
#: rlc_circuit and dc_motor (1 % noise; 10 per parameter at seed 7, then 20 at seed 2 where the first
#: choice, 1/10, 1/2, 1/4, put 0.92 on a wrong component), from memory {20 s, none} x estimator
#: {1, 1/3, 1/10, 1/20, 1/30, 1/100} x network {1, 1/2, 1/4} x balance {1, 1/2, 1/4, 1/10, 0}: largest
#: wrong belief 0.65 / 0.58 (dc_motor seeds 2 / 7), 0.31 (spring_mass_damper), right suspect in
#: 0.99 of the steps after the alarm, every run right at the end.
TRACKING_WEIGHTS = EvidenceWeights(estimator=0.05, network=0.25, balance=0.1)


def tracking_stages(model: SystemModel, monitor: Monitor, config: PHMConfig, n_systems: int) -> EstimationStages:
    """The tracking filter bank and its drift carried to the limits."""
    estimator = TrackingEstimator.from_chain(model, monitor, config, n_systems)
    prognosis = DriftPrognosis(model, estimator.degradable, config.extrapolation, estimator.diffusion, n_systems)
    return EstimationStages(estimator, prognosis, TRACKING_WEIGHTS)


#: estimator kind -> its stages' builder (called with the model, the chain's monitor, the chain's settings and N)
ESTIMATORS: dict[str, Callable[[SystemModel, Monitor, PHMConfig, int], EstimationStages]] = {
    "ea_inversion": ea_inversion_stages,
    "tracking": tracking_stages,
}


def make_stages(model: SystemModel, monitor: Monitor, config: PHMConfig, n_systems: int) -> EstimationStages:
    """The chain's estimator of kind ``config.estimator_kind`` (a key of ``ESTIMATORS``, checked by ``PHMConfig``) and its prognosis."""
    return ESTIMATORS[config.estimator_kind](model, monitor, config, n_systems)
