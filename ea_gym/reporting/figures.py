"""Figures of one scenario run through the PHM chain (paper Figs 9, 12, 13, plus RUL and detection).

:func:`plot_time_frequency`, :func:`plot_estimate`, :func:`plot_estimate_error`, :func:`plot_rul` and
:func:`plot_signals` each draw one PNG from the run, the chain and the results of
:func:`~ea_gym.reporting.results.chain_results`; ``PLOTS`` names them as ``FIGURES`` does their files.

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
from matplotlib.text import Annotation
from numpy.typing import ArrayLike

from ea_gym.diagnosis.features import residual_spectrogram
from ea_gym.files import save_figure
from ea_gym.phm import ChainRun, PHMChain
from ea_gym.pyplot import plt
from ea_gym.reporting.results import (
    ALPHA,
    ESTIMATION_START,
    chain_results,
    estimate_series,
    fault_of,
    faulty_parameter,
    isolated_class,
    truth_limits,
)
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
#: each component's colour and marker, in ``chain.degradable`` order (red is the safe limits', black the truth's, orange,
#: purple and brown the extrapolations')
COMPONENT_STYLES: tuple[tuple[str, str], ...] = (
    ("tab:blue", "o"), ("tab:green", "s"), ("tab:cyan", "^"), ("tab:olive", "D"), ("tab:pink", "v"), ("tab:gray", "P"),
    ("navy", "X"), ("darkgreen", "*"),
)
#: the backdrop of an End-of-Life label: the lines it crosses stay readable beneath it
LABEL_BOX = {"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.75}
#: the captions of the figures of recorded measurements, where they differ: no truth is drawn
RECORDED_CAPTIONS: dict[str, str] = {
    "estimate": "Every component's estimate, safe limits and End of Life (paper Fig 12; no truth: recorded measurements)",
    "rul": "Remaining Useful Life of every component: prediction and interval (no truth: recorded measurements)",
}


def _mark_events(ax: Any, results: dict, scenario: Scenario | None, label: bool = True) -> None:
    """Vertical lines at the fault onsets, every fault profile's breakpoints and the detection time."""
    breakpoints = sorted({t for fault in scenario.faults for t in fault.profile.times}) if scenario is not None else []
    for j, tb in enumerate(breakpoints):
        ax.axvline(tb, color="0.6", lw=0.8, ls=":", label="profile breakpoints" if label and j == 0 else None)
    if results.get("detection_time") is not None:
        ax.axvline(results["detection_time"], color="tab:red", lw=1.0, ls="--",
                   label=f"detection {results['detection_time']:g} s" if label else None)


def plot_within(ax: Any, x: ArrayLike, y: ArrayLike, bottom: float, top: float, color: str, label: str,
                marker: str = ".", size: float = 4.0) -> None:
    """Points (x, y) on an axis whose y range is [bottom, top] (set by the caller): those outside are
    drawn at the edge they passed as triangles pointing off the axis, so that none leaves it and the
    axis does not stretch to a runaway value. Nothing is drawn (and nothing enters the legend) for an
    empty set."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    inside = (y >= bottom) & (y <= top)
    if inside.any():
        ax.plot(x[inside], y[inside], marker, color=color, ms=size, ls="none", label=label)
    for edge, outside, pointer in ((top, y > top, "^"), (bottom, y < bottom, "v")):
        if outside.any():
            ax.plot(x[outside], np.full(int(outside.sum()), edge), pointer, color=color, ms=size + 2, ls="none",
                    clip_on=False, label=f"{label}: off the axis, {'above' if edge == top else 'below'} it")


def component_style(chain: PHMChain, name: str) -> tuple[str, str]:
    """The colour and marker of component ``name`` in every figure."""
    return COMPONENT_STYLES[chain.degradable.index(name) % len(COMPONENT_STYLES)]


def place_labels(ax: Any, labels: list[tuple[Annotation, int]]) -> None:
    """Move End-of-Life labels so that none overprints another: each label (with the direction, +1 up or -1 down, toward
    the inside of the axes from the limit it names), in order, is first moved sideways into the axes' width where it
    sticks out, then one label height plus 2 points that way while its box overlaps the box of a label placed before
    it. Call once the figure's layout is final (``tight_layout``)."""
    figure = ax.figure
    renderer = figure.canvas.get_renderer()
    to_points = 72.0 / figure.dpi
    frame = ax.get_window_extent(renderer)
    placed: list[Any] = []
    for label, direction in labels:
        box = label.get_window_extent(renderer)
        dx, dy = label.xyann
        label.xyann = (dx - max(box.x1 - frame.x1, 0.0) * to_points + max(frame.x0 - box.x0, 0.0) * to_points, dy)
        for _ in range(4 * len(labels) + 1):  # enough steps to clear every label placed before
            box = label.get_window_extent(renderer)
            if not any(box.overlaps(other) for other in placed):
                break
            dx, dy = label.xyann
            label.xyann = (dx, dy + direction * (box.height * to_points + 2.0))
        placed.append(label.get_window_extent(renderer))


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
        _mark_events(ax, results, scenario)
        ax.set_xlim(0, float(run.t[-1]))
        if ax.get_legend_handles_labels()[0]:  # nothing to mark without a fault profile or an alarm
            ax.legend(loc="upper right", fontsize=8, framealpha=0.8)
    ax.set_xlabel(f"time (s, centre of the {chain.config.isolation.frame:g} s STFT window, hop {hop * sub:g} s)")
    ax.set_ylabel("frequency (Hz)")
    ax.set_title(f"Time-frequency map of the EA residual of the I element {name}")
    fig.tight_layout()
    return save_figure(fig, path)


def _truth_curve(scenario: Scenario, parameter: str, end: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, end, 2001)
    index = scenario.model.parameter_names.index(parameter)
    return t, scenario.parameters_at(t)[:, index]


def _fit_steps(run: ChainRun, chain: PHMChain, results: dict, parameter: str) -> list[int]:
    """Steps whose extrapolation of ``parameter`` is drawn: the middle prediction of each scored phase,
    else up to 3 of its predictions spread over the run. Only steps at which ``parameter`` was the
    isolated one: another parameter's End of Life is never drawn on its estimate."""
    t = run.t
    chosen: list[float] = []
    phases = (results.get("metrics") or {}).get("eol_phases") or []
    for phase in phases:
        first, last = phase["prediction_times"]
        chosen.append(0.5 * (first + last))
    if not chosen:
        times = [p["t"] for p in results["eol_predictions"] if p["parameter"] == parameter]
        if times:
            chosen = [times[int(k)] for k in np.unique(np.linspace(0, len(times) - 1, min(3, len(times))).round())]
    own = chain.classes.index(parameter)
    candidates = np.flatnonzero([math.isfinite(float(s.eol[0])) and isolated_class(s) == own for s in run.statuses])
    steps = []
    for target in chosen[:3]:
        if len(candidates):
            steps.append(int(candidates[np.argmin(np.abs(t[candidates] - target))]))
    return sorted(set(steps))


def _estimate_title(parameter: str, results: dict, scenario: Scenario | None) -> str:
    """What the estimate figure shows, and whether the parameter is the faulty one."""
    fault = faulty_parameter(scenario)
    isolated = results["estimate"]["parameter"]
    if isolated is None:
        state = (results.get("isolation") or {}).get("state", "no alarm")
        if state == "undecided":
            return f"No parameter isolated at the end (undecided): {parameter}, the one favoured, without End of Life"
        return f"No parameter isolated ({state}): the true {parameter} alone"
    if fault is not None and isolated != fault:
        return f"Estimate of {isolated}, isolated wrongly (the fault is in {fault}): no End of Life of {fault} on it"
    return f"Estimate of {isolated} and End-of-Life extrapolation"


def _draw_extrapolations(ax: Any, run: ChainRun, chain: PHMChain, scenario: Scenario | None, results: dict, parameter: str,
                         ylim: tuple[float, float], end: float) -> tuple[float, list[tuple[Annotation, int]]]:
    """The isolated ``parameter``'s trend fits up to its limits, the predicted End of Life (x) and the true
    trend's (circle); returns the right end of the time axis (s) and the End-of-Life labels (for :func:`place_labels`)."""
    lower, upper = chain.model.safe_limits[parameter]
    right = end
    labels: list[tuple[Annotation, int]] = []
    colors = ["tab:orange", "tab:purple", "tab:brown"]
    # the truth's End of Life only for the faulty parameter
    fault = fault_of(scenario, parameter)
    marked = {"predicted": False, "true": False}
    for k, i in enumerate(_fit_steps(run, chain, results, parameter)):
        prediction = run.statuses[i].end_of_life[0]
        if prediction is None or not math.isfinite(prediction.eol):
            continue
        fit, eol = prediction.fit, prediction.eol
        level = lower if prediction.limit == "lower" else upper
        # the polynomial trend from its first estimate (EA inversion), or the tracked drift from now
        x = np.linspace(prediction.t if fit is None else fit.times[0], eol, 200)
        y = prediction.path(x)
        color = colors[k % len(colors)]
        what = "tracked drift" if fit is None else f"degree-{len(fit.coefficients) - 1} fit"
        ax.plot(x, np.where((y >= ylim[0]) & (y <= ylim[1]), y, np.nan), color=color, lw=1.4, ls="-.",
                label=f"{what} at t = {prediction.t:g} s")
        ax.plot([eol], [level], "x", color=color, ms=10, mew=2.5, zorder=5, label=None if marked["predicted"] else "predicted EoL")
        marked["predicted"] = True
        text = f"EoL {eol:.1f} s"
        if scenario is not None and fault is not None:
            limits = truth_limits(scenario, parameter)
            true_eol = float(fault.profile.trend_end_of_life(np.array([prediction.t]), limits)[0])
            if math.isfinite(true_eol):
                true_level = limits[0 if prediction.limit == "lower" else 1]
                ax.plot([true_eol], [true_level], "o", color=color, ms=13, mfc="none", mew=1.5, zorder=6,
                        label=None if marked["true"] else "true trend EoL")
                marked["true"] = True
                text += f" (true {true_eol:.1f} s)"
                right = max(right, true_eol)
        offset = 8 if prediction.limit == "upper" else -16
        label = ax.annotate(text, (eol, level), textcoords="offset points", xytext=(-150 if eol > 0.8 * right else -40, offset),
                            color=color, fontsize=9, fontweight="bold", bbox=LABEL_BOX)
        labels.append((label, -1 if prediction.limit == "upper" else 1))
        right = max(right, eol)
    return right, labels


def plot_estimate(run: ChainRun, chain: PHMChain, scenario: Scenario | None, path: str | os.PathLike[str],
                  results: dict | None = None) -> Path:
    """Paper Fig 12 for every component: one panel per degradable part (:func:`estimate_figure`)."""
    results = chain_results(run, chain, scenario) if results is None else results
    return save_figure(estimate_figure(run, chain, scenario, results), path)


def _joint(results: dict) -> bool:
    """Whether the run's components come from the chain's per-part health (its joint filter), not its estimator alone."""
    return any(series["degrading"] and series["degrading"][-1] is not None for series in results["components"].values())


def estimate_figure(run: ChainRun, chain: PHMChain, scenario: Scenario | None, results: dict) -> Any:
    """Every component's estimate against its truth and safe limits, with its End of Life.

    With the chain's per-part health (``HealthStatus.parts``): one panel per degradable part, each in its own colour
    and marker: its estimate with +-2 std (results' "components"), the steps where it is named degrading (shaded), its
    truth, its safe limits and its latest End of Life (x at the limit its estimate heads for, with the interval and the
    true trend's); the panel of the isolated (or favoured) parameter also shows the chain's estimator's own estimate of
    it and its End-of-Life extrapolations, as paper Fig 12. Without it, the estimator's one suspect alone
    (:func:`_suspect_figure`). Estimates beyond a panel's range are drawn at its edge (:func:`plot_within`); no two
    End-of-Life labels overprint (:func:`place_labels`)."""
    if not _joint(results):
        return _suspect_figure(run, chain, scenario, results)
    names = list(results["components"])
    end = float(run.t[-1])
    suspect = results["estimate"]["parameter"] or (results.get("isolation") or {}).get("favoured")
    fig, axes = plt.subplots(len(names), 1, figsize=(10, 1.2 + 3.0 * len(names)), sharex=True, squeeze=False)
    right = end
    labels: list[tuple[Any, list[tuple[Annotation, int]]]] = []  # each panel and its End-of-Life labels
    for ax, name in zip(axes[:, 0], names):
        edge, drawn = _draw_component(ax, run, chain, scenario, results, name, name == suspect)
        right = max(right, edge)
        labels.append((ax, drawn))
    right = min(right, 2.0 * end) * 1.02
    for ax, name in zip(axes[:, 0], names):
        if scenario is not None:
            tt, truth = _truth_curve(scenario, name, right)
            ax.plot(tt, np.clip(truth, *ax.get_ylim()), color="k", lw=1.2, label=f"true {name}")
        ax.set_xlim(0, right)
        ax.legend(loc="upper center", fontsize=7.5, ncol=4, framealpha=0.85)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle("Every component: estimate, truth, safe limits and End of Life", fontsize=11)
    fig.tight_layout()
    for ax, drawn in labels:
        place_labels(ax, drawn)
    return fig


def _heading(values: np.ndarray, lower: float, upper: float) -> tuple[str, float]:
    """The limit (its name and value) the recent estimates head for: the sign of their trend over the last 10 steps, the
    nearer limit where they are flat."""
    recent = values[np.isfinite(values)][-10:]
    slope = np.polyfit(np.arange(len(recent)), recent, 1)[0] if len(recent) >= 2 else 0.0
    if slope == 0.0:
        slope = -1.0 if recent[-1] - lower < upper - recent[-1] else 1.0
    return ("lower", lower) if slope < 0 else ("upper", upper)


def _draw_component(ax: Any, run: ChainRun, chain: PHMChain, scenario: Scenario | None, results: dict, name: str,
                    suspect: bool) -> tuple[float, list[tuple[Annotation, int]]]:
    """One component's panel of :func:`estimate_figure`; returns the right end its End of Life needs (s) and its labels."""
    series = results["components"][name]
    color, marker = component_style(chain, name)
    unit = series["unit"]
    lower, upper = series["limits"]
    span = upper - lower
    ylim = (lower - 0.15 * span, upper + 0.45 * span)  # room for the legend above the limits
    t = np.asarray(series["t"], dtype=float)
    value = np.array([np.nan if v is None else v for v in series["value"]], dtype=float)
    std = np.array([np.nan if v is None else v for v in series["std"]], dtype=float)
    named = np.array([bool(v) for v in series["named"]])
    spread = np.isfinite(std)
    if spread.any():
        ax.fill_between(t, np.clip(value - 2 * std, *ylim), np.clip(value + 2 * std, *ylim), where=spread, color=color, alpha=0.2,
                        lw=0, label="+-2 std")
    plot_within(ax, t, value, *ylim, color=color, label=f"estimate of {name}", marker=marker, size=3.0)
    if named.any():
        starts = np.flatnonzero(np.diff(np.concatenate([[0], named.astype(int)])) == 1)
        stops = np.flatnonzero(np.diff(np.concatenate([named.astype(int), [0]])) == -1)
        step = chain.step_time
        for k, (first, last) in enumerate(zip(starts, stops)):
            ax.axvspan(t[first] - step, t[last], color=color, alpha=0.08, lw=0, label="named degrading" if k == 0 else None)
    ax.axhline(lower, color="tab:red", lw=1.0, label=f"safe limits {lower:g} / {upper:g} {unit}".rstrip())
    ax.axhline(upper, color="tab:red", lw=1.0)
    right = float(t[-1])
    labels: list[tuple[Annotation, int]] = []
    if suspect:
        estimate = results["estimate"]
        if estimate["parameter"] is None:
            estimate = estimate_series(run, chain, chain.classes.index(name))
        plot_within(ax, estimate["t"], estimate["value"], *ylim, color="0.45", size=2.5,
                    label=f"estimator's estimate ({'isolated' if results['estimate']['parameter'] else 'favoured, not isolated'})")
        if results["estimate"]["parameter"]:
            right, labels = _draw_extrapolations(ax, run, chain, scenario, results, name, ylim, right)
    rul = np.array([np.nan if v is None else v for v in series["rul"]], dtype=float)
    predicted = np.flatnonzero(np.isfinite(rul))
    if len(predicted):
        i = int(predicted[-1])
        eol = t[i] + rul[i]
        low, high = (t[i] + series[key][i] if series[key][i] is not None else np.nan for key in ("rul_low", "rul_high"))
        limit, level = _heading(value[: i + 1], lower, upper)
        text = f"{name} EoL {eol:.1f} s [{low:.0f}, {high:.0f}] at {t[i]:g} s"
        ax.plot([eol], [level], marker="x", color=color, ms=10, mew=2.5, ls="none", zorder=5, label=f"latest End of Life of {name}")
        if np.isfinite([low, high]).all():
            ax.plot([low, high], [level, level], color=color, lw=4, alpha=0.5, solid_capstyle="butt", label="its interval")
        if scenario is not None and name in scenario.faulty_parameters:
            true_eol = float(scenario.true_end_of_life(np.array([t[i]]))[name][0])
            if math.isfinite(true_eol):
                ax.plot([true_eol], [level], "o", color=color, ms=12, mfc="none", mew=1.5, ls="none", label="true trend EoL")
                text += f" (true {true_eol:.1f} s)"
                right = max(right, true_eol)
        label = ax.annotate(text, (eol, level), textcoords="offset points", xytext=(-60, 8 if limit == "upper" else -16),
                            color=color, fontsize=9, fontweight="bold", bbox=LABEL_BOX)
        labels.append((label, -1 if limit == "upper" else 1))
        right = max(right, eol, high if math.isfinite(high) else eol)
    ax.set_ylim(*ylim)
    ax.set_ylabel(f"{name} ({unit})" if unit else name)
    state = "named degrading" if named.size and named[-1] else "not named degrading"
    ax.set_title(f"{name}: {state} at the end, degrading probability {series['degrading'][-1]:.2f}", fontsize=10)
    ax.grid(alpha=0.3)
    return right, labels


def _suspect_figure(run: ChainRun, chain: PHMChain, scenario: Scenario | None, results: dict) -> Any:
    """Paper Fig 12 of a chain without per-part health: the isolated parameter's estimate vs its truth, the safe limits,
    and the degree-1 extrapolations from a prediction time in each phase up to the limit, with the predicted End of
    Life (x) and the true trend's End of Life (circle).

    The y axis spans the parameter's safe range with margins; estimates beyond it are drawn at its
    edge (:func:`plot_within`). Only End-of-Life predictions made while the drawn parameter was the
    isolated one are drawn. Undecided at the end: the estimate of the parameter the belief favours,
    without End of Life; no alarm: the truth of the faulty parameter alone."""
    estimate = results["estimate"]
    # undecided: the estimate of the parameter the belief favours, as one hypothesis among others
    favoured = (results.get("isolation") or {}).get("favoured")
    if estimate["parameter"] is None and favoured is not None:
        estimate = estimate_series(run, chain, chain.classes.index(favoured))
    parameter = estimate["parameter"] or faulty_parameter(scenario)
    fig, ax = plt.subplots(figsize=(10, 5.5))
    end = float(run.t[-1])
    if parameter is None:
        ax.text(0.5, 0.5, "no parameter isolated", ha="center", transform=ax.transAxes)
        return fig
    unit = chain.model.units.get(parameter, "")
    lower, upper = chain.model.safe_limits[parameter]
    span = upper - lower
    ylim = (lower - 0.15 * span, upper + 0.35 * span)  # room for the legend above the limits
    right = end
    labels: list[tuple[Annotation, int]] = []
    if results["estimate"]["parameter"]:
        right, labels = _draw_extrapolations(ax, run, chain, scenario, results, parameter, ylim, end)
    right = min(right, 2.0 * end) * 1.02
    if scenario is not None:
        tt, truth = _truth_curve(scenario, parameter, right)
        ax.plot(tt, np.clip(truth, *ylim), color="k", lw=1.5, label=f"true {parameter}")
    undecided = results["estimate"]["parameter"] is None
    color, marker = component_style(chain, parameter)
    plot_within(ax, estimate["t"], estimate["value"], *ylim, color="0.45" if undecided else color, marker=marker, size=3.0,
                label=f"estimate of {parameter}" + (" (favoured, not isolated)" if undecided else ""))
    ax.axhline(lower, color="tab:red", lw=1.0, label=f"safe limits {lower:g} / {upper:g} {unit}")
    ax.axhline(upper, color="tab:red", lw=1.0)
    ax.set_ylim(*ylim)
    ax.set_xlim(0, right)
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"{parameter} ({unit})")
    ax.set_title(_estimate_title(parameter, results, scenario))
    ax.grid(alpha=0.3)
    ax.legend(loc="upper center", fontsize=8, ncol=3, framealpha=0.85)
    fig.tight_layout()
    place_labels(ax, labels)
    return fig


def plot_estimate_error(run: ChainRun, chain: PHMChain, scenario: Scenario, path: str | os.PathLike[str],
                        results: dict | None = None) -> Path:
    """Paper Fig 13: estimate minus truth over time; every component's (:func:`_component_errors`) with the chain's
    per-part health, else the suspect's (parameter unit, and % of nominal on the right)."""
    results = chain_results(run, chain, scenario) if results is None else results
    if _joint(results):
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
    _mark_events(ax, results, scenario)
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
    _mark_events(ax, results, scenario)
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
    joint = _joint(results)
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
    _mark_events(ax, results, scenario)
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
        _mark_events(ax, results, scenario, label=False)
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


#: figure name -> the function drawing it
PLOTS: dict[str, Callable[..., Path]] = {
    "time_frequency": plot_time_frequency,
    "estimate": plot_estimate,
    "estimate_error": plot_estimate_error,
    "rul": plot_rul,
    "signals": plot_signals,
}
