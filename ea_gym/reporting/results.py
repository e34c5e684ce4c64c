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
from dataclasses import dataclass
from typing import Any

import numpy as np

from ea_gym.degradation import PiecewiseLinearProfile
from ea_gym.files import finite_or_none, json_ready
from ea_gym.metrics import eol_error, estimation_errors, prognostic_report
from ea_gym.models import SystemModel
from ea_gym.numerics import TINY
from ea_gym.phm import ChainRun, Commissioning, HealthStatus, PartHealth, PHMChain
from ea_gym.scenario import FaultSpec, Scenario

#: Estimation errors are scored from this time on (s): the estimator's start-up is left out.
ESTIMATION_START = 10.0
#: Saxena metrics settings.
ALPHA = 0.2
LAMBDA = 0.5
#: A phase needs at least this many predictions to be scored.
MIN_PHASE_PREDICTIONS = 3
#: The per-part metrics score whether a part is named degrading, and its RUL interval, from this long (s) after each
#: change of its truth (a fault's onset, the end of its ramp): the chain needs that long to see a drift.
SETTLING = 30.0


@dataclass(frozen=True)
class RunInputs:
    """Where a run's noise levels and healthy machine came from: ``results.json``'s "run" and "commissioning".

    Attributes:
        noise_source: the sensor noise level's: "scenario" (its ``sensors.noise``), "--noise" (given) or "estimated"
            (from the record: ``ea_gym.measurements.noise_estimate``).
        noise_estimate: the record's own estimate (fraction of each signal's RMS) where one was made, else None.
        load_noise_source: the load measurement's noise level's: "scenario" (its ``sensors.load_noise``), "--load-noise"
            (given) or "assumed exact" (none given: 0, the load read as exact).
        commissioning: the healthy machine's values the chain runs from (``ea_gym.phm.commission``); None: the model's
            nominal values.
        commissioning_source: what it was fitted on (a healthy record's file, the first seconds of the record).
    """

    noise_source: str = "scenario"
    noise_estimate: float | None = None
    load_noise_source: str = "scenario"
    commissioning: Commissioning | None = None
    commissioning_source: str | None = None


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


def fault_onset(model: SystemModel, fault: FaultSpec) -> float | None:
    """First time (s) the fault's parameter leaves its nominal value in ``model``; None if it never does."""
    nominal = float(model.nominal[fault.parameter])
    times, values = fault.profile.times, fault.profile.values
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


def fault_of(scenario: Scenario | None, parameter: str | None = None) -> FaultSpec | None:
    """The scenario's fault in ``parameter`` (None: its first fault), the truth a run is scored against; None without
    one or without a scenario (recorded measurements, whose truth is unknown)."""
    if scenario is None:
        return None
    return next((fault for fault in scenario.faults if parameter is None or fault.parameter == parameter), None)


def faulty_parameter(scenario: Scenario | None) -> str | None:
    """The parameter of the scenario's (first) fault; None without one (:func:`fault_of`)."""
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


def _phase_metrics(
    predictions: list[dict[str, Any]], profile: PiecewiseLinearProfile, limits: tuple[float, float]
) -> tuple[list[dict[str, Any]], int]:
    """Per segment of a fault's ``profile``: End-of-Life errors and Saxena metrics of the predictions of its parameter
    ({"t", "eol", "limit"}: s, s, "lower", "upper" or None where the prediction does not say) made in it.

    Returns the phases and the number of finite predictions made where the true trend never reaches
    a limit (false alarms of the prognosis).
    """
    if not predictions:
        return [], 0
    t = np.array([p["t"] for p in predictions])
    eol = np.array([p["eol"] for p in predictions])
    predicted_limit = np.array([str(p["limit"]) for p in predictions])
    limit_said = np.array([p["limit"] is not None for p in predictions])
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
                "limit_agreement": float(np.mean(predicted_limit[rows] == limit)) if limit_said[rows].all() else None,
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


def chain_results(run: ChainRun, chain: PHMChain, scenario: Scenario | None, measurements: str | None = None,
                  inputs: RunInputs = RunInputs()) -> dict:
    """The results of a run, JSON-ready (inf and NaN are None).

    Args:
        scenario: the simulated scenario, whose faults are the truth the run is scored against; None for
            recorded ``measurements`` (their file's name), whose truth is unknown: no metrics.
        inputs: where the noise levels and the healthy machine came from.

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
        degrading: the parts judged degrading at the end (:func:`degrading_parts`), a list of names.
        components: every degradable part's series, one entry per step (:func:`component_series`).
        eol_predictions: [{"t", "parameter", "eol", "limit", "rul", "rul_low", "rul_high"}] for every
            step with a finite End of Life (s) of a suspect the isolation was confident of; "parameter" is
            the one isolated at that step, "limit" "lower" or "upper".
        run: what was run with which settings (:func:`_run_record`).
        commissioning: only where the chain ran from a commissioned machine (:func:`commissioning_results`).
        metrics: only when the scenario has a fault: "fault_parameters" (every faulty parameter), the single-fault
            keys of the faulty parameter the chain isolated, else the first (:func:`_fault_metrics`), "parts" (every
            faulty part's, :func:`part_metrics`) and "degrading_set" (:func:`degrading_set_metrics`).
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
    components = component_series(run, chain)
    results: dict[str, Any] = {
        "detection_time": detection_time,
        "isolated_parameter": isolated_parameter,
        "class_probabilities": {name: float(p) for name, p in zip(chain.classes, last.diagnosis[0])},
        "isolation": _isolation(last, chain),
        "model_fit": model_fit_results(last),
        "degrading": degrading_parts(last, chain),
        "network_probabilities": {name: float(p) for name, p in zip(chain.classes, network)},
        "estimate": estimate,
        "components": components,
        "eol_predictions": predictions,
        "run": _run_record(run, chain, scenario, measurements, inputs),
    }
    if inputs.commissioning is not None:
        results["commissioning"] = commissioning_results(inputs.commissioning, inputs.commissioning_source)
    if scenario is not None and scenario.faults:
        faulty = scenario.faulty_parameters
        parameter = isolated_parameter if isolated_parameter in faulty else faulty[0]
        results["metrics"] = {
            "fault_parameters": list(faulty),
            **_fault_metrics(scenario, parameter, detection_time, isolated_parameter, estimate, predictions),
            "parts": {fault.parameter: part_metrics(scenario, fault, components[fault.parameter])
                      for fault in scenario.faults if fault.parameter in components},
            "degrading_set": degrading_set_metrics(scenario, chain, run),
        }
    return json_ready(results)


def _run_record(run: ChainRun, chain: PHMChain, scenario: Scenario | None, measurements: str | None, inputs: RunInputs) -> dict[str, Any]:
    """``chain_results``' "run": the scenario or measurements file, sample rate (Hz), duration (s), steps, "noise" (the
    sensor noise level the chain ran with) and "noise_source" (:class:`RunInputs`; "noise_estimate", the record's own,
    where one was made), "load_noise" (the load measurement's) and "load_noise_source", estimate lag, frame (s),
    "rul_interval" (the confidence of the RUL intervals)."""
    timing = chain.config.timing
    return {
        **({"scenario": scenario.source} if scenario is not None else {"measurements": measurements}),
        "sample_rate": float(timing.sample_rate),
        "duration": float(run.t[-1]),
        "steps": len(run.statuses),
        "noise": float(timing.noise),
        "noise_source": inputs.noise_source,
        **({"noise_estimate": inputs.noise_estimate} if inputs.noise_estimate is not None else {}),
        "load_noise": float(timing.load_noise),
        "load_noise_source": inputs.load_noise_source,
        "estimate_lag": float(chain.estimate_lag),
        "frame": float(chain.config.isolation.frame),
        "rul_interval": float(chain.config.extrapolation.confidence),
    }


def commissioning_results(commissioning: Commissioning, source: str | None) -> dict[str, Any]:
    """The commissioned machine (N = 1) as ``results.json`` gives it: "values" and "std" (name -> SI, a NaN std None) and
    "source" (what it was fitted on)."""
    return {
        "values": {name: float(v) for name, v in zip(commissioning.names, commissioning.value[0])},
        "std": {name: finite_or_none(v) for name, v in zip(commissioning.names, commissioning.std[0])},
        "source": source,
    }


def _part_health(run: ChainRun) -> list[PartHealth] | None:
    """Every status's per-part health, None where the chain runs without its joint side filter (``HealthStatus.parts``)."""
    parts = [s.parts for s in run.statuses]
    return None if any(p is None for p in parts) else [p for p in parts if p is not None]


def component_series(run: ChainRun, chain: PHMChain) -> dict[str, dict[str, Any]]:
    """Every degradable part's series, one entry per step, as ``results.json``'s "components" (JSON-ready, null where undefined).

    Per part: "unit" and "limits" (its SI unit and safe limits [lower, upper]); per step "t" (the step's end, s), "value"
    (its estimate, SI), "std" (its standard deviation, SI), "degrading" (the probability that it is degrading), "named"
    (whether it is judged degrading), "rul", "rul_low", "rul_high" (its Remaining Useful Life and the ends of its
    interval, ``ExtrapolationConfig.confidence``, s; null where no End of Life is predicted), from
    ``HealthStatus.parts``. A chain without the joint side filter (``parts`` None) gives its estimator's own estimates
    (``HealthStatus.estimates``, each as if it alone were faulty) and their std, and null for the rest.
    """
    t = run.t.tolist()
    model = chain.model
    described = {name: {"unit": model.units.get(name, ""), "limits": list(model.safe_limits[name])} for name in chain.degradable}
    parts = _part_health(run)
    if parts is None:
        value = np.array([s.estimates[0] for s in run.statuses])
        std = np.sqrt(np.array([s.estimation.variance[0] for s in run.statuses]))
        unknown: list[None] = [None] * len(t)
        return {
            name: {**described[name], "t": t, "value": json_ready(value[:, d]), "std": json_ready(std[:, d]), "degrading": unknown,
                   "named": unknown, "rul": unknown, "rul_low": unknown, "rul_high": unknown}
            for d, name in enumerate(chain.degradable)
        }
    value, std = np.array([p.value[0] for p in parts]), np.array([p.std[0] for p in parts])
    degrading, named = np.array([p.degrading[0] for p in parts]), np.array([p.named[0] for p in parts])
    rul = np.array([p.rul[0] for p in parts])  # (steps, D, 3): point, low, high
    return {
        name: {**described[name], "t": t, "value": json_ready(value[:, d]), "std": json_ready(std[:, d]),
               "degrading": json_ready(degrading[:, d]), "named": json_ready(named[:, d]), "rul": json_ready(rul[:, d, 0]),
               "rul_low": json_ready(rul[:, d, 1]), "rul_high": json_ready(rul[:, d, 2])}
        for d, name in enumerate(chain.degradable)
    }


def degrading_parts(status: HealthStatus, chain: PHMChain) -> list[str]:
    """The parts judged degrading at ``status`` (``PartHealth.named``); without the joint side filter, the isolated one
    if any (the single-fault chain's one verdict)."""
    if status.parts is None:
        isolated = isolated_class(status)
        return [chain.classes[isolated]] if isolated > 0 else []
    return [name for name, named in zip(chain.degradable, status.parts.named[0]) if named]


def _degrading_truth(profile: PiecewiseLinearProfile, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Whether the profile's parameter is degrading at times t (the segment containing t changes it), and the last
    time at or before each t its state changed (s; -inf where it never did)."""
    times = np.asarray(profile.times)
    moving = np.append(np.diff(profile.values) != 0, False)  # the segment starting at each point
    segment = _segment(profile, t)
    state = np.where(segment >= 0, moving[np.clip(segment, 0, None)], False)
    before = np.concatenate([[False], moving[:-1]])  # the state just before each point
    changes = times[moving != before]
    index = np.searchsorted(changes, t, side="right") - 1
    return state, np.where(index >= 0, changes[np.clip(index, 0, None)], -np.inf)


def degrading_set_metrics(scenario: Scenario, chain: PHMChain, run: ChainRun) -> dict[str, Any] | None:
    """How often the chain named exactly the set of parts that were degrading: over the steps from the first fault's onset
    + ``SETTLING`` s that are at least as long after every part's last change (a fault's onset, the end of its ramp), the
    fraction whose named set (``PartHealth.named``) is the true one (the parts whose profile changes at that time; the
    others healthy). None without the joint side filter, or when no step is scored: {"exact", "steps", "settling"}."""
    parts = _part_health(run)
    if parts is None:
        return None
    t = run.t
    truth = np.zeros((len(t), len(chain.degradable)), dtype=bool)
    onsets = [fault_onset(scenario.model, fault) for fault in scenario.faults]
    settled = t >= min((onset for onset in onsets if onset is not None), default=np.inf) + SETTLING
    for fault in scenario.faults:
        if fault.parameter in chain.degradable:
            state, changed = _degrading_truth(fault.profile, t)
            truth[:, chain.degradable.index(fault.parameter)] = state
            settled &= t >= changed + SETTLING
    if not settled.any():
        return None
    named = np.array([p.named[0] for p in parts])
    exact = np.all(named == truth, axis=1)[settled]
    return {"exact": float(exact.mean()), "steps": int(settled.sum()), "settling": SETTLING}


def part_metrics(scenario: Scenario, fault: FaultSpec, series: dict[str, Any]) -> dict[str, Any]:
    """A faulty part's metrics from its component series (:func:`component_series`) against its profile.

    Keys: "onset" (s, :func:`fault_onset`), "estimation" (errors of its estimate against the truth from
    ESTIMATION_START on, as the single-fault key), "named" (over the steps from its onset + ``SETTLING`` s that are as
    long after its last change, the fraction where it is named degrading exactly when it is; None without the joint
    side filter or such steps),
    "rul_coverage" (over the steps from its onset + ``SETTLING`` whose true trend reaches a limit: "fraction" whose
    interval holds the true RUL, a step without a prediction counting as a miss; "predicted", the fraction with one;
    "steps"), "eol_phases" and "eol_fault_phase" (per profile segment, as the single-fault keys, from its RUL predictions)
    and "predictions_without_true_eol".
    """
    t = np.asarray(series["t"], dtype=float)
    onset = fault_onset(scenario.model, fault)
    metrics: dict[str, Any] = {"onset": onset, "limits": list(truth_limits(scenario, fault.parameter))}
    value = np.array([np.nan if v is None else v for v in series["value"]], dtype=float)
    metrics["estimation"] = _estimation_metrics(scenario, fault.parameter, {"t": t[np.isfinite(value)], "value": value[np.isfinite(value)]})
    state, changed = _degrading_truth(fault.profile, t)
    settled = (t >= changed + SETTLING) & (t >= (np.inf if onset is None else onset + SETTLING))
    named = series["named"]
    metrics["named"] = (float(np.mean([bool(named[i]) == state[i] for i in np.flatnonzero(settled)]))
                        if settled.any() and named[0] is not None else None)
    true_eol = fault.profile.trend_end_of_life(t, truth_limits(scenario, fault.parameter))
    rul = np.array([np.nan if v is None else v for v in series["rul"]], dtype=float)
    low = np.array([-np.inf if v is None else v for v in series["rul_low"]], dtype=float)
    high = np.array([np.inf if v is None else v for v in series["rul_high"]], dtype=float)
    scored = np.isfinite(true_eol) & (true_eol > t) & (t >= (np.inf if onset is None else onset + SETTLING))
    true_rul = true_eol - t
    covered = np.isfinite(rul) & (low <= true_rul) & (true_rul <= high)
    metrics["rul_coverage"] = {
        "fraction": float(covered[scored].mean()) if scored.any() else None,
        "predicted": float(np.isfinite(rul[scored]).mean()) if scored.any() else None,
        "steps": int(scored.sum()),
    }
    predicted = np.flatnonzero(np.isfinite(rul))
    predictions = [{"t": float(t[i]), "eol": float(t[i] + rul[i]), "limit": None} for i in predicted]
    phases, without_truth = _phase_metrics(predictions, fault.profile, truth_limits(scenario, fault.parameter))
    metrics["eol_phases"] = phases
    metrics["eol_fault_phase"] = phases[0] if phases else None
    metrics["predictions_without_true_eol"] = without_truth
    return metrics


def isolation_outcome(fault_parameter: str, detection_time: float | None, isolated_parameter: str | None) -> str:
    """How a run's isolation ended against the true faulty parameter: "right", "wrong" (another parameter
    isolated), "undecided" (an alarm, no confident suspect) or "not detected"."""
    if isolated_parameter is not None:
        return "right" if isolated_parameter == fault_parameter else "wrong"
    return "not detected" if detection_time is None else "undecided"


def _fault_metrics(scenario: Scenario, parameter: str, detection_time: float | None, isolated_parameter: str | None,
                   estimate: dict[str, Any], predictions: list[dict[str, Any]]) -> dict[str, Any]:
    """``chain_results``'s single-fault "metrics" of the scenario's fault in ``parameter``: fault parameter, fault onset (s),
    detection delay (s), isolation_correct, isolation_outcome (:func:`isolation_outcome`), and when isolation is correct:
    "estimation" (errors of the estimate against the truth at its stamps from ESTIMATION_START on, with the window used),
    "eol_phases" (per profile segment whose true trend reaches a limit and has at least MIN_PHASE_PREDICTIONS
    predictions made while the fault parameter was isolated: true EoL, fraction of predictions heading for the right
    limit, EoL errors predicted - true, Saxena metrics on the RUL with alpha = 0.2, lambda = 0.5), "eol_fault_phase"
    (the first of them) and "predictions_without_true_eol" (finite predictions where the true trend is flat)."""
    fault = fault_of(scenario, parameter)
    assert fault is not None  # parameter is one of the scenario's faulty parameters
    onset = fault_onset(scenario.model, fault)
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
        # only the predictions made while the faulty parameter was the isolated one are about it
        mine = [p for p in predictions if p["parameter"] == parameter]
        phases, without_truth = _phase_metrics(mine, fault.profile, truth_limits(scenario, parameter))
        metrics["eol_phases"] = phases
        metrics["eol_fault_phase"] = phases[0] if phases else None
        metrics["predictions_without_true_eol"] = without_truth
    return metrics


def _estimation_metrics(scenario: Scenario, parameter: str, estimate: dict[str, Any]) -> dict[str, Any] | None:
    """Errors of the estimate series against the truth at its stamps from ESTIMATION_START on; None without one."""
    stamps = np.asarray(estimate["t"], dtype=float)
    values = np.asarray(estimate["value"], dtype=float)
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
