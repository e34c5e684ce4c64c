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
from ea_gym.reporting.results import ALPHA, LAMBDA, RunInputs, chain_results
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


def degrading_text(results: dict) -> str:
    """The parts judged degrading at the end in one line (results' "degrading")."""
    named = results.get("degrading") or []
    return f"degrading parts: {', '.join(named)}" if named else "degrading parts: none"


def component_text(series: dict) -> str:
    """A component at the end of the run in one line: its estimate (with its std and position in its safe range), its
    degrading probability, and its RUL with the interval (results' "components")."""
    value, std = series["value"][-1], series["std"][-1]
    unit = f" {series['unit']}" if series.get("unit") else ""
    lower, upper = series["limits"]
    if value is None:
        estimate = "no estimate"
    else:
        spread = f" +- {_fmt(std, 3)}" if std is not None else ""
        estimate = f"{_fmt(value)}{spread}{unit} ({(value - lower) / (upper - lower):.0%} of its safe range {lower:g}-{upper:g}{unit})"
    probability = series["degrading"][-1]
    if probability is None:
        degrading = "degrading not estimated (the chain runs without its joint filter)"
    else:
        degrading = f"degrading with probability {probability:.2f}" + (" (named)" if series["named"][-1] else "")
    rul, low, high = series["rul"][-1], series["rul_low"][-1], series["rul_high"][-1]
    remaining = "no End of Life" if rul is None else f"RUL {_fmt(rul)} s [{_fmt(low)}, {_fmt(high)}]"
    return f"{estimate}; {degrading}; {remaining}"


def _component_rows(results: dict) -> list[tuple[str, str]]:
    """One row per component at the end of the run."""
    confidence = results.get("run", {}).get("rul_interval")
    interval = f" and its {confidence:.0%} interval" if confidence is not None else " and its interval"
    return [(f"{name} at {series['t'][-1]:g} s: estimate, degrading probability, RUL{interval}", component_text(series))
            for name, series in (results.get("components") or {}).items() if series["t"]]


def _input_rows(results: dict) -> list[tuple[str, str]]:
    """The noise levels the chain ran with and where they came from, and the commissioned machine."""
    run = results.get("run", {})
    rows = []
    if "noise" in run:
        estimate = f"; the record's estimate {run['noise_estimate']:.2%}" if run.get("noise_estimate") is not None else ""
        rows.append(("sensor noise (of each signal's RMS)", f"{run['noise']:.2%} ({run.get('noise_source', '-')}{estimate})"))
    if "load_noise" in run:
        rows.append(("load noise (of the load's RMS)", f"{run['load_noise']:.2%} ({run.get('load_noise_source', '-')})"))
    commissioning = results.get("commissioning")
    if commissioning:
        values = ", ".join(f"{name} {_fmt(value)}" + (f" +- {_fmt(commissioning['std'][name], 2)}" if commissioning["std"][name] is not None else "")
                           for name, value in commissioning["values"].items())
        rows.append(("healthy machine (commissioned)", f"{values} (from {commissioning['source']})"))
    return rows


def _summary_rows(results: dict) -> list[tuple[str, str]]:
    measurements = results.get("run", {}).get("measurements")
    rows = [("recorded measurements (truth unknown: no errors against it)", str(measurements))] if measurements else []
    rows += [
        ("model fit", fit_text(results)),
        ("degrading parts (named at the end)", ", ".join(results.get("degrading") or []) or "none"),
        *_component_rows(results),
        *_input_rows(results),
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


def _percent(value: float | None) -> str:
    return "-" if value is None else f"{value:.0%}"


def _parts_table(metrics: dict) -> list[str]:
    """Every faulty part's metrics (results' metrics "parts") and how often the set was named exactly."""
    lines = [
        "| part | onset (s) | estimate error median / max | named right | RUL interval covers the truth (predicted) "
        "| alpha-lambda (fault phase) |",
        "|---|---|---|---|---|---|",
    ]
    for name, part in metrics["parts"].items():
        estimation = part.get("estimation")
        error = f"{estimation['median']:.3g} / {estimation['max']:.3g}" if estimation else "-"
        coverage = part["rul_coverage"]
        covered = f"{_percent(coverage['fraction'])} ({_percent(coverage['predicted'])}) of {coverage['steps']} steps"
        phase = part.get("eol_fault_phase")
        passed = "-" if not phase or "alpha_lambda" not in phase["prognostics"] else _fmt(phase["prognostics"]["alpha_lambda"]["passed"])
        lines.append(f"| {name} | {_fmt(part['onset'])} | {error} | {_percent(part['named'])} | {covered} | {passed} |")
    scored = metrics.get("degrading_set")
    if scored:
        lines += ["", f"The set of degrading parts was named exactly in {scored['exact']:.0%} of the {scored['steps']} steps "
                  f"scored (from {scored['settling']:g} s after the first onset and after every part's last change)."]
    return lines


def _report_text(out: Path, results: dict, figures: dict[str, Path], title: str, sections: list[str] | None) -> str:
    lines = [f"# {title}", "", "## Summary", "", "| quantity | value |", "|---|---|"]
    lines += [f"| {name} | {value} |" for name, value in _summary_rows(results)]
    metrics = results.get("metrics") or {}
    if metrics.get("parts"):
        lines += [
            "",
            "## Every faulty part",
            "",
            ("Each part's estimate against its profile from the estimation start, whether it was named degrading exactly "
             "when it was and whether its RUL interval held the true RUL (a step without one counts as a miss), from "
             "30 s after its onset; alpha-lambda of its End-of-Life predictions in its fault phase."),
            "",
            *_parts_table(metrics),
        ]
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
                      sections: list[str] | None = None, measurements: str | None = None, inputs: RunInputs | None = None) -> dict:
    """Results, figures and report of a run in ``out``: ``results.json``, ``report.md`` and the PNGs of
    :data:`FIGURES`. ``scenario`` None: a run of recorded ``measurements`` (their file), whose truth is
    unknown: no metrics and none of the :data:`TRUTH_FIGURES`.

    ``inputs``: where the noise levels and the healthy machine came from (:class:`~ea_gym.reporting.results.RunInputs`;
    None: the scenario's).

    Everything is drawn in a temporary directory beside ``out`` and moved in only when all of it
    succeeded; ``results.json`` is written last, so its presence means the directory is complete.
    Returns the results.
    """
    results = chain_results(run, chain, scenario, measurements, RunInputs() if inputs is None else inputs)
    with staged_output(out, last="results.json") as staging:
        figures = {}
        for name, plot in PLOTS.items():
            if scenario is None and name in TRUTH_FIGURES:
                continue
            figures[name] = plot(run, chain, scenario, staging / FIGURES[name][0], results=results)
        write_phm_report(staging, results, figures, title, sections)
        write_json(staging / "results.json", results)
    return results
