"""The PHM chain on Energy Activity, one stage a module (paper section 3, Fig 5).

monitor (``ea_gym.diagnosis.monitor``) -> :mod:`~ea_gym.phm.detection` -> :mod:`~ea_gym.phm.isolation`
(network, balance evidence) -> :mod:`~ea_gym.phm.estimation` (the ``ParameterEstimator`` seam; the EA
inversion of :mod:`~ea_gym.phm.inversion_estimator`, the tracking filters of :mod:`~ea_gym.phm.tracking`,
each registered with its prognosis in :mod:`~ea_gym.phm.registry`) -> :mod:`~ea_gym.phm.fit` (whether the
model explains the data at all) -> fusion (:mod:`~ea_gym.phm.isolation`) ->
:mod:`~ea_gym.phm.prognosis`, with the joint filter (:mod:`~ea_gym.phm.joint`) beside for every part's health;
:mod:`~ea_gym.phm.commissioning` fits the healthy machine's own values; :mod:`~ea_gym.phm.config` holds each stage's settings and
:mod:`~ea_gym.phm.chain` composes them, :mod:`~ea_gym.phm.harness`
runs scenarios and recorded signals through a chain (whole, or streamed as they arrive: ``StreamingChain``);
:mod:`~ea_gym.phm.thresholds` keeps the detection thresholds computed once.
"""

from ea_gym.phm.chain import HealthStatus, PartHealth, PHMChain
from ea_gym.phm.commissioning import Commissioning, commission
from ea_gym.phm.config import (
    ChainTiming,
    DetectorConfig,
    ExtrapolationConfig,
    InversionConfig,
    IsolationConfig,
    JointFilterConfig,
    ModelFitConfig,
    PHMConfig,
    TrackingConfig,
)
from ea_gym.phm.detection import calibrate_thresholds, relative_residuals
from ea_gym.phm.estimation import ParameterEstimates, ParameterEstimator, StepSignals
from ea_gym.phm.fit import InnovationSource, ModelFit, ModelFitTest, StepInnovations
from ea_gym.phm.harness import (
    ChainRun,
    StreamingChain,
    build_chain,
    chain_config,
    chain_sample_rate,
    check_duration,
    classifier_for,
    fitted_initial_state,
    run_measurements,
    run_scenario,
    run_signals,
    scenario_measurements,
)
from ea_gym.phm.inversion import EAInversion
from ea_gym.phm.inversion_estimator import EAInversionEstimator
from ea_gym.phm.isolation import EvidenceWeights, balance_chi_square
from ea_gym.phm.joint import JointFilter
from ea_gym.phm.prognosis import (
    DriftPrognosis,
    EndOfLife,
    PrognosisStage,
    TrendFit,
    TrendPrognosis,
    drift_end_of_life,
    predict_end_of_life,
)
from ea_gym.phm.registry import ESTIMATORS, EstimationStages, make_stages, register_estimator, registered_estimators
from ea_gym.phm.thresholds import thresholds_for
from ea_gym.phm.tracking import TrackingEstimator

__all__ = [
    "ESTIMATORS",
    "ChainRun",
    "ChainTiming",
    "Commissioning",
    "DetectorConfig",
    "EAInversion",
    "EAInversionEstimator",
    "DriftPrognosis",
    "EndOfLife",
    "EstimationStages",
    "EvidenceWeights",
    "InversionConfig",
    "IsolationConfig",
    "JointFilter",
    "JointFilterConfig",
    "ExtrapolationConfig",
    "HealthStatus",
    "InnovationSource",
    "ModelFit",
    "ModelFitConfig",
    "ModelFitTest",
    "PHMChain",
    "PartHealth",
    "PHMConfig",
    "ParameterEstimates",
    "ParameterEstimator",
    "PrognosisStage",
    "StepInnovations",
    "StepSignals",
    "StreamingChain",
    "TrackingConfig",
    "TrackingEstimator",
    "TrendFit",
    "TrendPrognosis",
    "balance_chi_square",
    "build_chain",
    "calibrate_thresholds",
    "chain_config",
    "chain_sample_rate",
    "check_duration",
    "classifier_for",
    "commission",
    "drift_end_of_life",
    "fitted_initial_state",
    "make_stages",
    "predict_end_of_life",
    "register_estimator",
    "registered_estimators",
    "relative_residuals",
    "run_measurements",
    "run_scenario",
    "run_signals",
    "scenario_measurements",
    "thresholds_for",
]
