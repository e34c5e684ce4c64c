"""The PHM chain on Energy Activity, one stage a module (paper section 3, Fig 5).

monitor (``ea_gym.diagnosis.monitor``) -> :mod:`~ea_gym.phm.detection` -> :mod:`~ea_gym.phm.isolation`
(network, balance evidence) -> :mod:`~ea_gym.phm.estimation` (the ``ParameterEstimator`` seam; the EA
inversion of :mod:`~ea_gym.phm.inversion`) -> fusion (:mod:`~ea_gym.phm.isolation`) ->
:mod:`~ea_gym.phm.prognosis`; :mod:`~ea_gym.phm.chain` composes them, :mod:`~ea_gym.phm.harness`
runs scenarios and recorded signals through a chain.
"""

from ea_gym.phm.chain import HealthStatus, PHMChain
from ea_gym.phm.config import PHMConfig
from ea_gym.phm.detection import DetectorConfig, calibrate_thresholds, relative_residuals
from ea_gym.phm.estimation import (
    EAInversionEstimator,
    ParameterEstimates,
    ParameterEstimator,
    StepSignals,
    make_estimator,
)
from ea_gym.phm.harness import ChainRun, build_chain, classifier_for, run_scenario, run_signals
from ea_gym.phm.inversion import EAInversion, EstimatorConfig
from ea_gym.phm.isolation import balance_chi_square
from ea_gym.phm.prognosis import EndOfLife, ExtrapolationConfig, TrendFit, predict_end_of_life

__all__ = [
    "ChainRun",
    "DetectorConfig",
    "EAInversion",
    "EAInversionEstimator",
    "EndOfLife",
    "EstimatorConfig",
    "ExtrapolationConfig",
    "HealthStatus",
    "PHMChain",
    "PHMConfig",
    "ParameterEstimates",
    "ParameterEstimator",
    "StepSignals",
    "TrendFit",
    "balance_chi_square",
    "build_chain",
    "calibrate_thresholds",
    "classifier_for",
    "make_estimator",
    "predict_end_of_life",
    "relative_residuals",
    "run_scenario",
    "run_signals",
]
