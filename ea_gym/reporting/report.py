"""The markdown report of one scenario run through the PHM chain, and the directory of all its outputs.

:func:`write_phm_outputs` writes the figures of :data:`~ea_gym.reporting.figures.FIGURES`,
``report.md`` and ``results.json`` into one directory so that nothing is left half-written when
something fails.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ea_gym.files import staged_output, write_json, write_text
from ea_gym.phm import ChainRun, PHMChain
from ea_gym.reporting.figures import FIGURES, PLOTS, RECORDED_CAPTIONS, TRUTH_FIGURES
from ea_gym.reporting.results import ALPHA, LAMBDA, chain_results
from ea_gym.scenario import Scenario


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


def _probabilities(probabilities: dict[str, float]) -> str:
    return ", ".join(f"{k}: {v:.3f}" for k, v in probabilities.items())


def isolation_text(results: dict) -> str:
    """The isolated parameter, or why there is none: "k", "undecided (k 0.62 of the fault belief, ...)"."""
    isolated = results.get("isolated_parameter")
    if isolated is not None:
        return str(isolated)
    isolation = results.get("isolation") or {}
    if isolation.get("state") in ("model does not fit", "model fit not yet known"):
        return f"- ({isolation['state']}: no part is isolated)"
    if isolation.get("state") != "undecided":
        return "- (no alarm)"
    return (f"undecided: no parameter reaches {isolation['threshold']:.0%} of the fault belief "
            f"(most likely {isolation['favoured']}, {isolation['confidence']:.0%})")


def _latest_rows(results: dict) -> list[tuple[str, str]]:
    """The last End-of-Life prediction (its EoL and RUL with their bounds) and the last estimate, where there are any."""
    rows = []
    predictions = results.get("eol_predictions") or []
    if predictions:
        last = predictions[-1]
        where = f"{last['parameter']} at its {last['limit']} limit, predicted at {last['t']:g} s"
        rows.append(("latest End of Life (s)", f"{_fmt(last['eol'])} ({where})"))
        rows.append(("latest RUL (s) [low, high]", f"{_fmt(last['rul'])} [{_fmt(last['rul_low'])}, {_fmt(last['rul_high'])}]"))
    estimate = results.get("estimate") or {}
    if estimate.get("value"):
        rows.append((f"latest estimate of {estimate['parameter']}", f"{_fmt(estimate['value'][-1])} at {estimate['t'][-1]:g} s"))
    return rows


def fit_text(results: dict) -> str:
    """The model-fit verdict in one line (results' "model_fit")."""
    fit = results.get("model_fit") or {}
    if not fit.get("tested"):
        return "model fit not tested (the test is off, or the estimator has no innovations)"
    if fit["statistic"] is None:
        return "model fit not yet known: the record is shorter than the test's window"
    measured = f"NIS {fit['statistic']:.3g} per degree of freedom, band {fit['band'][0]:.3g}-{fit['band'][1]:.3g}"
    if fit["ok"] is None:
        return f"model fit not yet known ({measured}): no part is isolated and no End of Life given"
    since = f", since {fit['since']:g} s" if fit["since"] is not None else ""
    if fit["ok"]:
        return f"the model fits the data ({measured}{since})"
    return (f"the model does not fit the data ({measured}{since}): no part is isolated and no End of Life given; "
            "check the load column's unit, the time column's sample rate and each C element's form")


def _summary_rows(results: dict) -> list[tuple[str, str]]:
    measurements = results.get("run", {}).get("measurements")
    rows = [("recorded measurements (truth unknown: no errors against it)", str(measurements))] if measurements else []
    rows += [
        ("model fit", fit_text(results)),
        ("detection time (s)", _fmt(results.get("detection_time"))),
        ("isolated parameter", isolation_text(results)),
        ("class probabilities (the chain's belief at the end, which isolates)", _probabilities(results.get("class_probabilities", {}))),
        ("isolation network's own probabilities (mean since detection)", _probabilities(results.get("network_probabilities", {}))),
        ("End-of-Life predictions", str(len(results.get("eol_predictions", [])))),
        *_latest_rows(results),
    ]
    metrics = results.get("metrics")
    if not metrics:
        return rows
    rows += [
        ("fault parameter", _fmt(metrics.get("fault_parameter"))),
        ("fault onset (s)", _fmt(metrics.get("fault_onset"))),
        ("detection delay (s)", _fmt(metrics.get("detection_delay"))),
        ("isolation", _fmt(metrics.get("isolation_outcome"))),
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
            if results.get("run", {}).get("measurements"):
                caption = RECORDED_CAPTIONS.get(name, caption)
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


def write_phm_outputs(out: Path, run: ChainRun, chain: PHMChain, scenario: Scenario | None, title: str,
                      sections: list[str] | None = None, measurements: str | None = None) -> dict:
    """Results, figures and report of a run in ``out``: ``results.json``, ``report.md`` and the PNGs of
    :data:`FIGURES`. ``scenario`` None: a run of recorded ``measurements`` (their file), whose truth is
    unknown: no metrics and none of the :data:`TRUTH_FIGURES`.

    Everything is drawn in a temporary directory beside ``out`` and moved in only when all of it
    succeeded; ``results.json`` is written last, so its presence means the directory is complete.
    Returns the results.
    """
    results = chain_results(run, chain, scenario, measurements)
    with staged_output(out, last="results.json") as staging:
        figures = {}
        for name, plot in PLOTS.items():
            if scenario is None and name in TRUTH_FIGURES:
                continue
            figures[name] = plot(run, chain, scenario, staging / FIGURES[name][0], results=results)
        write_phm_report(staging, results, figures, title, sections)
        write_json(staging / "results.json", results)
    return results
