"""Evaluating the benchmark's policies on the common evaluation seeds, and comparing them paired by seed."""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from agents.benchmark.batches import evaluate_side_by_side
from agents.benchmark.runners import BatchRunner, LocalRunner
from agents.benchmark.settings import RULES, display_path
from agents.benchmark.stopwatch import Stopwatch
from agents.benchmark.timelines import record_timeline
from agents.benchmark.tuning import RuleBuilder
from agents.conventions import AGENT_FILES, SUMMARY_FILE, pickled
from agents.evaluation import EpisodeStats, mean_ci95
from agents.policies import ActionMap, RunToFailure
from ea_gym.files import finite_or_none, json_ready, refuse_links

__all__ = ["EVALUATION_ORDER", "paired", "agent_missing", "plan_policies", "evaluate_policies", "policy_rows", "value_of_information"]

#: the order the policies are evaluated and listed in (the extra trained agents follow)
EVALUATION_ORDER = ("oracle", "ppo", "rul_threshold", "corrective_band", "periodic", "run_to_failure")


def paired(a: EpisodeStats, b: EpisodeStats) -> dict[str, Any]:
    """Per-seed cost of a minus cost of b: mean and 95 % interval (normal approximation).

    ``clearly_more`` / ``clearly_less``: the interval lies above / below 0 (False when it is undefined,
    with fewer than 2 episodes).
    """
    if not np.array_equal(a.seeds, b.seeds):
        raise ValueError("paired differences need the same seeds")
    mean, low, high = mean_ci95(a.per_episode["cost"] - b.per_episode["cost"])
    return {"mean": mean, "ci95": [low, high], "clearly_more": bool(low > 0), "clearly_less": bool(high < 0)}


def agent_missing(directory: Path | None) -> str | None:
    """Why a trained agent's directory cannot be loaded (None if it can); ValueError for one holding a symbolic link,
    which is refused rather than skipped."""
    if directory is None:
        return "no PPO directory given"
    directory = Path(directory)
    if not directory.is_dir():
        return f"no trained policy at {display_path(directory)} (no such directory)"
    refuse_links(directory, "as an agent")
    missing = [name for name in AGENT_FILES if not (directory / name).is_file()]
    if missing and pickled(directory) is None:  # stable-baselines3's files: loaded, or refused, by load_policy
        return f"no trained policy at {display_path(directory)} (missing {', '.join(missing)})"
    return None


def plan_policies(
    tuned: Mapping[str, tuple[Any, str | None]],
    builders: Mapping[str, RuleBuilder],
    actions: ActionMap,
    learned: Mapping[str, Path | None],
    say: Callable[[str], None],
    trust_pickle: bool = False,
) -> tuple[dict[str, dict[str, Any]], dict[str, str]]:
    """The policies to evaluate, name -> policy, obs_mode, label, parameter, action, parameter_name, kind
    (and, for trained agents, extra), and the skipped agents, name -> why. ``trust_pickle``: see
    ``agents.training.load_policy``."""
    plan: dict[str, dict[str, Any]] = {}
    for name in RULES:
        label, mode, parameter_name = RULES[name]
        value, action = tuned.get(name, (None, None))
        policy = builders[name](value, action) if name in tuned else RunToFailure(actions)
        plan[name] = {"policy": policy, "obs_mode": mode, "label": label, "parameter": value, "action": action,
                      "parameter_name": parameter_name, "kind": "rule"}
    skipped: dict[str, str] = {}
    for name, directory in learned.items():
        why = agent_missing(directory)
        if why is not None:
            skipped[name] = why + "; evaluated nothing"
            say(f"skipping {name}: {why}")
            continue
        assert directory is not None  # agent_missing says why otherwise
        plan[name] = _plan_agent(Path(directory), trust_pickle)
    return plan, skipped


def _plan_agent(directory: Path, trust_pickle: bool) -> dict[str, Any]:
    """An agent directory as a ``PortableAgent`` (it travels to Ray workers); stable-baselines3's files, when
    trusted, as ``load_policy`` loads them (they stay in this process: ``runners.runner_for``)."""
    from agents.portable_agent import PortableAgent  # loads torch: imported only when an agent is evaluated
    from agents.training import load_policy

    policy = load_policy(directory, trust_pickle=True) if trust_pickle and pickled(directory) else PortableAgent(directory)
    summary = json.loads((directory / SUMMARY_FILE).read_text())
    run = summary.get("run", {})
    algo = str(run.get("algo", "ppo")).upper()
    return {"policy": policy, "obs_mode": policy.obs_mode, "label": f"{algo} agent, {directory.name}",
            "parameter": None, "parameter_name": None, "kind": "ppo",
            "extra": {"directory": display_path(directory), "training": json_ready(run),
                      "training_wall_time_s": summary.get("wall_time_s"),
                      "policy": f"{algo} from {display_path(directory)} (obs_mode {policy.obs_mode!r})"}}


def evaluate_policies(
    plan: Mapping[str, Mapping[str, Any]],
    order: list[str],
    make: Callable[[str], Any],
    seeds: range,
    timeline_seed: int,
    env_kwargs: Mapping[str, Any],
    stopwatch: Stopwatch,
    max_envs: int,
    runner: BatchRunner | None = None,
) -> tuple[dict[str, EpisodeStats], dict[str, dict[str, Any]]]:
    """Every planned policy on the evaluation ``seeds`` (the policies of one obs_mode side by side on one
    vector environment, ``batches.evaluate_side_by_side``), then one timeline episode each, in ``order``;
    ``runner`` runs both (with Ray, the timelines side by side too)."""
    stats: dict[str, EpisodeStats] = {}
    for mode in dict.fromkeys(plan[name]["obs_mode"] for name in order):
        names = [name for name in order if plan[name]["obs_mode"] == mode]

        def run(names: list[str] = names, mode: str = mode) -> Mapping[Any, EpisodeStats]:
            return evaluate_side_by_side({name: plan[name]["policy"] for name in names}, make(mode), seeds, stopwatch.progress, max_envs,
                                         description=f"evaluate {mode}", runner=runner)

        stats.update(stopwatch.timed(f"evaluate {mode} ({', '.join(names)})", run))
    episodes = [partial(record_timeline, plan[name]["policy"], plan[name]["obs_mode"], timeline_seed, env_kwargs) for name in order]
    timelines = stopwatch.timed(f"timelines ({len(order)} episodes)", lambda: (runner or LocalRunner()).run(episodes))
    return {name: stats[name] for name in order}, dict(zip(order, timelines))


def policy_rows(
    plan: Mapping[str, Mapping[str, Any]], order: list[str], stats: Mapping[str, EpisodeStats],
) -> tuple[dict[str, dict[str, Any]], list[str]]:
    """benchmark.json's row per policy (ranked: ``rank`` 1 the lowest mean cost) and the ranking."""
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
    return rows, ranking


def value_of_information(plan: Mapping[str, Mapping[str, Any]], order: list[str], stats: Mapping[str, EpisodeStats]) -> dict[str, Any]:
    """Per obs_mode the best rule and the trained agents; the paired gains of each step up in information."""
    phm_rule = min(("rul_threshold", "corrective_band"), key=lambda n: stats[n].mean_cost)
    rule_of = {"sensors": "periodic", "phm": phm_rule, "oracle": "oracle"}
    by_mode: dict[str, dict[str, Any]] = {
        mode: {"rule": rule_of[mode], "ppo": [n for n in order if plan[n]["kind"] == "ppo" and plan[n]["obs_mode"] == mode]}
        for mode in ("sensors", "phm", "oracle")}
    gains = []
    for less, more in (("sensors", "phm"), ("phm", "oracle"), ("sensors", "oracle")):
        pairs = [("rule", by_mode[less]["rule"], by_mode[more]["rule"])]
        if by_mode[less]["ppo"] and by_mode[more]["ppo"]:
            pairs.append(("PPO", by_mode[less]["ppo"][0], by_mode[more]["ppo"][0]))
        for kind, a, b in pairs:
            gains.append({"kind": kind, "from": less, "to": more, "less": a, "more": b,
                          "difference": json_ready(paired(stats[a], stats[b]))})
    return {"by_obs_mode": by_mode, "gains": gains}
