"""Results of one scenario run through the PHM chain, and their metrics against the ground truth (paper 4.3-4.4).

:func:`chain_results` turns a :class:`~ea_gym.phm.ChainRun` into JSON-ready results: detection time,
isolated parameter (None when the chain ends undecided) with the chain's fused class probabilities that
chose it (the isolation network's own output beside them, named as such), the isolated parameter's
estimate over time, every End of Life prediction, and, when the scenario has a fault, the metrics
against the ground truth: estimation errors, detection delay, how isolation ended (right, wrong,
undecided), and per phase of the fault profile the End of Life errors and the Saxena et al. (2010)
prognostic metrics on the RUL. Everything is read from the chain's per-step records
(:class:`~ea_gym.phm.HealthStatus`): nothing the chain decided is re-derived.

The ground-truth End of Life at a time t is the one a perfect degree-1 extrapolation of the true
parameter predicts there (:meth:`PiecewiseLinearProfile.trend_end_of_life`): the current segment of
the profile extended to the safe limit it heads for. It is constant over each segment of the
profile, so predictions are scored per segment ("phase": the paper's fault and corrective-action
phases of Fig 10 / Table 3).

Units: times in s, parameters in their SI unit (``SystemModel.units``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ea_gym.degradation import PiecewiseLinearProfile
from ea_gym.files import finite_or_none, json_ready
from ea_gym.metrics import eol_error, estimation_errors, prognostic_report
from ea_gym.numerics import TINY
from ea_gym.phm import ChainRun, HealthStatus, PHMChain
from ea_gym.scenario import FaultSpec, Scenario

#: Estimation errors are scored from this time on (s): the estimator's start-up is left out.
ESTIMATION_START = 10.0
#: Saxena metrics settings.
ALPHA = 0.2
LAMBDA = 0.5
#: A phase needs at least this many predictions to be scored.
MIN_PHASE_PREDICTIONS = 3


def isolated_class(status: HealthStatus) -> int:
    """The status's isolated class index: its suspect if the isolation is confident of it, else 0."""
    return int(status.isolated[0]) if status.confident[0] else 0


def _isolation(status: HealthStatus, chain: PHMChain) -> dict[str, Any]:
    """The status's isolation verdict: "no alarm", "isolated" (a confident suspect) or "undecided" (an
    alarm, and the evidence does not single out a parameter), the fault class the belief favours and its
    share of the fault classes' belief."""
    fault_belief = status.diagnosis[0, 1:]
    favoured = 1 + int(np.argmax(fault_belief))
    fit = status.model_fit
    if not status.alarm[0]:
        state = "no alarm"
    elif fit is not None and fit.withheld[0]:
        state = "model does not fit" if fit.misfit[0] else "model fit not yet known"
    else:
        state = "isolated" if isolated_class(status) > 0 else "undecided"
    named = state in ("isolated", "undecided")
    return {
        "state": state,
        "favoured": chain.classes[favoured] if named else None,
        "confidence": float(fault_belief[favoured - 1] / max(float(fault_belief.sum()), TINY)) if named else 0.0,
        "threshold": float(chain.config.isolation.confidence),
    }


def model_fit_results(status: HealthStatus) -> dict[str, Any]:
    """The model-fit test's verdict at ``status`` (:mod:`ea_gym.phm.fit`): "ok" true (the model fits), false
    (it does not: no part isolated, no End of Life), None (not yet known, or not "tested": the test is off or
    the estimator has no innovations); "statistic" the NIS per degree of freedom over the window, "band"
    [low, high] its band, "since" when (s) the verdict was reached."""
    fit = status.model_fit
    if fit is None:
        return {"ok": None, "statistic": None, "band": None, "since": None, "tested": False}
    ok = True if fit.fits[0] else False if fit.misfit[0] else None
    band = [float(fit.low[0]), float(fit.high[0])]
    return {"ok": ok, "statistic": float(fit.statistic[0]), "band": band, "since": float(fit.since[0]), "tested": True}


def _fault_onset(scenario: Scenario) -> float | None:
    """First time (s) the faulty parameter leaves its nominal value; None if it never does."""
    if scenario.fault is None:
        return None
    nominal = float(scenario.model.nominal[scenario.fault.parameter])
    profile = scenario.fault.profile
    times, values = profile.times, profile.values
    if not math.isclose(values[0], nominal, rel_tol=1e-12, abs_tol=0.0):
        return 0.0
    for i in range(len(times) - 1):
        if not math.isclose(values[i + 1], nominal, rel_tol=1e-12, abs_tol=0.0):
            return float(times[i])
    return None


def _segment(profile: PiecewiseLinearProfile, t: np.ndarray) -> np.ndarray:
    """Index of the profile segment containing each t (the one starting at a breakpoint; -1 before the
    first point, len(times) - 1 from the last on), as in ``trend_end_of_life``."""
    return np.searchsorted(np.asarray(profile.times), np.asarray(t, dtype=float), side="right") - 1


def _limit(status: HealthStatus) -> str | None:
    """Which limit the status's End of Life refers to."""
    prediction = status.end_of_life[0]
    return None if prediction is None else prediction.limit


def fault_of(scenario: Scenario | None) -> FaultSpec | None:
    """The scenario's fault, the truth a run is scored against; None without a fault or a scenario (recorded
    measurements, whose truth is unknown)."""
    return None if scenario is None else scenario.fault


def faulty_parameter(scenario: Scenario | None) -> str | None:
    """The parameter of the scenario's fault; None without one (:func:`fault_of`)."""
    fault = fault_of(scenario)
    return None if fault is None else fault.parameter


def truth_limits(scenario: Scenario, parameter: str) -> tuple[float, float]:
    """The safe limits of ``parameter`` in the scenario's model, (lower, upper) in its unit."""
    lower, upper = scenario.model.safe_limits[parameter]
    return float(lower), float(upper)


def estimate_series(run: ChainRun, chain: PHMChain, isolated: int) -> dict[str, Any]:
    """The estimates of the parameter of class ``isolated`` at the steps that updated it (the others repeat
    a stale value while another suspect is followed alone)."""
    if isolated == 0:
        return {"parameter": None, "t": [], "value": []}
    d = isolated - 1
    updated = [s for s in run.statuses if s.estimation.estimated[0, d]]
    t = [float(s.estimation.time[0, d]) for s in updated]
    value = [float(s.estimates[0, d]) for s in updated]
    return {"parameter": chain.degradable[d], "t": t, "value": value}


def _eol_predictions(run: ChainRun, chain: PHMChain) -> list[dict[str, Any]]:
    predictions = []
    for s in run.statuses:
        eol = float(s.eol[0])
        isolated = isolated_class(s)
        # an End of Life is only reported for a suspect the isolation was confident of at the time
        if not math.isfinite(eol) or isolated == 0:
            continue
        t = float(s.t[0])
        predictions.append(
            {
                "t": t,
                "parameter": chain.classes[isolated],
                "eol": eol,
                "limit": _limit(s),
                "rul": eol - t,
                "rul_low": finite_or_none(float(s.eol_low[0]) - t),
                "rul_high": finite_or_none(float(s.eol_high[0]) - t),
            }
        )
    return predictions


def _phase_metrics(predictions: list[dict[str, Any]], scenario: Scenario) -> tuple[list[dict[str, Any]], int]:
    """Per profile segment: End-of-Life errors and Saxena metrics of the predictions made in it.

    Returns the phases and the number of finite predictions made where the true trend never reaches
    a limit (false alarms of the prognosis).
    """
    fault = scenario.fault
    if fault is None:
        return [], 0
    profile = fault.profile
    limits = truth_limits(scenario, fault.parameter)
    # only the predictions made while the faulty parameter was the isolated one are about it
    predictions = [p for p in predictions if p["parameter"] == fault.parameter]
    if not predictions:
        return [], 0
    t = np.array([p["t"] for p in predictions])
    eol = np.array([p["eol"] for p in predictions])
    predicted_limit = np.array([str(p["limit"]) for p in predictions])
    true_eol = profile.trend_end_of_life(t, limits)
    segment = _segment(profile, t)
    scored = np.isfinite(true_eol) & (true_eol > t)
    without_truth = int(np.sum(~np.isfinite(true_eol)))
    phases = []
    for k in np.unique(segment[scored]):
        rows = np.flatnonzero(scored & (segment == k))
        if len(rows) < MIN_PHASE_PREDICTIONS:
            continue
        times = profile.times
        start = float(times[k]) if k >= 0 else 0.0
        end = float(times[k + 1]) if k + 1 < len(times) else None
        truth = float(np.median(true_eol[rows]))
        slope_sign = np.sign(profile.value(t[rows[0]] + 1e-6) - profile.value(t[rows[0]]))
        limit = "lower" if slope_sign < 0 else "upper"
        errors = np.array([eol_error(eol[r], true_eol[r]) for r in rows])
        rul_pred = eol[rows] - t[rows]
        rul_true = true_eol[rows] - t[rows]
        try:
            prognostics = prognostic_report(t[rows], rul_pred, rul_true, eol=truth, alpha=ALPHA, lam=LAMBDA)
        except ValueError as exc:  # e.g. no prediction at or after t_lambda
            prognostics = {"error": str(exc)}
        phases.append(
            {
                "segment": [start, end],
                "limit": limit,
                "true_eol": truth,
                "n_predictions": len(rows),
                "limit_agreement": float(np.mean(predicted_limit[rows] == limit)),
                "prediction_times": [float(t[rows[0]]), float(t[rows[-1]])],
                "predicted_eol": {
                    "median": float(np.median(eol[rows])),
                    "final": float(eol[rows[-1]]),
                },
                "eol_error": {
                    "min": float(errors.min()),
                    "max": float(errors.max()),
                    "median": float(np.median(errors)),
                    "median_absolute": float(np.median(np.abs(errors))),
                    "final": float(errors[-1]),
                },
                "prognostics": prognostics,
            }
        )
    return phases, without_truth


def chain_results(run: ChainRun, chain: PHMChain, scenario: Scenario | None, measurements: str | None = None) -> dict:
    """The results of a run, JSON-ready (inf and NaN are None).

    Args:
        scenario: the simulated scenario, whose fault is the truth the run is scored against; None for
            recorded ``measurements`` (their file's name), whose truth is unknown: no metrics.

    Keys:
        detection_time: first alarm (s) or None.
        isolated_parameter: the last status's suspect if the isolation is confident of it; None without
            an alarm and when the chain is undecided (the evidence does not single out a parameter).
        class_probabilities: class -> the chain's fused belief at the last status (the network's average
            weighed by the estimator's and the energy balance's evidence), the probabilities that chose
            ``isolated_parameter``: it is their argmax among the fault classes. They sum to 1.
        isolation: {"state": "no alarm" | "isolated" | "undecided", "favoured": the fault class the belief
            favours (None without an alarm), "confidence": its share of the fault classes' belief,
            "threshold": the share a suspect needs to be isolated}.
        network_probabilities: class -> the isolation network's own output: its mean probability over the
            statuses since detection that had a full isolation frame, or the last status's when there is
            no alarm. One of the three kinds of evidence, not the verdict.
        estimate: {"parameter", "t", "value"}: the isolated parameter's estimate at every step where
            the chain's estimator updated it (an alarm raised, and the parameter a hypothesis it
            follows), stamped at the time it describes; parameter None when none is isolated.
        model_fit: {"ok", "statistic", "band", "since", "tested"} (:func:`model_fit_results`): whether the model
            explains the data; while it does not, nothing is isolated and no End of Life given.
        eol_predictions: [{"t", "parameter", "eol", "limit", "rul", "rul_low", "rul_high"}] for every
            step with a finite End of Life (s) of a suspect the isolation was confident of; "parameter" is
            the one isolated at that step, "limit" "lower" or "upper".
        run: scenario file or measurements file, sample rate (Hz), duration, steps, noise, estimate lag,
            frame (s).
        metrics: only when the scenario has a fault: fault parameter, fault onset (s), detection delay
            (s), isolation_correct, isolation_outcome (:func:`isolation_outcome`), and when isolation
            is correct: "estimation" (errors of the estimate against the truth at its stamps from
            ESTIMATION_START on, with the window used),
            "eol_phases" (per profile segment whose true trend reaches a limit and has at least
            MIN_PHASE_PREDICTIONS predictions made while the fault parameter was isolated: true EoL,
            fraction of predictions heading for the right limit, EoL errors predicted - true, Saxena metrics
            on the RUL with alpha = 0.2, lambda = 0.5), "eol_fault_phase" (the first of them) and
            "predictions_without_true_eol" (finite predictions where the true trend is flat).
    """
    statuses = run.statuses
    if not statuses:
        raise ValueError("the run has no status")
    last = statuses[-1]
    detection = float(last.detection_time[0])
    detection_time = detection if math.isfinite(detection) else None
    isolated = isolated_class(last)
    isolated_parameter = chain.classes[isolated] if isolated > 0 else None
    # the statuses the chain's isolation averages: alarm raised and a full frame seen
    counted = [s.probabilities[0] for s in statuses if s.counted[0]]
    network = np.mean(counted, axis=0) if counted else last.probabilities[0]
    estimate = estimate_series(run, chain, isolated)
    predictions = _eol_predictions(run, chain)
    results: dict[str, Any] = {
        "detection_time": detection_time,
        "isolated_parameter": isolated_parameter,
        "class_probabilities": {name: float(p) for name, p in zip(chain.classes, last.diagnosis[0])},
        "isolation": _isolation(last, chain),
        "model_fit": model_fit_results(last),
        "network_probabilities": {name: float(p) for name, p in zip(chain.classes, network)},
        "estimate": estimate,
        "eol_predictions": predictions,
        "run": {
            **({"scenario": scenario.source} if scenario is not None else {"measurements": measurements}),
            "sample_rate": float(chain.config.timing.sample_rate),
            "duration": float(run.t[-1]),
            "steps": len(statuses),
            "noise": float(chain.config.timing.noise),
            "estimate_lag": float(chain.estimate_lag),
            "frame": float(chain.config.isolation.frame),
        },
    }
    if scenario is not None and scenario.fault is not None:
        results["metrics"] = _fault_metrics(scenario, scenario.fault.parameter, detection_time, isolated_parameter, estimate, predictions)
    return json_ready(results)


def isolation_outcome(fault_parameter: str, detection_time: float | None, isolated_parameter: str | None) -> str:
    """How a run's isolation ended against the true faulty parameter: "right", "wrong" (another parameter
    isolated), "undecided" (an alarm, no confident suspect) or "not detected"."""
    if isolated_parameter is not None:
        return "right" if isolated_parameter == fault_parameter else "wrong"
    return "not detected" if detection_time is None else "undecided"


def _fault_metrics(scenario: Scenario, parameter: str, detection_time: float | None, isolated_parameter: str | None,
                   estimate: dict[str, Any], predictions: list[dict[str, Any]]) -> dict[str, Any]:
    """``chain_results``'s "metrics" of a scenario whose fault is in ``parameter``."""
    onset = _fault_onset(scenario)
    metrics: dict[str, Any] = {
        "fault_parameter": parameter,
        "fault_onset": onset,
        "detection_delay": (detection_time - onset) if detection_time is not None and onset is not None else None,
        "isolation_correct": isolated_parameter == parameter,
        "isolation_outcome": isolation_outcome(parameter, detection_time, isolated_parameter),
        "limits": list(truth_limits(scenario, parameter)),
    }
    if isolated_parameter == parameter:
        metrics["estimation"] = _estimation_metrics(scenario, parameter, estimate)
        phases, without_truth = _phase_metrics(predictions, scenario)
        metrics["eol_phases"] = phases
        metrics["eol_fault_phase"] = phases[0] if phases else None
        metrics["predictions_without_true_eol"] = without_truth
    return metrics


def _estimation_metrics(scenario: Scenario, parameter: str, estimate: dict[str, Any]) -> dict[str, Any] | None:
    """Errors of the estimate series against the truth at its stamps from ESTIMATION_START on; None without one."""
    stamps = np.array(estimate["t"])
    values = np.array(estimate["value"])
    index = scenario.model.parameter_names.index(parameter)
    window = stamps >= ESTIMATION_START
    if not window.any():
        return None
    truth = scenario.parameters_at(stamps[window])[:, index]
    errors = estimation_errors(values[window], truth)
    nominal = float(scenario.model.nominal[parameter])
    return {
        **errors,
        "relative_to_nominal": {k: v / abs(nominal) for k, v in errors.items()},
        "window": [float(stamps[window][0]), float(stamps[window][-1])],
        "n": int(window.sum()),
    }
