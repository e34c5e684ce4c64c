"""The benchmark's figures: each policy's episode costs, and one episode per policy over time."""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ea_gym.env.events import ActionKind, parse_action

__all__ = ["plot_cost_distribution", "plot_timelines"]

#: resolution of the figures (dots per inch)
PNG_DPI = 110


def _pyplot() -> Any:
    from ea_gym.pyplot import plt

    return plt


def plot_cost_distribution(rows: Mapping[str, Mapping[str, Any]], path: Path) -> Path:
    """Box plot of each policy's episode costs, best (lowest mean) on top, episodes as dots, means as diamonds."""
    from ea_gym.files import save_figure

    plt = _pyplot()
    names = sorted(rows, key=lambda n: rows[n]["mean_cost"])
    costs = [np.asarray(rows[n]["per_episode"]["cost"], dtype=float) for n in names]
    positions = np.arange(len(names))[::-1]  # the best on top
    fig, ax = plt.subplots(figsize=(10, 1.2 + 0.75 * len(names)))
    import matplotlib

    horizontal = {"orientation": "horizontal"} if tuple(map(int, matplotlib.__version__.split(".")[:2])) >= (3, 10) else {"vert": False}
    ax.boxplot(costs, positions=positions, **horizontal, widths=0.55, showfliers=False, patch_artist=True,
               boxprops={"facecolor": "#dde6f2", "edgecolor": "#44546a"}, medianprops={"color": "#44546a"},
               whiskerprops={"color": "#44546a"}, capprops={"color": "#44546a"})
    jitter = np.random.default_rng(0)  # fixed: the figure is reproducible
    for y, values in zip(positions, costs):
        ax.scatter(values, y + jitter.uniform(-0.18, 0.18, values.size), s=10, color="#44546a", alpha=0.45, linewidths=0, zorder=3)
    means = [rows[n]["mean_cost"] for n in names]
    ax.scatter(means, positions, marker="D", s=55, color="#c0392b", edgecolor="white", zorder=4, label="mean")
    xmax = max(float(np.max(c)) for c in costs)

    def tick(name: str) -> str:
        row = rows[name]
        ratio = row.get("cost_ratio_to_oracle")
        return f"{name} ({row['obs_mode']})\nmean {row['mean_cost']:.0f}" + (f", {ratio:.2f}x oracle" if ratio is not None else "")

    ax.set_yticks(positions, [tick(n) for n in names], fontsize=9)
    ax.set_xlim(0, xmax * 1.05 if xmax > 0 else 1)
    ax.set_xlabel("episode cost (sum of maintenance, failure and lost-production costs)")
    n = len(costs[0])
    ax.set_title(f"Cost per episode over {n} evaluation episodes (same seeds for every policy)")
    ax.grid(axis="x", alpha=0.3)
    ax.legend(loc="best", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path, dpi=PNG_DPI)


_COMPONENT_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2")


def _segments(t: np.ndarray, keys: Sequence[str]) -> Iterator[tuple[str, slice]]:
    """(component, slice) runs of equal component along the episode."""
    start = 0
    for i in range(1, len(keys) + 1):
        if i == len(keys) or keys[i] != keys[start]:
            yield keys[start], slice(start, i)
            start = i


def _spans(t: np.ndarray, mask: np.ndarray) -> Iterator[tuple[float, float]]:
    """(t0, t1) intervals where mask holds (each sample covers [t - dt, t])."""
    dt = float(t[1] - t[0]) if len(t) > 1 else 1.0
    i = 0
    while i < len(mask):
        if mask[i]:
            j = i
            while j + 1 < len(mask) and mask[j + 1]:
                j += 1
            yield t[i] - dt, t[j]
            i = j + 1
        else:
            i += 1


def plot_timelines(timelines: Mapping[str, Mapping[str, Any]], rows: Mapping[str, Mapping[str, Any]], path: Path) -> Path:
    """One row per policy (sorted by mean cost): the degrading component's parameter and the RUL of one episode."""
    from ea_gym.files import save_figure

    plt = _pyplot()
    names = sorted(timelines, key=lambda n: rows[n]["mean_cost"] if n in rows else math.inf)
    first = next(iter(timelines.values()))
    components = list(first["components"])
    color = {c: _COMPONENT_COLORS[i % len(_COMPONENT_COLORS)] for i, c in enumerate(components)}
    finite = [v for n in names for v in timelines[n]["true_rul"] if v is not None]
    rul_max = first["rul_max"]
    rul_top = min(rul_max, max(60.0, 1.15 * (np.percentile(finite, 95) if finite else 60.0)))
    fig, axes = plt.subplots(len(names), 2, figsize=(16, 2.5 * len(names) + 1.3), sharex=True, squeeze=False,
                             gridspec_kw={"width_ratios": [1, 1]})
    for r, name in enumerate(names):
        _plot_timeline(axes[r], name, timelines[name], rows.get(name, {}), color, rul_max, rul_top)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
        ax.set_xlim(0, float(np.asarray(first["t"])[-1]))
    axes[0, 0].text(0.0, 1.35, "degrading component's parameter: true (solid), PHM estimate (dashed); safe limits at 0 and 1",
                    transform=axes[0, 0].transAxes, fontsize=10, weight="bold")
    axes[0, 1].text(0.0, 1.35, "RUL: true (solid), PHM point (dashed) and interval (band) while it gives one", transform=axes[0, 1].transAxes,
                    fontsize=10, weight="bold")
    handles = _timeline_legend(components, color)
    fig.suptitle(f"One evaluation episode per policy (seed {first['seed']}, the same machine and loads for all)", fontsize=12, y=0.995)
    fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 6), fontsize=9, frameon=False)
    fig.tight_layout(rect=(0, 0.06 if len(names) <= 3 else 0.035, 1, 0.975), h_pad=2.2)
    return save_figure(fig, path, dpi=PNG_DPI)


def _plot_timeline(axes: Any, name: str, tl: Mapping[str, Any], row: Mapping[str, Any], color: Mapping[str, str],
                   rul_max: float, rul_top: float) -> None:
    """One policy's row: its parameter positions (left) and RULs (right), downtime shaded, events marked."""
    t = np.asarray(tl["t"], dtype=float)
    keys = tl["component"]
    true_pos = np.asarray(tl["true_position"], dtype=float)
    est_pos = np.clip(np.asarray(tl["estimated_position"], dtype=float), -0.2, 1.2)
    true_rul = np.array([np.nan if v is None else v for v in tl["true_rul"]], dtype=float)
    rul = np.asarray(tl["rul"], dtype=float)
    down = np.asarray(tl["down"], dtype=bool)
    # no PHM output while the machine is down (the chain restarts); an RUL at rul_max is "no prognosis"
    est_pos[down] = np.nan
    rul[down | (rul[:, 0] >= rul_max)] = np.nan
    ax_p, ax_r = axes
    for ax in (ax_p, ax_r):
        for t0, t1 in _spans(t, down):
            ax.axvspan(t0, t1, color="0.85", lw=0, zorder=0)
        for ft, _ in tl["failures"]:
            ax.axvline(ft, color="#c0392b", lw=1.2, ls="-", alpha=0.8, zorder=1)
        ax.grid(alpha=0.25)
    for component, s in _segments(t, keys):
        ax_p.plot(t[s], true_pos[s], color=color[component], lw=2.0, zorder=3)
        ax_p.plot(t[s], est_pos[s], color=color[component], lw=1.0, ls="--", alpha=0.85, zorder=2)
        ax_r.plot(t[s], true_rul[s], color=color[component], lw=2.0, zorder=3)
    ax_r.fill_between(t, np.minimum(rul[:, 1], rul_top), np.minimum(rul[:, 2], rul_top), color="0.4", alpha=0.18, lw=0, zorder=1)
    ax_r.plot(t, np.minimum(rul[:, 0], rul_top), color="0.25", lw=1.0, ls="--", marker=".", ms=2.5, zorder=2)
    for level in (0.0, 1.0):
        ax_p.axhline(level, color="#c0392b", lw=0.8, ls=":")
    threshold = row.get("parameter") if row.get("parameter_name") == "threshold_s" else None
    if threshold is not None:
        ax_r.axhline(threshold, color="#8e44ad", lw=0.9, ls=":", zorder=2)
        ax_r.text(0.995, threshold, f"threshold {threshold:g} s", color="#8e44ad", fontsize=8, va="bottom", ha="right",
                  transform=ax_r.get_yaxis_transform())
    _mark_events(ax_p, ax_r, tl, color)
    ax_p.set_ylim(-0.2, 1.2)
    ax_r.set_ylim(0, rul_top)
    ax_p.set_title(f"{name}: {row.get('label', name)}, obs_mode {tl['obs_mode']} | {_episode_summary(tl)}", loc="left", fontsize=10)
    ax_p.set_ylabel("position in\nsafe range")
    ax_r.set_ylabel("RUL (s)")


def _mark_events(ax_p: Any, ax_r: Any, tl: Mapping[str, Any], color: Mapping[str, str]) -> None:
    """Replacements (triangles), corrective steps (ticks) and failures (crosses) above and below the parameter
    plot; actions of other kinds are not marked."""
    for at, meaning in tl["actions"]:
        action = parse_action(meaning)
        if action.kind == ActionKind.REPLACE:
            tint = color[str(action.component)]
            ax_p.plot(at, 1.12, marker="v", ms=8, color=tint, mec="black", mew=0.6, zorder=5, clip_on=False)
            ax_r.axvline(at, color=tint, lw=0.8, alpha=0.6, zorder=1)
        elif action.kind == ActionKind.CORRECTIVE:
            ax_p.plot(at, -0.12, marker="|", ms=8, color=color[str(action.component)], zorder=5, clip_on=False)
    for ft, _ in tl["failures"]:
        ax_p.plot(ft, 1.12, marker="X", ms=9, color="#c0392b", mec="black", mew=0.6, zorder=6, clip_on=False)


def _episode_summary(tl: Mapping[str, Any]) -> str:
    kinds = [parse_action(meaning).kind for _, meaning in tl["actions"]]
    replacements, correctives = kinds.count(ActionKind.REPLACE), kinds.count(ActionKind.CORRECTIVE)
    summary = f"episode cost {tl['cost']:.0f}, {len(tl['failures'])} failure(s), {replacements} replacement(s)"
    if correctives:
        summary += f", {correctives} corrective step(s)"
    return summary


def _timeline_legend(components: Sequence[str], color: Mapping[str, str]) -> list[Any]:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    return [Patch(color=color[c], label=f"component {c}") for c in components] + [
        Line2D([], [], color="0.3", lw=2, label="true"),
        Line2D([], [], color="0.3", lw=1, ls="--", label="PHM estimate"),
        Patch(color="0.4", alpha=0.18, label="PHM RUL interval"),
        Line2D([], [], ls="", marker="v", color="0.5", mec="black", label="replacement (ordered)"),
        Line2D([], [], ls="", marker="|", color="0.3", ms=8, label="corrective step"),
        Line2D([], [], ls="", marker="X", color="#c0392b", mec="black", label="failure (forced replacement)"),
        Patch(color="0.85", label="machine down"),
    ]
