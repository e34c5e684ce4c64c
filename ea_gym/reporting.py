"""Results, figures and a markdown report of one scenario run through the PHM chain (paper 4.3-4.4).

:func:`chain_results` turns a :class:`~ea_gym.phm.ChainRun` into JSON-ready results: detection time,
isolated parameter and class probabilities, the isolated parameter's estimate over time, every End of
Life prediction, and, when the scenario has a fault, the metrics against the ground truth: estimation
errors, detection delay, whether isolation is correct, and per phase of the fault profile the End of
Life errors and the Saxena et al. (2010) prognostic metrics on the RUL.

The ground-truth End of Life at a time t is the one a perfect degree-1 extrapolation of the true
parameter predicts there (:meth:`PiecewiseLinearProfile.trend_end_of_life`): the current segment of
the profile extended to the safe limit it heads for. It is constant over each segment of the
profile, so predictions are scored per segment ("phase": the paper's fault and corrective-action
phases of Fig 10 / Table 3).

Figures (paper Figs 9, 12, 13, plus RUL and detection): :func:`plot_time_frequency`,
:func:`plot_estimate`, :func:`plot_estimate_error`, :func:`plot_rul`, :func:`plot_signals`.
:func:`write_phm_outputs` writes them, ``report.md`` and ``results.json`` into one directory so that
nothing is left half-written when something fails.

Units: times in s, parameters in their SI unit (``SystemModel.units``), EA in J, frequencies in Hz.
"""

from __future__ import annotations

import itertools
import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.colors import LogNorm

from ea_gym.diagnosis.features import residual_spectrogram
from ea_gym.files import finite_or_none, json_ready, save_figure, write_json, write_text
from ea_gym.metrics import eol_error, estimation_errors, prognostic_report
from ea_gym.phm import ChainRun, HealthStatus, PHMChain
from ea_gym.pyplot import plt
from ea_gym.scenario import Scenario

__all__ = [
    "FIGURES",
    "chain_results",
    "plot_estimate",
    "plot_estimate_error",
    "plot_rul",
    "plot_signals",
    "plot_time_frequency",
    "write_phm_outputs",
    "write_phm_report",
]

#: Estimation errors are scored from this time on (s): the estimator's start-up is left out.
ESTIMATION_START = 10.0
#: Saxena metrics settings.
ALPHA = 0.2
LAMBDA = 0.5
#: A phase needs at least this many predictions to be scored.
MIN_PHASE_PREDICTIONS = 3

#: figure name -> (file name, caption)
FIGURES: dict[str, tuple[str, str]] = {
    "time_frequency": ("time_frequency.png", "Time-frequency map of the I element's EA residual (paper Fig 9)"),
    "estimate": ("estimate.png", "Parameter estimate, truth, safe limits and End-of-Life extrapolations (paper Fig 12)"),
    "estimate_error": ("estimate_error.png", "Estimation error over time (paper Fig 13)"),
    "rul": ("rul.png", "Remaining Useful Life: prediction, interval and truth with the alpha cone"),
    "signals": ("signals.png", "Measured and reference Energy Activity per element, detection statistic"),
}


# --------------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------------


def _times(run: ChainRun) -> np.ndarray:
    return np.array([float(s.t[0]) for s in run.statuses])


def _step_time(chain: PHMChain) -> float:
    """Seconds of the prognosis clock per update."""
    return float(getattr(chain, "step_time", chain.config.step))


def _ready(run: ChainRun) -> np.ndarray:
    """Steps at which the chain's estimator updated an estimate."""
    return np.array([bool(s.estimation.estimated[0].any()) for s in run.statuses], dtype=bool)


def _isolated(run: ChainRun) -> int:
    return int(run.statuses[-1].isolated[0]) if run.statuses else 0


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


def _segment(profile, t: np.ndarray) -> np.ndarray:
    """Index of the profile segment containing each t (the one starting at a breakpoint; -1 before the
    first point, len(times) - 1 from the last on), as in ``trend_end_of_life``."""
    return np.searchsorted(np.asarray(profile.times), np.asarray(t, dtype=float), side="right") - 1


def _limit(status: HealthStatus) -> str | None:
    """Which limit the status's End of Life refers to."""
    prediction = status.end_of_life[0]
    return None if prediction is None else prediction.limit


def _truth_limits(scenario: Scenario, parameter: str) -> tuple[float, float]:
    return tuple(float(x) for x in scenario.model.safe_limits[parameter])


# --------------------------------------------------------------------------------------------------
# results
# --------------------------------------------------------------------------------------------------


def _estimate_series(run: ChainRun, chain: PHMChain, isolated: int) -> dict[str, Any]:
    if isolated == 0:
        return {"parameter": None, "t": [], "value": []}
    d = isolated - 1
    ready = _ready(run)
    t = [float(s.estimation.time[0, d]) for s, r in zip(run.statuses, ready) if r]
    value = [float(s.estimates[0, d]) for s, r in zip(run.statuses, ready) if r]
    return {"parameter": chain.degradable[d], "t": t, "value": value}


def _eol_predictions(run: ChainRun, chain: PHMChain) -> list[dict[str, Any]]:
    predictions = []
    for s in run.statuses:
        eol = float(s.eol[0])
        if not math.isfinite(eol):
            continue
        t = float(s.t[0])
        isolated = int(s.isolated[0])
        predictions.append(
            {
                "t": t,
                "parameter": chain.classes[isolated] if isolated > 0 else None,
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
    profile = scenario.fault.profile
    limits = _truth_limits(scenario, scenario.fault.parameter)
    # only the predictions made while the faulty parameter was the isolated one are about it
    predictions = [p for p in predictions if p["parameter"] == scenario.fault.parameter]
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


def chain_results(run: ChainRun, chain: PHMChain, scenario: Scenario) -> dict:
    """The results of a run, JSON-ready (inf and NaN are None).

    Keys:
        detection_time: first alarm (s) or None.
        isolated_parameter: the last status's isolated parameter, None when none.
        class_probabilities: class -> mean probability over the statuses since detection that had a
            full isolation frame (the statuses the chain's own isolation averages; before a full frame
            a status reports "none" = 1), or the last status's when there is no alarm.
        estimate: {"parameter", "t", "value"}: the isolated parameter's estimate at every step where
            the chain ran its estimator (a full inversion window seen and an alarm raised; before, it
            holds the nominal values), stamped at ``status.t - chain.estimate_lag`` (the time it describes).
        eol_predictions: [{"t", "parameter", "eol", "limit", "rul", "rul_low", "rul_high"}] for every
            step with a finite End of Life (s); "parameter" is the one isolated at that step, "limit"
            "lower" or "upper".
        run: duration, steps, noise, estimate lag, frame (s).
        metrics: only when the scenario has a fault: fault parameter, fault onset (s), detection delay
            (s), isolation_correct, and when isolation is correct: "estimation" (errors of the estimate
            against the truth at its stamps from ESTIMATION_START on, with the window used),
            "eol_phases" (per profile segment whose true trend reaches a limit and has at least
            MIN_PHASE_PREDICTIONS predictions made while the fault parameter was isolated: true EoL,
            fraction of predictions heading for the right limit, EoL errors predicted - true, Saxena metrics
            on the RUL with alpha = 0.2, lambda = 0.5), "eol_fault_phase" (the first of them) and
            "predictions_without_true_eol" (finite predictions where the true trend is flat).
    """
    statuses = run.statuses
    if not statuses:
        raise ValueError("the run has no status")
    t = _times(run)
    last = statuses[-1]
    detection = float(last.detection_time[0])
    detection_time = detection if math.isfinite(detection) else None
    isolated = _isolated(run)
    isolated_parameter = chain.classes[isolated] if isolated > 0 else None

    # the statuses the chain's isolation averages: alarm raised and a full frame seen
    counted = [s.probabilities[0] for s in statuses if s.counted[0]]
    probabilities = np.mean(counted, axis=0) if counted else last.probabilities[0]

    estimate = _estimate_series(run, chain, isolated)
    predictions = _eol_predictions(run, chain)
    results: dict[str, Any] = {
        "detection_time": detection_time,
        "isolated_parameter": isolated_parameter,
        "class_probabilities": {name: float(p) for name, p in zip(chain.classes, probabilities)},
        "estimate": estimate,
        "eol_predictions": predictions,
        "run": {
            "scenario": scenario.source,
            "duration": float(t[-1]),
            "steps": len(statuses),
            "noise": float(chain.config.noise),
            "estimate_lag": float(chain.estimate_lag),
            "frame": float(chain.config.frame),
        },
    }

    if scenario.fault is not None:
        parameter = scenario.fault.parameter
        onset = _fault_onset(scenario)
        metrics: dict[str, Any] = {
            "fault_parameter": parameter,
            "fault_onset": onset,
            "detection_delay": (detection_time - onset) if detection_time is not None and onset is not None else None,
            "isolation_correct": isolated_parameter == parameter,
            "limits": list(_truth_limits(scenario, parameter)),
        }
        if isolated_parameter == parameter:
            stamps = np.array(estimate["t"])
            values = np.array(estimate["value"])
            index = scenario.model.parameter_names.index(parameter)
            window = stamps >= ESTIMATION_START
            if window.any():
                truth = scenario.parameters_at(stamps[window])[:, index]
                errors = estimation_errors(values[window], truth)
                nominal = float(scenario.model.nominal[parameter])
                metrics["estimation"] = {
                    **errors,
                    "relative_to_nominal": {k: v / abs(nominal) for k, v in errors.items()},
                    "window": [float(stamps[window][0]), float(stamps[window][-1])],
                    "n": int(window.sum()),
                }
            else:
                metrics["estimation"] = None
            phases, without_truth = _phase_metrics(predictions, scenario)
            metrics["eol_phases"] = phases
            metrics["eol_fault_phase"] = phases[0] if phases else None
            metrics["predictions_without_true_eol"] = without_truth
        results["metrics"] = metrics
    return json_ready(results)


# --------------------------------------------------------------------------------------------------
# figures
# --------------------------------------------------------------------------------------------------


def _mark_events(ax, results: dict, scenario: Scenario, label: bool = True) -> None:
    """Vertical lines at the fault onset, the profile's breakpoints and the detection time."""
    if scenario.fault is not None:
        times = scenario.fault.profile.times
        for j, tb in enumerate(times):
            ax.axvline(tb, color="0.6", lw=0.8, ls=":", label="profile breakpoints" if label and j == 0 else None)
    if results.get("detection_time") is not None:
        ax.axvline(results["detection_time"], color="tab:red", lw=1.0, ls="--",
                   label=f"detection {results['detection_time']:g} s" if label else None)


def plot_time_frequency(run: ChainRun, chain: PHMChain, scenario: Scenario, path: str | os.PathLike[str],
                        results: dict | None = None) -> Path:
    """Paper Fig 9: |STFT| of the I element's EA residual series over time and frequency.

    The STFT window is the isolation frame (``chain.config.frame`` in sub-windows), the hop 1 s;
    each column is drawn at the centre time of its window; frequencies up to the model's excitation
    bandwidth. Colour: log scale, three decades below the maximum.
    """
    results = chain_results(run, chain, scenario) if results is None else results
    sub = chain.monitor.config.sub_window
    frame = round(chain.config.frame / sub)
    hop = max(round(1.0 / sub), 1)
    i = chain.monitor.inertia_index
    name = chain.monitor.elements[i]
    series = run.residual_series[i]
    fig, ax = plt.subplots(figsize=(10, 5))
    if len(series) < frame:
        ax.text(0.5, 0.5, f"run shorter than one {chain.config.frame:g} s frame", ha="center", transform=ax.transAxes)
    else:
        frequencies, times, magnitude = residual_spectrogram(series, sub, frame, hop)
        times = times + 0.5 * sub  # sub-window j is centred at (j + 1/2) sub_window
        keep = frequencies <= chain.model.excitation_bandwidth + 1e-9
        shown = magnitude[keep]
        top = float(shown.max()) if shown.size and shown.max() > 0 else 1.0
        mesh = ax.pcolormesh(times, frequencies[keep], np.maximum(shown, top * 1e-3), shading="nearest",
                             norm=LogNorm(vmin=top * 1e-3, vmax=top), cmap="viridis")
        colorbar = fig.colorbar(mesh, ax=ax)
        colorbar.set_label(f"|STFT| of the EA residual of {name} (J)")
        _mark_events(ax, results, scenario)
        ax.set_xlim(0, float(run.t[-1]))
        ax.legend(loc="upper right", fontsize=8, framealpha=0.8)
    ax.set_xlabel(f"time (s, centre of the {chain.config.frame:g} s STFT window, hop {hop * sub:g} s)")
    ax.set_ylabel("frequency (Hz)")
    ax.set_title(f"Time-frequency map of the EA residual of the I element {name}")
    fig.tight_layout()
    return save_figure(fig, path)


def _truth_curve(scenario: Scenario, parameter: str, end: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, end, 2001)
    index = scenario.model.parameter_names.index(parameter)
    return t, scenario.parameters_at(t)[:, index]


def _fit_steps(run: ChainRun, chain: PHMChain, results: dict) -> list[int]:
    """Steps whose extrapolation is drawn: the middle prediction of each scored phase, else up to 3
    predictions spread over the run."""
    t = _times(run)
    chosen: list[float] = []
    phases = (results.get("metrics") or {}).get("eol_phases") or []
    for phase in phases:
        first, last = phase["prediction_times"]
        chosen.append(0.5 * (first + last))
    if not chosen:
        times = [p["t"] for p in results["eol_predictions"]]
        if times:
            chosen = [times[int(k)] for k in np.unique(np.linspace(0, len(times) - 1, min(3, len(times))).round())]
    finite = np.array([math.isfinite(float(s.eol[0])) for s in run.statuses])
    steps = []
    for target in chosen[:3]:
        candidates = np.flatnonzero(finite)
        if len(candidates):
            steps.append(int(candidates[np.argmin(np.abs(t[candidates] - target))]))
    return sorted(set(steps))


def plot_estimate(run: ChainRun, chain: PHMChain, scenario: Scenario, path: str | os.PathLike[str],
                  results: dict | None = None) -> Path:
    """Paper Fig 12: the isolated parameter's estimate vs the truth, the safe limits, and the degree-1
    extrapolations from a prediction time in each phase up to the limit, with the predicted End of
    Life (x) and the true trend's End of Life (circle)."""
    results = chain_results(run, chain, scenario) if results is None else results
    estimate = results["estimate"]
    parameter = estimate["parameter"] or (scenario.fault.parameter if scenario.fault else None)
    fig, ax = plt.subplots(figsize=(10, 5.5))
    end = float(run.t[-1])
    if parameter is None:
        ax.text(0.5, 0.5, "no parameter isolated", ha="center", transform=ax.transAxes)
        return save_figure(fig, path)
    unit = scenario.model.units.get(parameter, "")
    lower, upper = chain.model.safe_limits[parameter]
    right = end
    colors = ["tab:orange", "tab:purple", "tab:brown"]
    for k, i in enumerate(_fit_steps(run, chain, results) if estimate["parameter"] else []):
        prediction = run.statuses[i].end_of_life[0]
        if prediction is None or not math.isfinite(prediction.eol):
            continue
        fit, eol = prediction.fit, prediction.eol
        level = lower if prediction.limit == "lower" else upper
        x = np.linspace(fit.times[0], eol, 200)
        color = colors[k % len(colors)]
        ax.plot(x, np.polyval(fit.coefficients, x - fit.t), color=color, lw=1.4, ls="-.",
                label=f"degree-{len(fit.coefficients) - 1} fit at t = {fit.t:g} s")
        ax.plot([fit.t], [np.polyval(fit.coefficients, 0.0)], "o", color=color, ms=5)
        ax.plot([eol], [level], "x", color=color, ms=10, mew=2.5, zorder=5)
        text = f"EoL {eol:.1f} s"
        if scenario.fault is not None and scenario.fault.parameter == parameter:
            true_eol = float(scenario.fault.profile.trend_end_of_life(np.array([fit.t]), _truth_limits(scenario, parameter))[0])
            if math.isfinite(true_eol):
                true_level = _truth_limits(scenario, parameter)[0 if prediction.limit == "lower" else 1]
                ax.plot([true_eol], [true_level], "o", color=color, ms=13, mfc="none", mew=1.5, zorder=6)
                text += f" (true {true_eol:.1f} s)"
                right = max(right, true_eol)
        offset = 8 if prediction.limit == "upper" else -16
        ax.annotate(text, (eol, level), textcoords="offset points", xytext=(-150 if eol > 0.8 * right else -40, offset),
                    color=color, fontsize=9, fontweight="bold")
        right = max(right, eol)
    right = min(right, 2.0 * end) * 1.02
    if scenario.fault is not None and scenario.fault.parameter == parameter:
        tt, truth = _truth_curve(scenario, parameter, right)
        ax.plot(tt, truth, color="k", lw=1.5, label="true value")
    ax.plot(estimate["t"], estimate["value"], ".", color="tab:blue", ms=4, label="EA estimate (filtered)")
    ax.axhline(lower, color="tab:red", lw=1.0, label=f"safe limits {lower:g} / {upper:g} {unit}")
    ax.axhline(upper, color="tab:red", lw=1.0)
    ax.plot([], [], "x", color="0.3", ms=8, mew=2, label="predicted EoL")
    ax.plot([], [], "o", color="0.3", ms=9, mfc="none", label="true trend EoL")
    span = upper - lower
    ax.set_ylim(lower - 0.15 * span, upper + 0.35 * span)  # room for the legend above the limits
    ax.set_xlim(0, right)
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"{parameter} ({unit})")
    ax.set_title(f"Estimate of {parameter} and End-of-Life extrapolation")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper center", fontsize=8, ncol=3, framealpha=0.85)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_estimate_error(run: ChainRun, chain: PHMChain, scenario: Scenario, path: str | os.PathLike[str],
                        results: dict | None = None) -> Path:
    """Paper Fig 13: estimate minus truth over time (parameter unit, and % of nominal on the right)."""
    results = chain_results(run, chain, scenario) if results is None else results
    estimate = results["estimate"]
    parameter = estimate["parameter"]
    fig, ax = plt.subplots(figsize=(10, 4.5))
    if parameter is None or not estimate["t"]:
        ax.text(0.5, 0.5, "no estimate", ha="center", transform=ax.transAxes)
        return save_figure(fig, path)
    t = np.array(estimate["t"])
    index = scenario.model.parameter_names.index(parameter)
    error = np.array(estimate["value"]) - scenario.parameters_at(t)[:, index]
    unit = scenario.model.units.get(parameter, "")
    nominal = float(scenario.model.nominal[parameter])
    ax.axvspan(0, ESTIMATION_START, color="0.9", label=f"start-up (not scored, < {ESTIMATION_START:g} s)")
    ax.plot(t, error, ".-", color="tab:blue", ms=4, lw=0.8, label=f"estimate - truth of {parameter}")
    ax.axhline(0.0, color="k", lw=0.8)
    _mark_events(ax, results, scenario)
    scored = t >= ESTIMATION_START
    if scored.any():
        bound = 1.3 * float(np.max(np.abs(error[scored])))
        ax.set_ylim(-max(bound, 1e-12), max(bound, 1e-12))
    estimation = (results.get("metrics") or {}).get("estimation")
    if estimation:
        ax.set_title(
            f"Error of the estimate of {parameter}: max {estimation['max']:.3g}, median {estimation['median']:.3g}, "
            f"RMSE {estimation['rmse']:.3g} {unit} from {ESTIMATION_START:g} s"
        )
    else:
        ax.set_title(f"Error of the estimate of {parameter}")
    ax.set_xlim(0, float(run.t[-1]))
    ax.set_xlabel("time the estimate describes (s)")
    ax.set_ylabel(f"error ({unit})")
    right = ax.secondary_yaxis("right", functions=(lambda e: 100 * e / nominal, lambda p: p * nominal / 100))
    right.set_ylabel("% of nominal")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=8, framealpha=0.85)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_rul(run: ChainRun, chain: PHMChain, scenario: Scenario, path: str | os.PathLike[str],
             results: dict | None = None) -> Path:
    """RUL prediction (points) and interval (shaded) over time vs the true RUL of the profile's trend,
    with the alpha = 0.2 cone (dashed). The y axis is clipped to [0, 2 x the largest finite true RUL]."""
    results = chain_results(run, chain, scenario) if results is None else results
    predictions = results["eol_predictions"]
    fig, ax = plt.subplots(figsize=(10, 5))
    end = float(run.t[-1])
    tt = np.linspace(0.0, end, 2401)
    top = None
    if scenario.fault is not None and results["isolated_parameter"] == scenario.fault.parameter:
        parameter = scenario.fault.parameter
        true_eol = scenario.fault.profile.trend_end_of_life(tt, _truth_limits(scenario, parameter))
        true_rul = np.where(np.isfinite(true_eol), true_eol - tt, np.nan)
        # break the line where the true EoL jumps (a new segment)
        jumps = np.flatnonzero(np.abs(np.diff(np.nan_to_num(true_eol, posinf=1e300))) > 1e-6) + 1
        true_rul[jumps] = np.nan
        ax.plot(tt, true_rul, color="k", lw=1.5, label="true RUL (trend of the profile)")
        ax.plot(tt, (1 - ALPHA) * true_rul, color="k", lw=0.9, ls="--", label=f"alpha = {ALPHA:g} cone")
        ax.plot(tt, (1 + ALPHA) * true_rul, color="k", lw=0.9, ls="--")
        if np.isfinite(true_rul).any():
            top = 2.0 * float(np.nanmax(true_rul))
    if predictions:
        t = np.array([p["t"] for p in predictions])
        rul = np.array([p["rul"] for p in predictions])
        big = 1e9
        low = np.array([big if p["rul_low"] is None else p["rul_low"] for p in predictions])
        high = np.array([big if p["rul_high"] is None else p["rul_high"] for p in predictions])
        if top is None:
            top = 2.0 * float(np.percentile(rul, 90)) if np.any(rul > 0) else 1.0
        # a gap of more than one step between predictions, or a change of parameter, breaks the shading
        parameters = [p["parameter"] for p in predictions]
        gaps = np.flatnonzero((np.diff(t) > 1.5 * _step_time(chain))
                              | np.array([a != b for a, b in itertools.pairwise(parameters)], dtype=bool)) + 1
        for k, part in enumerate(np.split(np.arange(len(t)), gaps)):
            ax.fill_between(t[part], np.clip(low[part], -top, 10 * top), np.clip(high[part], -top, 10 * top),
                            color="tab:blue", alpha=0.25, lw=0,
                            label=f"{chain.config.extrapolation.confidence:.0%} interval" if k == 0 else None)
        same = np.array([p["parameter"] == results["isolated_parameter"] for p in predictions])
        ax.plot(t[same], rul[same], ".", color="tab:blue", ms=5, label=f"predicted RUL ({results['isolated_parameter']})")
        if (~same).any():
            ax.plot(t[~same], rul[~same], "x", color="0.4", ms=5, label="while another parameter was isolated")
    if top is None or not math.isfinite(top) or top <= 0:
        top = 1.0
    _mark_events(ax, results, scenario)
    ax.set_ylim(0, top)
    ax.set_xlim(0, end)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("RUL (s)")
    ax.set_title("Remaining Useful Life")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=8, framealpha=0.85)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_signals(run: ChainRun, chain: PHMChain, scenario: Scenario, path: str | os.PathLike[str],
                 results: dict | None = None) -> Path:
    """Measured vs reference EA of every element per step, and the detection statistics (every element's
    EA residual and the energy balance's) relative to their thresholds (log scale; the alarm needs one
    above 1 for ``persistence`` steps)."""
    results = chain_results(run, chain, scenario) if results is None else results
    t = _times(run)
    elements = chain.monitor.elements
    n = len(elements)
    columns = 2
    rows = (n + columns - 1) // columns
    fig = plt.figure(figsize=(11, 2.6 * rows + 3.4))
    grid = fig.add_gridspec(rows + 1, columns, height_ratios=[1.0] * rows + [1.3])
    ea = np.array([s.ea[0] for s in run.statuses])
    reference = np.array([s.ea_reference[0] for s in run.statuses])
    for e, name in enumerate(elements):
        ax = fig.add_subplot(grid[e // columns, e % columns])
        ax.plot(t, reference[:, e], color="k", lw=1.0, label="reference")
        ax.plot(t, ea[:, e], color="tab:blue", lw=1.0, alpha=0.8, label="measured")
        _mark_events(ax, results, scenario, label=False)
        ax.set_title(f"EA of {name} per {chain.config.step:g} s step", fontsize=10)
        ax.set_ylabel("EA (J)")
        ax.grid(alpha=0.3)
        if e == 0:
            ax.legend(loc="upper right", fontsize=8)
    ax = fig.add_subplot(grid[rows, :])
    statistic = np.array([np.abs(s.statistic[0]) for s in run.statuses]) / chain.thresholds
    floor = 1e-3
    for e, name in enumerate(chain.statistic_names):
        ax.semilogy(t, np.maximum(statistic[:, e], floor), lw=1.0, label=name)
    ax.axhline(1.0, color="k", lw=1.4, label="threshold")
    _mark_events(ax, results, scenario)
    ax.set_ylim(floor, max(10.0, float(np.nanmax(statistic)) * 2 if statistic.size else 10.0))
    ax.set_xlabel("time (s)")
    ax.set_ylabel("|relative residual| / threshold")
    ax.set_title(f"Detection statistic over {chain.config.detector.window:g} s "
                 f"(alarm after {chain.config.detector.persistence} steps above 1)", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="upper left", fontsize=8, ncol=len(chain.statistic_names) + 2)
    fig.tight_layout()
    return save_figure(fig, path)


_PLOTS = {
    "time_frequency": plot_time_frequency,
    "estimate": plot_estimate,
    "estimate_error": plot_estimate_error,
    "rul": plot_rul,
    "signals": plot_signals,
}


# --------------------------------------------------------------------------------------------------
# report
# --------------------------------------------------------------------------------------------------


def _fmt(value: Any, digits: int = 4) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(value)
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.{digits}g}"
    return str(value)


def _summary_rows(results: dict) -> list[tuple[str, str]]:
    rows = [
        ("detection time (s)", _fmt(results.get("detection_time"))),
        ("isolated parameter", _fmt(results.get("isolated_parameter"))),
        ("class probabilities (mean since detection)",
         ", ".join(f"{k}: {v:.3f}" for k, v in results.get("class_probabilities", {}).items())),
        ("End-of-Life predictions", str(len(results.get("eol_predictions", [])))),
    ]
    metrics = results.get("metrics")
    if not metrics:
        return rows
    rows += [
        ("fault parameter", _fmt(metrics.get("fault_parameter"))),
        ("fault onset (s)", _fmt(metrics.get("fault_onset"))),
        ("detection delay (s)", _fmt(metrics.get("detection_delay"))),
        ("isolation correct", _fmt(metrics.get("isolation_correct"))),
    ]
    estimation = metrics.get("estimation")
    if estimation:
        window = estimation["window"]
        rows.append((
            f"estimation error, {window[0]:.4g}-{window[1]:.4g} s (max / median / RMSE)",
            (f"{estimation['max']:.4g} / {estimation['median']:.4g} / {estimation['rmse']:.4g} "
            f"({100 * estimation['relative_to_nominal']['max']:.2f} / {100 * estimation['relative_to_nominal']['median']:.2f} / "
            f"{100 * estimation['relative_to_nominal']['rmse']:.2f} % of nominal)"),
        ))
    if "predictions_without_true_eol" in metrics:
        rows.append(("finite predictions where the true trend is flat", str(metrics["predictions_without_true_eol"])))
    return rows


def _phase_table(phases: list[dict]) -> list[str]:
    if not phases:
        return ["No phase of the profile had enough End-of-Life predictions to score."]
    lines = [
        ("| phase (s) | limit | true EoL (s) | predictions | median predicted EoL (s) | EoL error min / median / max (s) "
        "| alpha-lambda (t, passed) | PH (s) | RA | CRA | RUL RMSE (s) |"),
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for p in phases:
        start, end = p["segment"]
        prognostics = p["prognostics"]
        if "error" in prognostics:
            saxena = f"| {prognostics['error']} | - | - | - | - |"
        else:
            al = prognostics["alpha_lambda"]
            saxena = (
                f"| {al['t_prediction']:.4g} s, {_fmt(al['passed'])} | {_fmt(prognostics['prognostic_horizon'])} "
                f"| {_fmt(prognostics['relative_accuracy'], 3)} | {_fmt(prognostics['cumulative_relative_accuracy'], 3)} "
                f"| {_fmt(prognostics['rul_errors']['rmse'])} |"
            )
        error = p["eol_error"]
        lines.append(
            f"| {start:g}-{_fmt(end)} | {p['limit']} | {p['true_eol']:.4g} | {p['n_predictions']} "
            f"({p['prediction_times'][0]:g}-{p['prediction_times'][1]:g} s) | {p['predicted_eol']['median']:.4g} "
            f"| {error['min']:.3g} / {error['median']:.3g} / {error['max']:.3g} " + saxena
        )
    return lines


def _report_text(out: Path, results: dict, figures: dict[str, Path], title: str, sections: list[str] | None) -> str:
    lines = [f"# {title}", "", "## Summary", "", "| quantity | value |", "|---|---|"]
    lines += [f"| {name} | {value} |" for name, value in _summary_rows(results)]
    metrics = results.get("metrics") or {}
    if "eol_phases" in metrics:
        lines += [
            "",
            "## End of Life per phase of the fault profile",
            "",
            ("True EoL: where the profile's current segment, extended, reaches the safe limit it heads for. "
            f"EoL error = predicted - true. Saxena et al. (2010) metrics on the RUL of the phase's predictions, "
            f"alpha = {ALPHA:g}, lambda = {LAMBDA:g}; PH uses the absolute cone alpha x EoL."),
            "",
            *_phase_table(metrics["eol_phases"]),
        ]
    if figures:
        lines += ["", "## Figures", ""]
        for name, path in figures.items():
            caption = FIGURES.get(name, (None, name))[1]
            relative = Path(os.path.relpath(Path(path), out)).as_posix()
            lines += [f"### {caption}", "", f"![{caption}]({relative})", ""]
    for section in sections or []:
        lines += ["", section.rstrip(), ""]
    return "\n".join(lines).rstrip() + "\n"


def write_phm_report(out: Path, results: dict, figures: dict[str, Path], title: str,
                     sections: list[str] | None = None) -> Path:
    """Write ``out/report.md`` atomically: summary table, per-phase End-of-Life table, the figures
    (linked relative to ``out``) and the extra markdown ``sections``."""
    out = Path(out)
    return write_text(out / "report.md", _report_text(out, results, figures, title, sections))


def write_phm_outputs(out: Path, run: ChainRun, chain: PHMChain, scenario: Scenario, title: str,
                      sections: list[str] | None = None) -> dict:
    """Results, figures and report of a run in ``out``: ``results.json``, ``report.md`` and the PNGs of
    :data:`FIGURES`.

    Everything is drawn in a temporary directory beside ``out`` and moved in only when all of it
    succeeded; ``results.json`` is written last, so its presence means the directory is complete.
    Returns the results.
    """
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    results = chain_results(run, chain, scenario)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        figures = {}
        for name, plot in _PLOTS.items():
            figures[name] = plot(run, chain, scenario, staging / FIGURES[name][0], results=results)
        write_phm_report(staging, results, figures, title, sections)
        out.mkdir(parents=True, exist_ok=True)
        (out / "results.json").unlink(missing_ok=True)  # the directory is incomplete until it is back
        for path in sorted(staging.iterdir()):
            os.replace(path, out / path.name)
        write_json(out / "results.json", results)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return results
