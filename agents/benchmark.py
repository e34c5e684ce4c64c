"""Benchmark of maintenance policies on common evaluation seeds: rules, the oracle and trained PPO agents.

``run_benchmark`` tunes the rule-based policies on tuning seeds, evaluates every policy on the same
evaluation seeds (common random numbers: per-seed cost differences are paired), and writes, atomically:

- ``benchmark.json``: per policy the mean episode cost with its 95 % interval (normal approximation,
  mean +- 1.96 sd / sqrt(n)), failures, availability, maintenance actions per episode, the ratio of its
  mean cost to the oracle's, the paired cost difference to the oracle, its obs_mode and tuned parameter,
  and the per-episode records; the seeds, the tuning tables, the skipped policies, the commands;
- ``benchmark.md``: the table sorted by mean cost, the ranking, the value of information, the tuning
  tables and the command that reproduces it;
- ``cost_distribution.png``: each policy's episode costs (box plot, episodes as dots, means marked);
- ``timelines.png`` (and the numbers in ``timelines.json``): one evaluation episode per policy, the
  same seed for all: the degrading component's true and PHM-estimated parameter (position in its safe
  range), the true and estimated RUL, the downtime and the actions.

Policies (environment ``ea_gym/SpringMassDamper-v0``, ``continue_after_failure=True``):

===================  ========  ====================================================================
name                 obs_mode  policy
===================  ========  ====================================================================
``oracle``           oracle    ``Oracle``: replace the truly degrading component, or apply a corrective
                               action on it, when its true RUL falls below the threshold (action and
                               threshold tuned): the reference lower bound
``ppo``              its own   a PPO agent loaded with ``agents.training.load_policy``
``rul_threshold``    phm       ``RulThreshold`` on the PHM chain's diagnosis and RUL (action and
                               threshold tuned)
``corrective_band``  phm       ``CorrectiveBand``: corrective actions on the suspect while its estimate
                               is beyond its component's band toward its limit (bands tuned; the
                               damper's narrower while it is quiet, ``QUIET_BAND``)
``periodic``         sensors   ``Periodic`` block replacement of every component (period tuned)
``run_to_failure``   sensors   ``RunToFailure``: never maintain
===================  ========  ====================================================================

plus any extra trained agents (``ppo_policies``, e.g. ``ppo_sensors`` and ``ppo_oracle``, for the value
of information: the same learner given less or more information).

Seeds: tuning ``0 .. tune_episodes - 1``; evaluation ``100_000 + seed * 10_000 + i`` for episode i;
the training environments of ``agents.training`` start at ``TRAINING_SEED`` = 1000 (1000..4999) and its
validation at ``VALIDATION_SEED`` = 5000, so no evaluation episode was seen in training, validation or
tuning. The environment's dynamics (wear, loads, sensor noise) depend only on the seed and the
actions, not on the obs_mode, so every policy meets the same machines.
"""

from __future__ import annotations

import json
import math
import shlex
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.evaluation import COST_ITEMS, EpisodeStats, evaluate, mean_ci95, tune
from agents.policies import ActionMap, CorrectiveBand, Oracle, Periodic, RulThreshold, RunToFailure
from ea_gym.env import ENV_ID
from ea_gym.files import finite_or_none, json_ready

__all__ = [
    "ENV_ID", "PERIODS", "THRESHOLDS", "BANDS", "QUIET_BAND", "ACTIONS", "DEFAULT_GRIDS", "EVALUATION_SEED_BASE", "EVALUATION_SEED_STRIDE",
    "env_factory", "vector_env_factory", "evaluation_seeds", "tuning_seeds", "paired", "fmt_ci", "fmt_diff", "record_timeline",
    "plot_cost_distribution", "plot_timelines", "markdown", "run_benchmark",
]

#: Periodic's grid of periods (s), the RUL thresholds (s) of RulThreshold and Oracle, CorrectiveBand's bands:
#: the spring's and the mass's band (their estimates are good to 1-2 % of their safe ranges) x the light
#: damper's while it is well excited (6-12 %: it needs the wider margin); while it is quiet, QUIET_BAND.
#: Storage bands of 0.9 fail (0.05 failures per episode on the tuning seeds), 0.7 held the parts further
#: from their limits than needed; damper bands of 0.4 and 0.8 cost more than 0.5-0.7
PERIODS = (20, 40, 60, 80, 120, 160, 240)
THRESHOLDS = (2, 5, 10, 15, 20, 30, 45, 60)
BANDS = tuple({"k": storage, "m": storage, "b": damper} for storage in (0.75, 0.8, 0.85) for damper in (0.5, 0.6, 0.7))
#: CorrectiveBand's band for the damper while its EA over a step is below 0.003 J (its estimate then
#: scatters 18 % of its range, rms): 0.3, better than 0.4 and than none on the 300 tuning episodes
QUIET_BAND = {"b": 0.3}
DEFAULT_GRIDS: dict[str, tuple[Any, ...]] = {
    "oracle": THRESHOLDS, "rul_threshold": THRESHOLDS, "corrective_band": BANDS, "periodic": PERIODS,
}
#: the actions RulThreshold and Oracle are tuned over, each with the whole threshold grid
ACTIONS = ("replace", "corrective")
EVALUATION_SEED_BASE = 100_000
EVALUATION_SEED_STRIDE = 10_000  # evaluation seeds of benchmark seed s: BASE + s * STRIDE + i, i < episodes

#: (label, obs_mode, tuned parameter's name) of the rule-based policies, in evaluation order
RULES = {
    "oracle": ("Oracle (true state)", "oracle", "threshold_s"),
    "rul_threshold": ("RulThreshold (PHM)", "phm", "threshold_s"),
    "corrective_band": ("CorrectiveBand (PHM)", "phm", "band"),
    "periodic": ("Periodic", "sensors", "period_s"),
    "run_to_failure": ("RunToFailure", "sensors", None),
}
_REQUIRED = ("model.zip", "training.json", "vecnormalize.pkl")
_PNG_DPI = 110


def env_factory(obs_mode: str, **env_kwargs: Any) -> Callable[[], Any]:
    """``() -> env``: ``ea_gym/SpringMassDamper-v0`` with ``continue_after_failure=True`` and ``env_kwargs``."""
    import gymnasium as gym

    import ea_gym  # noqa: F401 - registers the environments

    kwargs = {"obs_mode": obs_mode, "continue_after_failure": True, **env_kwargs}
    return lambda: gym.make(ENV_ID, **kwargs)


def vector_env_factory(obs_mode: str, **env_kwargs: Any) -> Callable[[int], Any]:
    """``(n) -> vector env``: ``env_factory``'s environment, n of them batched (``ea_gym.env.vector``)."""
    import gymnasium as gym

    import ea_gym  # noqa: F401 - registers the environments

    kwargs = {"obs_mode": obs_mode, "continue_after_failure": True, **env_kwargs}
    return lambda n: gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


def evaluation_seeds(seed: int, episodes: int) -> range:
    """The benchmark's evaluation seeds: ``100_000 + seed * 10_000 + i`` for i < episodes."""
    if not (isinstance(seed, (int, np.integer)) and seed >= 0):
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    if not (isinstance(episodes, (int, np.integer)) and 1 <= episodes <= EVALUATION_SEED_STRIDE):
        raise ValueError(f"episodes must be an integer in [1, {EVALUATION_SEED_STRIDE}], got {episodes!r}")
    start = EVALUATION_SEED_BASE + int(seed) * EVALUATION_SEED_STRIDE
    return range(start, start + int(episodes))


def tuning_seeds(tune_episodes: int) -> range:
    """The tuning seeds ``0 .. tune_episodes - 1`` (below the training seeds, which start at 1000)."""
    from_training = 1_000  # agents.training.TRAINING_SEED, not imported here: it loads torch
    if not (isinstance(tune_episodes, (int, np.integer)) and 1 <= tune_episodes <= from_training):
        raise ValueError(f"tune_episodes must be an integer in [1, {from_training}], got {tune_episodes!r}")
    return range(int(tune_episodes))


def paired(a: EpisodeStats, b: EpisodeStats) -> dict[str, Any]:
    """Per-seed cost of a minus cost of b: mean and 95 % interval (normal approximation).

    ``clearly_more`` / ``clearly_less``: the interval lies above / below 0 (False when it is undefined,
    with fewer than 2 episodes).
    """
    if not np.array_equal(a.seeds, b.seeds):
        raise ValueError("paired differences need the same seeds")
    mean, low, high = mean_ci95(a.per_episode["cost"] - b.per_episode["cost"])
    return {"mean": mean, "ci95": [low, high], "clearly_more": bool(low > 0), "clearly_less": bool(high < 0)}


def fmt_ci(row: Mapping[str, Any]) -> str:
    """``mean [low, high]`` of a row with ``mean_cost`` and ``ci95`` (just the mean when the interval is None/NaN)."""
    low, high = row["ci95"]
    if low is None or high is None or not (math.isfinite(low) and math.isfinite(high)):
        return f"{row['mean_cost']:.1f}"
    return f"{row['mean_cost']:.1f} [{low:.1f}, {high:.1f}]"


def fmt_diff(d: Mapping[str, Any]) -> str:
    """``+mean [+low, +high]`` of a paired difference (just the mean when the interval is None/NaN)."""
    low, high = d["ci95"]
    if low is None or high is None or not (math.isfinite(low) and math.isfinite(high)):
        return f"{d['mean']:+.1f}"
    return f"{d['mean']:+.1f} [{low:+.1f}, {high:+.1f}]"


def _parameter(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _parameter(v) for k, v in value.items()}
    return int(value) if isinstance(value, (int, float)) and float(value).is_integer() else value


def _value(value: Any) -> str:
    """A tuned value for the tables: a number, or one per component (CorrectiveBand's bands)."""
    if isinstance(value, Mapping):
        return ", ".join(f"{k} {v:g}" for k, v in value.items())
    return f"{value:g}"


# -- one episode, recorded for the timelines ----------------------------------------------------


def record_timeline(policy: Any, obs_mode: str, seed: int, env_kwargs: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Step one episode of ``policy`` on ``obs_mode`` and record what the timelines show.

    The PHM chain's estimates come from a second environment in obs_mode "phm" stepped in lockstep
    with the same seed and the same actions (the dynamics do not depend on the obs_mode; the true
    parameters of the two are checked equal at every step), so a policy that sees no PHM output
    (sensors, oracle) is shown beside what the chain would have estimated on its episode.

    Returns JSON-ready lists over the episode's states (t = 0 after the reset, then after each step):
    ``t`` (s), ``component`` (the degrading one), ``true_position`` and ``estimated_position`` (its
    parameter as a position in its safe range: 0 lower limit, 1 upper; the estimate clipped to
    [-1, 2] by the environment), ``true_rul`` (s, None before the fault arrives), ``rul`` (the chain's
    [point, low, high], s, clipped to [0, rul_max]), ``down`` (machine down); and the events:
    ``actions`` ([t, meaning] of each action carried out, t the time it was given), ``failures``
    ([t, component]), with the episode's ``cost``.
    """
    env_kwargs = dict(env_kwargs or {})
    env = env_factory(obs_mode, **env_kwargs)()
    shadow = env_factory("phm", **env_kwargs)() if obs_mode != "phm" else None
    try:
        base = env.unwrapped
        core = base.core
        components = list(base.maintainable_components)
        limits = {c: base.safe_limits[c] for c in components}
        meanings = list(base.action_meanings)
        dt = float(base.config.step_seconds)
        observation, info = env.reset(seed=int(seed))
        phm_observation, phm_info = (observation, info) if shadow is None else shadow.reset(seed=int(seed))
        record: dict[str, Any] = {
            "seed": int(seed), "obs_mode": obs_mode, "components": components, "rul_max": float(base.config.rul_max),
            "t": [], "component": [], "true_position": [], "estimated_position": [], "true_rul": [], "rul": [],
            "down": [], "actions": [], "failures": [], "cost": 0.0,
        }

        def note(t: float, observation: Mapping[str, Any], phm_observation: Mapping[str, Any], info: Mapping[str, Any]) -> None:
            component = core.wear_components[int(core.wear.faulty[0])]
            low, high = limits[component]
            record["t"].append(t)
            record["component"].append(component)
            record["true_position"].append((info["true_parameters"][component] - low) / (high - low))
            record["estimated_position"].append(float(phm_observation["parameter_estimate"][components.index(component)]))
            record["true_rul"].append(finite_or_none(float(info["true_rul"])))
            record["rul"].append([float(v) for v in phm_observation["rul"]])
            record["down"].append(bool(observation["maintenance_in_progress"][0] > 0.5))

        note(0.0, observation, phm_observation, info)
        state, start, step = None, True, 0
        while True:
            action, state = policy.predict(observation, state=state, episode_start=np.array([start]), deterministic=True)
            start = False
            action = int(np.asarray(action).reshape(-1)[0])
            was_down = bool(observation["maintenance_in_progress"][0] > 0.5)
            observation, _, terminated, truncated, info = env.step(action)
            if shadow is not None:
                phm_observation, _, _, _, phm_info = shadow.step(action)
                if phm_info["true_parameters"] != info["true_parameters"]:
                    raise RuntimeError(f"the phm shadow of the {obs_mode} env diverged at step {step + 1} (seed {seed})")
            else:
                phm_observation = observation
            if action != 0 and not was_down:
                record["actions"].append([step * dt, meanings[action]])
            step += 1
            record["cost"] += float(info["cost"]["total"])
            for event in info["events"]:
                if event.startswith("failure: "):
                    record["failures"].append([step * dt, event.split(" ")[1]])
            note(step * dt, observation, phm_observation, info)
            if terminated or truncated:
                break
        return record
    finally:
        env.close()
        if shadow is not None:
            shadow.close()


# -- figures -----------------------------------------------------------------------------------


def _pyplot():
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
    return save_figure(fig, path, dpi=_PNG_DPI)


_COMPONENT_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2")


def _segments(t: np.ndarray, keys: Sequence[str]):
    """(component, slice) runs of equal component along the episode."""
    start = 0
    for i in range(1, len(keys) + 1):
        if i == len(keys) or keys[i] != keys[start]:
            yield keys[start], slice(start, i)
            start = i


def _spans(t: np.ndarray, mask: np.ndarray):
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
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from ea_gym.files import save_figure

    plt = _pyplot()
    names = sorted(timelines, key=lambda n: rows[n]["mean_cost"] if n in rows else math.inf)
    components = list(next(iter(timelines.values()))["components"])
    color = {c: _COMPONENT_COLORS[i % len(_COMPONENT_COLORS)] for i, c in enumerate(components)}
    finite = [v for n in names for v in timelines[n]["true_rul"] if v is not None]
    rul_max = next(iter(timelines.values()))["rul_max"]
    rul_top = min(rul_max, max(60.0, 1.15 * (np.percentile(finite, 95) if finite else 60.0)))
    fig, axes = plt.subplots(len(names), 2, figsize=(16, 2.5 * len(names) + 1.3), sharex=True, squeeze=False,
                             gridspec_kw={"width_ratios": [1, 1]})
    for r, name in enumerate(names):
        tl, row = timelines[name], rows.get(name, {})
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
        ax_p, ax_r = axes[r]
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
        for at, meaning in tl["actions"]:
            kind, component = meaning.rsplit(" ", 1)
            if kind == "replace":
                ax_p.plot(at, 1.12, marker="v", ms=8, color=color[component], mec="black", mew=0.6, zorder=5, clip_on=False)
                ax_r.axvline(at, color=color[component], lw=0.8, alpha=0.6, zorder=1)
            else:
                ax_p.plot(at, -0.12, marker="|", ms=8, color=color[component], zorder=5, clip_on=False)
        for ft, _ in tl["failures"]:
            ax_p.plot(ft, 1.12, marker="X", ms=9, color="#c0392b", mec="black", mew=0.6, zorder=6, clip_on=False)
        ax_p.set_ylim(-0.2, 1.2)
        ax_r.set_ylim(0, rul_top)
        replacements = sum(1 for _, m in tl["actions"] if m.startswith("replace "))
        correctives = len(tl["actions"]) - replacements
        summary = f"episode cost {tl['cost']:.0f}, {len(tl['failures'])} failure(s), {replacements} replacement(s)"
        if correctives:
            summary += f", {correctives} corrective step(s)"
        label = row.get("label", name)
        ax_p.set_title(f"{name}: {label}, obs_mode {tl['obs_mode']} | {summary}", loc="left", fontsize=10)
        ax_p.set_ylabel("position in\nsafe range")
        ax_r.set_ylabel("RUL (s)")
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
        ax.set_xlim(0, float(np.asarray(next(iter(timelines.values()))["t"])[-1]))
    axes[0, 0].text(0.0, 1.35, "degrading component's parameter: true (solid), PHM estimate (dashed); safe limits at 0 and 1",
                    transform=axes[0, 0].transAxes, fontsize=10, weight="bold")
    axes[0, 1].text(0.0, 1.35, "RUL: true (solid), PHM point (dashed) and interval (band) while it gives one", transform=axes[0, 1].transAxes,
                    fontsize=10, weight="bold")
    handles = [Patch(color=color[c], label=f"component {c}") for c in components] + [
        Line2D([], [], color="0.3", lw=2, label="true"),
        Line2D([], [], color="0.3", lw=1, ls="--", label="PHM estimate"),
        Patch(color="0.4", alpha=0.18, label="PHM RUL interval"),
        Line2D([], [], ls="", marker="v", color="0.5", mec="black", label="replacement (ordered)"),
        Line2D([], [], ls="", marker="|", color="0.3", ms=8, label="corrective step"),
        Line2D([], [], ls="", marker="X", color="#c0392b", mec="black", label="failure (forced replacement)"),
        Patch(color="0.85", label="machine down"),
    ]
    seed = next(iter(timelines.values()))["seed"]
    fig.suptitle(f"One evaluation episode per policy (seed {seed}, the same machine and loads for all)", fontsize=12, y=0.995)
    fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 6), fontsize=9, frameon=False)
    fig.tight_layout(rect=(0, 0.06 if len(names) <= 3 else 0.035, 1, 0.975), h_pad=2.2)
    return save_figure(fig, path, dpi=_PNG_DPI)


# -- the report ----------------------------------------------------------------------------------


def _ratio(row: Mapping[str, Any]) -> str:
    r = row.get("cost_ratio_to_oracle")
    return "n/a" if r is None else f"{r:.2f}"


def _param(row: Mapping[str, Any]) -> str:
    if row.get("parameter") is None:
        return "-"
    unit = " s" if str(row.get("parameter_name", "")).endswith("_s") else ""
    action = f"{row['action']}, " if row.get("action") else ""
    return f"{action}{row['parameter_name'].removesuffix('_s')} = {_value(row['parameter'])}{unit}"


def markdown(result: Mapping[str, Any]) -> str:
    """The benchmark's report: ranking table, skipped policies, value of information, tuning, command."""
    rows = result["policies"]
    seeds = result["seeds"]
    env = result["environment"]
    ranking = result["ranking"]
    lines = [
        "# Maintenance policy benchmark",
        "",
        f"`{env['id']}` with continue_after_failure=True"
        + (f", env_kwargs {env['env_kwargs']}" if env["env_kwargs"] else "")
        + f": horizon {env['horizon']} steps of {env['step_seconds']:g} s. "
        f"{seeds['episodes']} evaluation episodes per policy on the same seeds "
        f"{seeds['evaluation'][0]}..{seeds['evaluation'][1]} (paired: every policy meets the same machines, loads and "
        f"faults); rules tuned on seeds {seeds['tuning'][0]}..{seeds['tuning'][1]}; PPO trained on seeds from "
        f"{seeds['training_from']} and validated on seeds from {seeds['validation_from']}: no evaluation episode was "
        "seen in tuning, training or validation.",
        "",
        "Cost: mean per episode [95 % CI, normal approximation mean ± 1.96 sd/√n]. ×oracle: mean cost / the "
        "oracle's. Δ oracle: paired per-seed cost difference to the oracle [95 % CI]. Failures, maintenance "
        "actions: mean per episode; availability: mean fraction of steps the machine was up.",
        "",
        "| rank | policy | obs_mode | tuned parameter | cost [95 % CI] | ×oracle | Δ oracle [95 % CI] | failures | availability | maintenance actions |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for rank, name in enumerate(ranking, 1):
        row = rows[name]
        lines.append(
            f"| {rank} | **{name}** ({row['label']}) | {row['obs_mode']} | {_param(row)} | {fmt_ci(row)} | {_ratio(row)} | "
            f"{fmt_diff(row['vs_oracle'])} | {row['failures']:.2f} | {row['availability']:.3f} | {row['maintenance_actions']:.1f} |"
        )
    lines += ["", f"Ranking (lowest mean cost first): {' < '.join(ranking)}.", ""]
    if result["skipped"]:
        lines += ["Skipped:", ""]
        lines += [f"- **{name}**: {note}" for name, note in result["skipped"].items()]
        lines.append("")
    lines += ["## Cost breakdown (mean per episode)", "", "| policy | " + " | ".join(i.replace("_", " ") for i in COST_ITEMS) + " |",
              "|---|" + "---|" * len(COST_ITEMS)]
    for name in ranking:
        b = rows[name]["cost_breakdown"]
        lines.append(f"| {name} | " + " | ".join(f"{b[i]:.1f}" for i in COST_ITEMS) + " |")
    lines += ["", "## Value of information", ""]
    voi = result["value_of_information"]
    lines += [
        "The same decision rule (or the same learner) given more information: sensors only → the PHM chain's "
        "diagnosis and RUL → the true state. Per information regime, the best policy of each kind:",
        "",
        "| information (obs_mode) | rule | rule cost [95 % CI] | learned (PPO) | PPO cost [95 % CI] |",
        "|---|---|---|---|---|",
    ]
    for mode, entry in voi["by_obs_mode"].items():
        rule = entry["rule"]
        learned = entry["ppo"]
        rule_text = f"{rule} | {fmt_ci(rows[rule])}" if rule else "- | -"
        ppo_text = " / ".join(learned) + " | " + " / ".join(fmt_ci(rows[n]) for n in learned) if learned else "- | -"
        lines.append(f"| {mode} | {rule_text} | {ppo_text} |")
    lines.append("")
    if voi["gains"]:
        lines += ["Cost saved by the extra information (paired per-seed difference, less information minus more, [95 % CI]):", ""]
        for gain in voi["gains"]:
            lines.append(f"- {gain['kind']}, {gain['from']} → {gain['to']}: {fmt_diff(gain['difference'])} per episode "
                         f"({gain['less']} minus {gain['more']})")
        lines.append("")
    if not any(entry["ppo"] for entry in voi["by_obs_mode"].values()):
        lines += ["No trained PPO agent was evaluated, so the learned column is empty.", ""]
    lines += ["## Tuning (tuning seeds)", ""]
    for name, tuning in result["tuning"].items():
        action = f" ({tuning['action']})" if tuning.get("action") else ""
        lines.append(f"{name} (obs_mode {tuning['obs_mode']}), {tuning['parameter_name']}: best {_value(tuning['best'])}{action}")
        lines += ["", "| value | cost [95 % CI] | failures | availability | maintenance actions |", "|---|---|---|---|---|"]
        for r in tuning["table"]:
            value = f"{r['action']}, {_value(r['parameter'])}" if r.get("action") else _value(r["parameter"])
            lines.append(f"| {value} | {fmt_ci(r)} | {r['failures']:.2f} | {r['availability']:.3f} | {r['maintenance_actions']:.1f} |")
        lines.append("")
    lines += [
        "## Figures",
        "",
        "![episode cost per policy](cost_distribution.png)",
        "",
        f"![one episode per policy, seed {seeds['timeline']}](timelines.png)",
        "",
        f"The timelines show evaluation seed {seeds['timeline']} for every policy (numbers in timelines.json); the PHM "
        "estimates beside the sensors- and oracle-mode policies come from the PHM chain run on the same episode.",
        "",
        "## Reproduce",
        "",
        "```bash",
        result["commands"]["reproduce"],
        "```",
        "",
    ]
    if result["commands"].get("note"):
        lines += [result["commands"]["note"], ""]
    t = result["timings_s"]
    lines += [f"Took {t['total']:.0f} s ({t['total'] / 60:.1f} min) on {result['machine']['platform']}, Python {result['machine']['python']}.", ""]
    return "\n".join(lines)


# -- the benchmark -------------------------------------------------------------------------------


def _ppo_missing(directory: Path | None) -> str | None:
    """Why a PPO directory cannot be loaded (None if it can)."""
    if directory is None:
        return "no PPO directory given"
    directory = Path(directory)
    if not directory.is_dir():
        return f"no trained policy at {_display_path(directory)} (no such directory)"
    missing = [name for name in _REQUIRED if not (directory / name).is_file()]
    if missing:
        return f"no trained policy at {_display_path(directory)} (missing {', '.join(missing)})"
    return None


def _display_path(path: Path) -> str:
    path = Path(path)
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def _default_command(episodes: int, seed: int, out: Path, ppo: Path | None, tune_episodes: int) -> str:
    words = ["ea-gym", "benchmark", "--episodes", str(episodes), "--seed", str(seed), "--out", _display_path(out),
             "--tune-episodes", str(tune_episodes)]
    words += ["--ppo", _display_path(ppo)] if ppo is not None else ["--no-ppo"]
    return shlex.join(words)


def run_benchmark(
    episodes: int,
    seed: int,
    out: Path,
    ppo: Path | None,
    tune_episodes: int = 300,
    progress: bool = True,
    *,
    batch_size: int = 100,
    ppo_policies: Mapping[str, Path] | None = None,
    grids: Mapping[str, Sequence[float]] | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    timeline_seed: int | None = None,
    command: str | None = None,
    command_note: str | None = None,
) -> dict[str, Any]:
    """Tune, evaluate and compare the maintenance policies; write the results to ``out``.

    Args:
        episodes: evaluation episodes per policy (>= 2 for confidence intervals; 1 gives none).
        seed: benchmark seed: evaluation seeds ``100_000 + seed * 10_000 + i``, i < episodes.
        out: output directory (created): benchmark.json, benchmark.md, cost_distribution.png,
            timelines.png, timelines.json.
        ppo: directory of a trained agent (``ea-gym train --out DIR``) evaluated as ``ppo`` on its own
            training obs_mode; None, or a directory without a model, skips it (noted in the outputs).
        tune_episodes: tuning episodes (seeds 0 .. tune_episodes - 1) per grid value.
        progress: progress bars and one line per stage.
        batch_size: the most episodes tuned or evaluated side by side on the batched environment (its
            episodes equal the single environment's bit for bit); the timelines step one environment.
        ppo_policies: more trained agents, name -> directory (e.g. ``{"ppo_sensors": ..., "ppo_oracle": ...}``),
            for the value-of-information comparison; missing ones are skipped with a note.
        grids: tuning grids by policy (``"oracle"``, ``"rul_threshold"``: thresholds in s, tried with each
            of ``ACTIONS``; ``"corrective_band"``: bands, each a number or a mapping per component;
            ``"periodic"``: periods in s); missing keys take ``DEFAULT_GRIDS``.
        env_kwargs: more keyword arguments of the environment (e.g. ``{"horizon": 100}``), for every
            policy, the tuning and the timelines.
        timeline_seed: the episode of the timelines (default the first evaluation seed).
        command: the command line that reproduces this run, written into the outputs (default the
            equivalent ``ea-gym benchmark`` command).
        command_note: a sentence written under the command in the markdown.

    Returns:
        The dictionary written to ``benchmark.json``.
    """
    import platform

    started = time.perf_counter()
    out = Path(out)
    env_kwargs = dict(env_kwargs or {})
    for reserved in ("obs_mode", "continue_after_failure"):
        if reserved in env_kwargs:
            raise ValueError(f"env_kwargs must not set {reserved!r}: the benchmark sets it")
    evaluation = evaluation_seeds(seed, episodes)
    tuning = tuning_seeds(tune_episodes)
    grids = {**DEFAULT_GRIDS, **{k: tuple(v) for k, v in (grids or {}).items()}}
    unknown = sorted(set(grids) - set(DEFAULT_GRIDS))
    if unknown:
        raise ValueError(f"grids: unknown policies {unknown}; tuned policies are {sorted(DEFAULT_GRIDS)}")
    for name, grid in grids.items():
        if not grid:
            raise ValueError(f"grids[{name!r}] must hold at least one value")
    extra = {str(k): (None if v is None else Path(v)) for k, v in (ppo_policies or {}).items()}
    clash = sorted(set(extra) & {"ppo", *RULES})
    if clash:
        raise ValueError(f"ppo_policies: the names {clash} are taken by the benchmark's own policies")
    timeline_seed = evaluation.start if timeline_seed is None else int(timeline_seed)
    if command is None:
        command = _default_command(episodes, seed, out, ppo, tune_episodes)
        if extra or grids != DEFAULT_GRIDS or env_kwargs:
            command_note = command_note or (
                "The command reproduces the defaults only: this run also used "
                + ", ".join(f"{k}={v}" for k, v in (("ppo_policies", {k: str(v) for k, v in extra.items()}),
                                                    ("grids", {k: list(v) for k, v in grids.items()}),
                                                    ("env_kwargs", env_kwargs)) if v)
                + " (agents.benchmark.run_benchmark)."
            )

    def say(text: str) -> None:
        if progress:
            print(text, flush=True)

    timings: dict[str, float] = {}

    def timed(label: str, fn: Callable[[], Any]) -> Any:
        t = time.perf_counter()
        value = fn()
        timings[label] = time.perf_counter() - t
        say(f"  {label}: {timings[label]:.1f} s")
        return value

    make = lambda mode: vector_env_factory(mode, **env_kwargs)  # noqa: E731
    probe = env_factory("oracle", **env_kwargs)()
    try:
        actions = ActionMap.from_env(probe)
        base = probe.unwrapped
        environment = {"id": ENV_ID, "continue_after_failure": True, "env_kwargs": json_ready(env_kwargs),
                       "horizon": int(base.config.horizon), "step_seconds": float(base.config.step_seconds),
                       "action_meanings": list(actions.action_meanings)}
    finally:
        probe.close()

    # tuning
    say(f"tuning on seeds {tuning.start}..{tuning.stop - 1}")
    tuned: dict[str, Any] = {}
    tables: dict[str, Any] = {}
    builders = {"oracle": lambda v, a: Oracle(actions, v, action=a), "rul_threshold": lambda v, a: RulThreshold(actions, v, action=a),
                "corrective_band": lambda v, a: CorrectiveBand(actions, v, quiet_band=QUIET_BAND), "periodic": lambda v, a: Periodic(actions, v)}
    for name in DEFAULT_GRIDS:
        label, mode, parameter_name = RULES[name]
        grid = [_parameter(v) for v in grids[name]]
        candidates = []  # (mean cost, value, action) of the best value per action
        rows = []
        for action in ACTIONS if name in ("oracle", "rul_threshold") else (None,):
            best, table = timed(
                f"tune {name}" + (f" ({action})" if action else ""),
                lambda name=name, grid=grid, mode=mode, action=action: tune(lambda v: builders[name](v, action), grid, make(mode), tuning, progress, batch_size),
            )
            candidates.append((min(r["mean_cost"] for r in table), best, action))
            rows += [{"action": action, **r} if action else r for r in table]
        _, best, action = min(candidates, key=lambda c: c[0])  # ties go to the earlier action
        tuned[name] = (best, action)
        tables[name] = {"obs_mode": mode, "parameter_name": parameter_name, "grid": grid, "best": best, "action": action, "table": rows}

    # the policies
    plan: dict[str, dict[str, Any]] = {}  # name -> policy, obs_mode, label, parameter, parameter_name, extra
    for name in RULES:
        label, mode, parameter_name = RULES[name]
        value, action = tuned.get(name, (None, None))
        policy = builders[name](value, action) if name in tuned else RunToFailure(actions)
        plan[name] = {"policy": policy, "obs_mode": mode, "label": label, "parameter": value, "action": action,
                      "parameter_name": parameter_name, "kind": "rule"}
    skipped: dict[str, str] = {}
    learned = {"ppo": None if ppo is None else Path(ppo), **extra}
    for name, directory in learned.items():
        why = _ppo_missing(directory)
        if why is not None:
            skipped[name] = why + "; evaluated nothing"
            say(f"skipping {name}: {why}")
            continue
        from agents.training import load_policy

        policy = load_policy(directory)
        summary = json.loads((directory / "training.json").read_text())
        run = summary.get("run", {})
        algo = str(run.get("algo", "ppo")).upper()
        plan[name] = {"policy": policy, "obs_mode": policy.obs_mode, "label": f"{algo} agent, {directory.name}",
                      "parameter": None, "parameter_name": None, "kind": "ppo",
                      "extra": {"directory": _display_path(directory), "training": json_ready(run),
                                "training_wall_time_s": summary.get("wall_time_s"),
                                "policy": f"{algo} from {_display_path(directory)} (obs_mode {policy.obs_mode!r})"}}

    # evaluation (and one timeline each)
    say(f"evaluating on seeds {evaluation.start}..{evaluation.stop - 1}")
    stats: dict[str, EpisodeStats] = {}
    timelines: dict[str, dict[str, Any]] = {}
    order = ["oracle", "ppo", "rul_threshold", "corrective_band", "periodic", "run_to_failure", *extra]
    order = [n for n in order if n in plan]
    for name in order:
        entry = plan[name]

        def run_policy(entry=entry, name=name) -> EpisodeStats:
            return evaluate(entry["policy"], make(entry["obs_mode"]), evaluation, progress, description=name, batch_size=batch_size)

        def run_timeline(entry=entry) -> dict[str, Any]:
            return record_timeline(entry["policy"], entry["obs_mode"], timeline_seed, env_kwargs)

        if entry["kind"] == "ppo":
            from ea_gym.threads import single_threaded_torch

            with single_threaded_torch():
                stats[name] = timed(f"evaluate {name}", run_policy)
                timelines[name] = timed(f"timeline {name}", run_timeline)
        else:
            stats[name] = timed(f"evaluate {name}", run_policy)
            timelines[name] = timed(f"timeline {name}", run_timeline)

    oracle_cost = stats["oracle"].mean_cost
    rows: dict[str, dict[str, Any]] = {}
    for name in order:
        entry, s = plan[name], stats[name]
        row = s.to_dict()
        ratio = s.mean_cost / oracle_cost if oracle_cost != 0 else math.inf
        row = {
            "label": entry["label"],
            "obs_mode": entry["obs_mode"],
            "kind": entry["kind"],
            "mean_cost": row.pop("mean_cost"),
            "ci95": row.pop("ci95"),
            "failures": row.pop("failures"),
            "availability": row.pop("availability"),
            "maintenance_actions": row.pop("maintenance_actions"),
            "cost_ratio_to_oracle": finite_or_none(ratio),
            "vs_oracle": json_ready(paired(s, stats["oracle"])),
            "parameter": entry["parameter"],
            "action": entry.get("action"),
            "parameter_name": entry["parameter_name"],
            **row,
            **entry.get("extra", {}),
        }
        rows[name] = row
    ranking = sorted(rows, key=lambda n: rows[n]["mean_cost"])
    for rank, name in enumerate(ranking, 1):
        rows[name]["rank"] = rank

    # value of information: per obs_mode the rule and the learned agents; paired gains between regimes
    phm_rule = min(("rul_threshold", "corrective_band"), key=lambda n: stats[n].mean_cost)
    rule_of = {"sensors": "periodic", "phm": phm_rule, "oracle": "oracle"}
    by_mode = {mode: {"rule": rule_of[mode], "ppo": [n for n in order if plan[n]["kind"] == "ppo" and plan[n]["obs_mode"] == mode]}
               for mode in ("sensors", "phm", "oracle")}
    gains = []
    for less, more in (("sensors", "phm"), ("phm", "oracle"), ("sensors", "oracle")):
        pairs = [("rule", by_mode[less]["rule"], by_mode[more]["rule"])]
        if by_mode[less]["ppo"] and by_mode[more]["ppo"]:
            pairs.append(("PPO", by_mode[less]["ppo"][0], by_mode[more]["ppo"][0]))
        for kind, a, b in pairs:
            gains.append({"kind": kind, "from": less, "to": more, "less": a, "more": b,
                          "difference": json_ready(paired(stats[a], stats[b]))})

    from agents.training import TRAINING_SEED, VALIDATION_SEED  # loads torch: imported only here
    from ea_gym.files import write_json, write_text

    out.mkdir(parents=True, exist_ok=True)
    rows = json_ready(rows)
    timed("figures", lambda: (plot_cost_distribution(rows, out / "cost_distribution.png"), plot_timelines(timelines, rows, out / "timelines.png")))
    write_json(out / "timelines.json", json_ready(timelines))
    total = time.perf_counter() - started
    timings["total"] = total

    result = {
        "policies": rows,
        "ranking": ranking,
        "skipped": skipped,
        "seeds": {
            "episodes": len(evaluation),
            "evaluation": [evaluation.start, evaluation.stop - 1],
            "evaluation_rule": f"{EVALUATION_SEED_BASE} + seed * {EVALUATION_SEED_STRIDE} + i, i < episodes",
            "benchmark_seed": int(seed),
            "tuning": [tuning.start, tuning.stop - 1],
            "training_from": TRAINING_SEED,
            "validation_from": VALIDATION_SEED,
            "timeline": timeline_seed,
        },
        "commands": {"reproduce": command, "note": command_note},
        "environment": environment,
        "tuning": json_ready(tables),
        "value_of_information": {"by_obs_mode": by_mode, "gains": gains},
        "ci_method": "normal approximation: mean +- 1.96 sd / sqrt(n), sd with ddof=1 (costs and paired differences)",
        "timings_s": timings,
        "machine": {"python": platform.python_version(), "platform": platform.platform(), "numpy": np.__version__},
    }
    result = json_ready(result)
    write_json(out / "benchmark.json", result)
    write_text(out / "benchmark.md", markdown(result))
    say(f"wrote {out}/benchmark.json, benchmark.md, cost_distribution.png, timelines.png in {total:.0f} s")
    return result
