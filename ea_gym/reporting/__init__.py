"""Results, figures and a markdown report of one scenario run through the PHM chain (paper 4.3-4.4).

:mod:`~ea_gym.reporting.results`: ``results.json``'s content and metrics; :mod:`~ea_gym.reporting.figures`:
the figures (the estimate's in :mod:`~ea_gym.reporting.estimate_figure`, what they share in
:mod:`~ea_gym.reporting.drawing`); :mod:`~ea_gym.reporting.report`: ``report.md`` and the output directory.
"""

from ea_gym.reporting.figures import (
    FIGURES,
    PLOTS,
    RECORDED_CAPTIONS,
    TRUTH_FIGURES,
    plot_estimate,
    plot_estimate_error,
    plot_rul,
    plot_signals,
    plot_time_frequency,
)
from ea_gym.reporting.report import fit_text, write_phm_outputs, write_phm_report
from ea_gym.reporting.results import ALPHA, ESTIMATION_START, LAMBDA, MIN_PHASE_PREDICTIONS, SETTLING, RunInputs, chain_results

__all__ = [
    "ALPHA",
    "ESTIMATION_START",
    "FIGURES",
    "LAMBDA",
    "MIN_PHASE_PREDICTIONS",
    "PLOTS",
    "RECORDED_CAPTIONS",
    "RunInputs",
    "SETTLING",
    "TRUTH_FIGURES",
    "chain_results",
    "fit_text",
    "plot_estimate",
    "plot_estimate_error",
    "plot_rul",
    "plot_signals",
    "plot_time_frequency",
    "write_phm_outputs",
    "write_phm_report",
]
