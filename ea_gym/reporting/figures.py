"""Figures of one scenario run through the PHM chain (paper Figs 9, 12, 13, plus RUL and detection).

:func:`plot_time_frequency`, :func:`plot_estimate`, :func:`plot_estimate_error`, :func:`plot_rul` and
:func:`plot_signals` each draw one PNG from the run, the chain and the results of
:func:`~ea_gym.reporting.results.chain_results`; ``PLOTS`` names them as ``FIGURES`` does their files. The estimate
figure is drawn by :mod:`~ea_gym.reporting.estimate_figure`; what the figures share (each component's colour and
marker, End-of-Life labels that never overprint) is in :mod:`~ea_gym.reporting.drawing`.

Units: times in s, parameters in their SI unit (``SystemModel.units``), EA in J, frequencies in Hz.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.colors import LogNorm
from numpy.typing import ArrayLike

from ea_gym.diagnosis.features import residual_spectrogram
from ea_gym.files import save_figure
from ea_gym.phm import ChainRun, PHMChain
from ea_gym.pyplot import plt
from ea_gym.reporting.drawing import component_style, joint_results, mark_events, plot_within
from ea_gym.reporting.estimate_figure import estimate_figure
from ea_gym.reporting.results import ALPHA, ESTIMATION_START, chain_results
from ea_gym.scenario import Scenario

#: figure name -> (file name, caption)
FIGURES: dict[str, tuple[str, str]] = {
    "time_frequency": ("time_frequency.png", "Time-frequency map of the I element's EA residual (paper Fig 9)"),
    "estimate": ("estimate.png", "Every component's estimate, truth, safe limits and End of Life (paper Fig 12)"),
    "estimate_error": ("estimate_error.png", "Estimation error of every component over time (paper Fig 13)"),
    "rul": ("rul.png", "Remaining Useful Life of every component: prediction, interval and truth with the alpha cone"),
    "signals": ("signals.png", "Measured and reference Energy Activity per element, detection statistic"),
}
#: the figures that compare with the truth: not drawn for recorded measurements
TRUTH_FIGURES = ("estimate_error",)
#: the captions of the figures of recorded measurements, where they differ: no truth is drawn
RECORDED_CAPTIONS: dict[str, str] = {
    "estimate": "Every component's estimate, safe limits and End of Life (paper Fig 12; no truth: recorded measurements)",
    "rul": "Remaining Useful Life of every component: prediction and interval (no truth: recorded measurements)",
}


def plot_time_frequency(run: ChainRun, chain: PHMChain, scenario: Scenario | None, path: str | os.PathLike[str],
                        results: dict | None = None) -> Path:
    """Paper Fig 9: |STFT| of the I element's EA residual series over time and frequency.

    The STFT window is the isolation frame (``chain.config.isolation.frame`` in sub-windows), the hop 1 s;
    each column is drawn at the centre time of its window; frequencies up to the model's excitation
    bandwidth. Colour: log scale, three decades below the maximum.
    """
    results = chain_results(run, chain, scenario) if results is None else results
    sub = chain.monitor.config.sub_window
    frame = round(chain.config.isolation.frame / sub)
    hop = max(round(1.0 / sub), 1)
    i = chain.monitor.inertia_index
    name = chain.monitor.elements[i]
    series = run.residual_series[i]
    fig, ax = plt.subplots(figsize=(10, 5))
    if len(series) < frame:
        ax.text(0.5, 0.5, f"run shorter than one {chain.config.isolation.frame:g} s frame", ha="center", transform=ax.transAxes)
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
        mark_events(ax, results, scenario)
        ax.set_xlim(0, float(run.t[-1]))
        if ax.get_legend_handles_labels()[0]:  # nothing to mark without a fault profile or an alarm
            ax.legend(loc="upper right", fontsize=8, framealpha=0.8)
    ax.set_xlabel(f"time (s, centre of the {chain.config.isolation.frame:g} s STFT window, hop {hop * sub:g} s)")
    ax.set_ylabel("frequency (Hz)")
    ax.set_title(f"Time-frequency map of the EA residual of the I element {name}")
    fig.tight_layout()
    return save_figure(fig, path)


def plot_estimate(run: ChainRun, chain: PHMChain, scenario: Scenario | None, path: str | os.PathLike[str],
                  results: dict | None = None) -> Path:
    """Paper Fig 12 for every component: one panel per degradable part (:func:`estimate_figure`)."""
    results = chain_results(run, chain, scenario) if results is None else results
    return save_figure(estimate_figure(run, chain, scenario, results), path)


def plot_estimate_error(run: ChainRun, chain: PHMChain, scenario: Scenario, path: str | os.PathLike[str],
                        results: dict | None = None) -> Path:
    """Paper Fig 13: estimate minus truth over time; every component's (:func:`_component_errors`) with the chain's
    per-part health, else the suspect's (parameter unit, and % of nominal on the right)."""
    results = chain_results(run, chain, scenario) if results is None else results
    if joint_results(results):
        return save_figure(_component_errors(chain, scenario, results), path)
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
    # the axis fits the scored errors; a larger start-up error is drawn at its edge
    scored = t >= ESTIMATION_START
    bound = max(1.3 * float(np.max(np.abs(error[scored] if scored.any() else error))), 1e-12)
    ax.plot(t, np.where(np.abs(error) <= bound, error, np.nan), "-", color="tab:blue", lw=0.8)
    plot_within(ax, t, error, -bound, bound, color="tab:blue", label=f"estimate - truth of {parameter}")
    ax.axhline(0.0, color="k", lw=0.8)
    mark_events(ax, results, scenario)
    ax.set_ylim(-bound, bound)
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
    def percent(error: ArrayLike) -> np.ndarray:
        return 100 * np.asarray(error) / nominal

    def value(share: ArrayLike) -> np.ndarray:
        return np.asarray(share) * nominal / 100

    right = ax.secondary_yaxis("right", functions=(percent, value))
    right.set_ylabel("% of nominal")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=8, framealpha=0.85)
    fig.tight_layout()
    return save_figure(fig, path)


def _component_errors(chain: PHMChain, scenario: Scenario, results: dict) -> Any:
    """Every component's estimate minus its truth over time, as % of its nominal value (the parts' units differ), each
    in its own colour and marker; the axis fits the errors from ESTIMATION_START on, larger ones drawn at its edge."""
    fig, ax = plt.subplots(figsize=(10, 4.5))
    ax.axvspan(0, ESTIMATION_START, color="0.9", label=f"start-up (not scored, < {ESTIMATION_START:g} s)")
    errors = {}
    for name, series in results["components"].items():
        t = np.asarray(series["t"], dtype=float)
        value = np.array([np.nan if v is None else v for v in series["value"]], dtype=float)
        truth = scenario.parameters_at(t)[:, scenario.model.parameter_names.index(name)]
        errors[name] = (t, 100.0 * (value - truth) / float(scenario.model.nominal[name]))
    scored = [np.abs(error[(t >= ESTIMATION_START) & np.isfinite(error)]) for t, error in errors.values()]
    bound = max(1.3 * max((float(e.max()) for e in scored if e.size), default=0.0), 1e-9)
    metrics = (results.get("metrics") or {}).get("parts") or {}
    for name, (t, error) in errors.items():
        color, marker = component_style(chain, name)
        ax.plot(t, np.where(np.abs(error) <= bound, error, np.nan), "-", color=color, lw=0.7)
        median = (metrics.get(name) or {}).get("estimation")
        scored_text = f" (median {median['relative_to_nominal']['median']:.2%} of nominal)" if median else ""
        plot_within(ax, t, error, -bound, bound, color=color, marker=marker, size=3.0, label=f"estimate - truth of {name}{scored_text}")
    ax.axhline(0.0, color="k", lw=0.8)
    mark_events(ax, results, scenario)
    ax.set_ylim(-bound, bound)
    ax.set_xlim(0, max(float(t[-1]) for t, _ in errors.values()))
    ax.set_xlabel("time the estimate describes (s)")
    ax.set_ylabel("error (% of nominal)")
    ax.set_title("Error of every component's estimate")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=8, framealpha=0.85)
    fig.tight_layout()
    return fig


def plot_rul(run: ChainRun, chain: PHMChain, scenario: Scenario | None, path: str | os.PathLike[str],
             results: dict | None = None) -> Path:
    """The Remaining Useful Life of every component (:func:`rul_figure`)."""
    results = chain_results(run, chain, scenario) if results is None else results
    return save_figure(rul_figure(run, chain, scenario, results), path)


def _true_rul(scenario: Scenario, name: str, tt: np.ndarray) -> np.ndarray:
    """The true RUL of faulty part ``name`` at times tt (s), NaN where its trend is flat and where its End of Life jumps
    (a new segment of its profile: the line breaks there)."""
    true_eol = scenario.true_end_of_life(tt)[name]
    true_rul = np.where(np.isfinite(true_eol), true_eol - tt, np.nan)
    jumps = np.flatnonzero(np.abs(np.diff(np.nan_to_num(true_eol, posinf=1e300))) > 1e-6) + 1
    true_rul[jumps] = np.nan
    return true_rul


def rul_figure(run: ChainRun, chain: PHMChain, scenario: Scenario | None, results: dict) -> Any:
    """RUL predictions over time against the truth, with the alpha = 0.2 cone (dashed).

    With the chain's per-part health (``HealthStatus.parts``): every component's RUL (points) and interval (shaded)
    from results' "components", each in its own colour and marker, and the true RUL of each faulty part in its colour.
    Without it, the estimator's predictions per parameter they were made for and the true RUL of the fault.
    The y axis is [0, 2 x the largest finite true RUL] (2 x the 90th percentile of the predictions without truth);
    predictions beyond it are drawn at its edge (:func:`plot_within`)."""
    fig, ax = plt.subplots(figsize=(10, 5))
    end = float(run.t[-1])
    tt = np.linspace(0.0, end, 2401)
    joint = joint_results(results)
    faulty = [] if scenario is None else [name for name in scenario.faulty_parameters if name in chain.degradable]
    # the estimator's own predictions are about its suspect: its truth is the isolated faulty part's, or the first one's
    truths = faulty if joint else [results["isolated_parameter"]] if results["isolated_parameter"] in faulty else faulty[:1]
    top = None
    for name, true_rul in ([] if scenario is None else [(name, _true_rul(scenario, name, tt)) for name in truths]):
        if np.isfinite(true_rul).any():
            color = component_style(chain, name)[0] if joint else "k"
            ax.plot(tt, true_rul, color=color, lw=1.5, label=f"true RUL of {name} (trend of the profile)")
            ax.plot(tt, (1 - ALPHA) * true_rul, color=color, lw=0.9, ls="--", label=f"alpha = {ALPHA:g} cone of {name}")
            ax.plot(tt, (1 + ALPHA) * true_rul, color=color, lw=0.9, ls="--")
            top = max(top or 0.0, 2.0 * float(np.nanmax(true_rul)))
    if joint:
        top = _draw_component_ruls(ax, chain, results, top)
    else:
        predictions = results["eol_predictions"]
        if predictions:
            t = np.array([p["t"] for p in predictions])
            rul = np.array([p["rul"] for p in predictions])
            if top is None:
                top = 2.0 * float(np.percentile(rul, 90)) if np.any(rul > 0) else 1.0
            _draw_rul_predictions(ax, chain, predictions, t, rul, top, truths[0] if truths else None)
    if top is None or not math.isfinite(top) or top <= 0:
        top = 1.0
    mark_events(ax, results, scenario)
    ax.set_ylim(0, top)
    ax.set_xlim(0, end)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("RUL (s)")
    ax.set_title("Remaining Useful Life of every component" if joint else "Remaining Useful Life")
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:  # no truth, no alarm: nothing drawn
        ax.legend(loc="upper right", fontsize=8, framealpha=0.85)
    else:
        ax.text(0.5, 0.5, "no End of Life predicted", ha="center", transform=ax.transAxes)
    fig.tight_layout()
    return fig


def _draw_component_ruls(ax: Any, chain: PHMChain, results: dict, top: float | None) -> float | None:
    """Every component's RUL points and interval in its own colour and marker; returns the y axis's top (s), set from
    the predictions (2 x their 90th percentile) where ``top`` is None and there are any."""
    big = 1e9
    drawn = {}
    for name, series in results["components"].items():
        t = np.asarray(series["t"], dtype=float)
        rul = np.array([np.nan if v is None else v for v in series["rul"]], dtype=float)
        if np.isfinite(rul).any():
            drawn[name] = (t, rul, series)
    if top is None and drawn:
        finite = np.concatenate([rul[np.isfinite(rul)] for _, rul, _ in drawn.values()])
        top = 2.0 * float(np.percentile(finite, 90)) if np.any(finite > 0) else 1.0
    if top is None:
        return None
    for name, (t, rul, series) in drawn.items():
        color, marker = component_style(chain, name)
        low = np.array([big if v is None else v for v in series["rul_low"]], dtype=float)
        high = np.array([big if v is None else v for v in series["rul_high"]], dtype=float)
        predicted = np.isfinite(rul)
        ax.fill_between(t, np.clip(low, -top, 10 * top), np.clip(high, -top, 10 * top), where=predicted, color=color, alpha=0.2, lw=0,
                        label=f"{results['run']['rul_interval']:.0%} interval of {name}")
        plot_within(ax, t[predicted], rul[predicted], 0.0, top, color=color, marker=marker, size=3.0, label=f"predicted RUL of {name}")
    return top


def _draw_rul_predictions(ax: Any, chain: PHMChain, predictions: list[dict], t: np.ndarray, rul: np.ndarray, top: float,
                          fault: str | None) -> None:
    """The predictions' intervals (shaded) and points, one colour per parameter: grey crosses for a
    parameter other than the faulty one (a wrong isolation)."""
    big = 1e9
    low = np.array([big if p["rul_low"] is None else p["rul_low"] for p in predictions])
    high = np.array([big if p["rul_high"] is None else p["rul_high"] for p in predictions])
    # a gap of more than one step between predictions, or a change of parameter, breaks the shading
    parameters = np.array([p["parameter"] for p in predictions])
    gaps = np.flatnonzero((np.diff(t) > 1.5 * chain.step_time) | (parameters[1:] != parameters[:-1])) + 1
    for k, part in enumerate(np.split(np.arange(len(t)), gaps)):
        ax.fill_between(t[part], np.clip(low[part], -top, 10 * top), np.clip(high[part], -top, 10 * top),
                        color="tab:blue", alpha=0.25, lw=0,
                        label=f"{chain.config.extrapolation.confidence:.0%} interval" if k == 0 else None)
    for parameter in dict.fromkeys(parameters):
        mine = parameters == parameter
        if fault is None or parameter == fault:
            plot_within(ax, t[mine], rul[mine], 0.0, top, color="tab:blue", label=f"predicted RUL of {parameter}")
        else:
            plot_within(ax, t[mine], rul[mine], 0.0, top, color="0.4", marker="x",
                        label=f"RUL of {parameter}, isolated wrongly (the fault is in {fault})")


def plot_signals(run: ChainRun, chain: PHMChain, scenario: Scenario | None, path: str | os.PathLike[str],
                 results: dict | None = None) -> Path:
    """Measured vs reference EA of every element per step, and the detection statistics (every element's
    EA residual and the energy balance's) relative to their thresholds (log scale; the alarm needs one
    above 1 for ``persistence`` steps)."""
    results = chain_results(run, chain, scenario) if results is None else results
    t = run.t
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
        mark_events(ax, results, scenario, label=False)
        ax.set_title(f"EA of {name} per {chain.config.timing.step:g} s step", fontsize=10)
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
    mark_events(ax, results, scenario)
    ax.set_ylim(floor, max(10.0, float(np.nanmax(statistic)) * 2 if statistic.size else 10.0))
    ax.set_xlabel("time (s)")
    ax.set_ylabel("|relative residual| / threshold")
    ax.set_title(f"Detection statistic over {chain.config.detector.window:g} s "
                 f"(alarm after {chain.config.detector.persistence} steps above 1)", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="upper left", fontsize=8, ncol=len(chain.statistic_names) + 2)
    fig.tight_layout()
    return save_figure(fig, path)


#: figure name -> the function drawing it
PLOTS: dict[str, Callable[..., Path]] = {
    "time_frequency": plot_time_frequency,
    "estimate": plot_estimate,
    "estimate_error": plot_estimate_error,
    "rul": plot_rul,
    "signals": plot_signals,
}
