"""The estimate figure of a PHM run (paper Fig 12): every component's estimate against its truth and safe limits, with
its End of Life; or, for a chain without per-part health, its one suspect with the End-of-Life extrapolations.

Units: times in s, parameters in their SI unit (``SystemModel.units``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from matplotlib.text import Annotation

from ea_gym.phm import ChainRun, PHMChain
from ea_gym.pyplot import plt
from ea_gym.reporting.drawing import LABEL_BOX, component_style, joint_results, place_labels, plot_within, truth_curve
from ea_gym.reporting.results import estimate_series, fault_of, faulty_parameter, isolated_class, truth_limits
from ea_gym.scenario import Scenario


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


def estimate_figure(run: ChainRun, chain: PHMChain, scenario: Scenario | None, results: dict) -> Any:
    """Every component's estimate against its truth and safe limits, with its End of Life.

    With the chain's per-part health (``HealthStatus.parts``): one panel per degradable part, each in its own colour
    and marker: its estimate with +-2 std (results' "components"), the steps where it is named degrading (shaded), its
    truth, its safe limits and its latest End of Life (x at the limit its estimate heads for, with the interval and the
    true trend's); the panel of the isolated (or favoured) parameter also shows the chain's estimator's own estimate of
    it and its End-of-Life extrapolations, as paper Fig 12. Without it, the estimator's one suspect alone
    (:func:`_suspect_figure`). Estimates beyond a panel's range are drawn at its edge (:func:`plot_within`); no two
    End-of-Life labels overprint (:func:`place_labels`)."""
    if not joint_results(results):
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
            tt, truth = truth_curve(scenario, name, right)
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
        tt, truth = truth_curve(scenario, parameter, right)
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
