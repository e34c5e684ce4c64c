"""Where a maintenance policy's cost comes from, per fault type, on the benchmark's evaluation seeds.

What it measures
    Each policy runs the benchmark's evaluation episodes (seeds 100000 on, ``continue_after_failure=True``,
    deterministic actions) side by side on one vector environment. Per episode it sums the cost items
    (corrective, replacement, failure, lost production) and counts the corrective steps, replacements and
    failures on the faulty component (the one whose fault was drawn; a new fault is drawn when it is
    replaced or fails) and on the others, and orders given while the machine was down (ignored by the
    environment). The episodes are grouped by the component of their first fault. It also reports the
    true wear (0 at nominal, 1 at the safe limit) of the corrected part after each corrective step, and
    what was being done on the step of each failure: carrying on, or a corrective action (which keeps its
    direction while continued, so a run of corrective steps can carry a part through nominal toward its
    other limit).

Usage (from the repository root)
    python experiments/studies/from_scratch_diagnosis.py AGENT_DIR... [--rule] [--episodes N] [--out FILE.json] [--smoke]

    ``--rule`` adds RulThreshold (corrective, 5 s: the benchmark's tuned setting) for comparison.
    ``--smoke``: the committed agent agents/data/ppo_phm and the rule on 2 episodes.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))  # this checkout's ea_gym, agents and experiments.common, installed or not

import ea_gym  # noqa: F401 - registers the environments
from agents.benchmark.settings import evaluation_seeds
from agents.policies import RulThreshold
from agents.shaping import true_wear
from agents.training import load_policy
from ea_gym.env.events import ActionKind, CorrectiveStep, Failure, Replacement, parse_action, parse_event
from ea_gym.threads import single_threaded_torch
from experiments.common import parse_with_smoke

#: the smoke run: the committed agent and the rule on two episodes, nothing written unless --out says where
SMOKE = {"agents": [ROOT / "agents" / "data" / "ppo_phm"], "rule": True, "episodes": 2, "out": None}
COUNTS = ("corrective_on_faulty", "corrective_on_other", "replaced_faulty", "replaced_other", "failed_faulty", "failed_other", "ignored_orders")
ITEMS = ("corrective", "replacement", "failure", "lost_production")


def diagnose(policy: Any, seeds: list[int]) -> dict[str, Any]:
    """The per-fault-type breakdown of ``policy``'s episodes on ``seeds`` (obs_mode phm)."""
    n = len(seeds)
    env: Any = gym.make_vec("ea_gym/SpringMassDamper-v0", num_envs=n, vectorization_mode="vector_entry_point",
                       obs_mode="phm", continue_after_failure=True)
    if not hasattr(policy, "predict"):
        policy = policy(env)
    core = env.unwrapped.core
    actions = [parse_action(meaning) for meaning in env.unwrapped.action_meanings]
    nominal, limits = env.unwrapped.nominal_parameters, env.unwrapped.safe_limits
    components = list(limits)
    observation, _ = env.reset(seed=seeds)
    first_fault = [core.faulty_component(i) for i in range(n)]
    records = [dict.fromkeys(("cost", *ITEMS, *COUNTS), 0.0) for _ in range(n)]
    corrected_wear: list[float] = []
    at_failure: Counter[str] = Counter()
    active = np.ones(n, dtype=bool)
    while active.any():
        action, _ = policy.predict(observation, deterministic=True)
        action = np.asarray(action, dtype=np.int64)
        down = observation["maintenance_in_progress"][:, 0] > 0.5
        faulty = [core.faulty_component(i) for i in range(n)]  # before the step: a failure or replacement draws a new fault
        observation, _, terminated, truncated, info = env.step(action)
        for i in np.flatnonzero(active):
            record, taken = records[i], actions[action[i]]
            record["cost"] += info["cost"]["total"][i]
            for item in ITEMS:
                record[item] += info["cost"][item][i]
            record["ignored_orders"] += float(down[i] and taken.kind is not ActionKind.CARRY_ON)
            for text in info["events"][i]:
                event = parse_event(text)
                which = "faulty" if getattr(event, "component", None) == faulty[i] else "other"
                if isinstance(event, CorrectiveStep):
                    record[f"corrective_on_{which}"] += 1
                elif isinstance(event, Replacement) and not any(isinstance(parse_event(e), Failure) for e in info["events"][i]):
                    record[f"replaced_{which}"] += 1
                elif isinstance(event, Failure):
                    record[f"failed_{which}"] += 1
                    at_failure[str(taken)] += 1
            if taken.kind is ActionKind.CORRECTIVE and not down[i]:
                parameters = {name: float(values[i]) for name, values in info["true_parameters"].items()}
                corrected_wear.append(float(true_wear(parameters, nominal, limits)[components.index(taken.component)]))
        active &= ~(terminated | truncated)
    env.close()
    by_fault: dict[str, Any] = {}
    for fault in sorted(set(first_fault)) + ["all"]:
        chosen = [r for r, f in zip(records, first_fault) if fault in ("all", f)]
        by_fault[fault] = {"episodes": len(chosen), **{key: float(np.mean([r[key] for r in chosen])) for key in ("cost", *ITEMS, *COUNTS)}}
    quantiles = np.quantile(corrected_wear, [0.1, 0.5, 0.9]).round(3).tolist() if corrected_wear else None
    return {"policy": repr(policy), "by_first_fault": by_fault, "corrected_wear_q10_q50_q90": quantiles,
            "action_on_failure_steps": dict(at_failure.most_common())}


def markdown(name: str, result: dict[str, Any]) -> str:
    """One policy's breakdown as a markdown table (means per episode)."""
    keys = ("cost", *ITEMS, *COUNTS)
    lines = [f"### {name}", "", "| first fault | episodes | " + " | ".join(k.replace("_", " ") for k in keys) + " |",
             "|---" * (len(keys) + 2) + "|"]
    for fault, row in result["by_first_fault"].items():
        lines.append(f"| {fault} | {row['episodes']} | " + " | ".join(f"{row[k]:.1f}" for k in keys) + " |")
    lines += ["", f"True wear of the corrected part after a corrective step (10/50/90 %): {result['corrected_wear_q10_q50_q90']}; "
              f"action on the steps of the failures: {result['action_on_failure_steps']}", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("agents", nargs="*", type=Path, help="trained agent directories (ea-gym train's output)")
    parser.add_argument("--rule", action="store_true", help="also RulThreshold (corrective, 5 s)")
    parser.add_argument("--episodes", type=int, default=100, help="evaluation episodes (default 100)")
    parser.add_argument("--out", type=Path, help="write the breakdowns as JSON")
    args = parse_with_smoke(parser, argv, SMOKE)
    seeds = list(evaluation_seeds(0, args.episodes))
    policies: dict[str, Any] = {str(path): load_policy(path) for path in args.agents}
    if args.rule:
        policies["rul_threshold (corrective, 5 s)"] = lambda env: RulThreshold(env, 5.0, action="corrective")
    results = {}
    with single_threaded_torch():
        for name, policy in policies.items():
            results[name] = diagnose(policy, seeds)
            print(markdown(name, results[name]), flush=True)
    if args.out is not None:
        args.out.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
