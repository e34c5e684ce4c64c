"""Does the maintenance environment's default cost model make the maintenance decision real?

What it measures
    On the default ``ea_gym/SpringMassDamper-v0`` (horizon 500 steps of 1 s, default costs and wear,
    ``continue_after_failure=True`` so that a run-to-failure policy keeps going after a failure, which
    forces a replacement with downtime), the cost of rule-based policies, each with the information it
    can honestly use:

    * ``RunToFailure`` (obs_mode "sensors"): never maintain;
    * too early: ``RulThreshold(threshold=inf)`` (obs_mode "phm"): replace a component as soon as the
      PHM chain diagnoses it, whatever its RUL; and ``Periodic`` with the shortest period of the grid;
    * ``Periodic`` (obs_mode "sensors": it reads only the time since maintenance): replace every
      component in turn each ``period`` s; period tuned on training seeds;
    * ``RulThreshold`` (obs_mode "phm"): replace the diagnosed component when the lower bound of the
      estimated RUL interval falls below the threshold; threshold tuned on training seeds;
    * ``Oracle`` (obs_mode "oracle"): the same rule on the true faulty component and true RUL, threshold
      tuned: the reference lower bound of condition-based maintenance;
    * supplementary: the ``RulThreshold`` and ``Oracle`` rules with a corrective action instead of a
      replacement, at the tuned replacement thresholds (not tuned themselves).

    Tuning uses training seeds 0 .. ``--tune-episodes``-1, evaluation seeds ``--eval-seed`` ..
    ``--eval-seed`` + ``--episodes`` - 1, the same for every policy (common random numbers, so that
    per-seed cost differences are paired). The environment's dynamics (wear, loads, noise) do not
    depend on obs_mode, only on the seed and the actions.

    Reported per policy: mean episode cost with its 95 % confidence interval (normal approximation,
    mean +- 1.96 sd / sqrt(n)), failures, availability (fraction of steps up), maintenance actions per
    episode, the cost breakdown, and the paired cost difference to the tuned ``RulThreshold`` and to the
    ``Oracle`` (mean +- 1.96 sd / sqrt(n) over the evaluation seeds). "Clearly more" means the paired
    difference's 95 % interval lies above 0.

How to run (from the repository root)
    .venv/bin/python experiments/studies/env_decision.py [--episodes 30] [--tune-episodes 10] [--out DIR] [--smoke]

    Writes ``DIR/decision.json`` and ``DIR/decision.md`` (default DIR:
    experiments/results/env_decision), atomically. About 6 to 10 minutes with the defaults (the PHM
    chain runs at ~250 steps/s; the sensors and oracle modes are ~3x faster).
"""

from __future__ import annotations

import argparse
import math
import platform
import shlex
import sys
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))  # this checkout's ea_gym, agents and experiments.common, installed or not

import ea_gym  # noqa: F401 - registers the environments
from agents import ActionMap, EpisodeStats, Oracle, Periodic, RulThreshold, RunToFailure, evaluate, tune
from agents.benchmark import ENV_ID, PERIODS, THRESHOLDS, env_factory, paired
from agents.benchmark import fmt_ci as _fmt_ci
from agents.benchmark import fmt_diff as _fmt_diff
from ea_gym.degradation import WearConfig
from ea_gym.env.costs import CostModel
from ea_gym.files import write_json, write_text
from experiments.common import parse_with_smoke

DEFAULT_OUT = ROOT / "experiments" / "results" / "env_decision"
#: the smoke run: one tuning episode per grid value of two, two evaluation episodes per policy
SMOKE = {"episodes": 2, "tune_episodes": 1, "periods": [60.0, 120.0], "thresholds": [5.0, 20.0], "no_progress": True}


def _number(value: float) -> float | str:
    return value if math.isfinite(value) else str(value)


def sentence(key: str, row: dict[str, Any], rows: dict[str, dict[str, Any]]) -> str:
    """One sentence per policy, from its numbers."""
    b = row["cost_breakdown"]
    vs = row.get("vs_rul_threshold")
    rel = ""
    if vs is not None and key != "rul_threshold":
        verdict = "clearly more than" if vs["clearly_more"] else ("clearly less than" if vs["clearly_less"] else "not clearly different from")
        rel = f" It costs {_fmt_diff(vs)} per episode relative to the tuned RulThreshold ({verdict} it)."
    parts = {
        "run_to_failure": (
            f"Never maintaining lets {row['failures']:.2f} failures per episode happen (failure cost "
            f"{b['failure']:.0f}, lost production {b['lost_production']:.0f}), availability {row['availability']:.3f}."
        ),
        "too_early_diagnosis": (
            f"Replacing the diagnosed component at once, whatever its RUL, spends {row['replacements']:.2f} "
            f"replacements per episode (replacement cost {b['replacement']:.0f}) and still fails {row['failures']:.2f} times."
        ),
        "too_early_periodic": (
            f"Replacing all components every {row['parameter']} s prevents failures ({row['failures']:.2f}) at "
            f"{row['replacements']:.1f} replacements per episode "
            f"(replacement cost {b['replacement']:.0f}, lost production {b['lost_production']:.0f})."
        ),
        "periodic": (
            f"The best period on the training seeds is {row['parameter']} s: {row['replacements']:.1f} replacements and "
            f"{row['failures']:.2f} failures per episode (replacement {b['replacement']:.0f}, failure {b['failure']:.0f})."
        ),
        "rul_threshold": (
            f"With the PHM chain's estimates and the tuned threshold of {row['parameter']} s, {row['replacements']:.2f} "
            f"replacements and {row['failures']:.2f} failures per episode; it costs "
            f"{_fmt_diff(row['vs_oracle'])} more than the Oracle (the price of estimation errors)."
        ),
        "oracle": (
            f"Knowing the faulty component and its true RUL, replacing at threshold {row['parameter']} s needs "
            f"{row['replacements']:.2f} replacements per episode and never fails ({row['failures']:.2f}): the reference lower bound."
        ),
        "rul_threshold_corrective": (
            f"Corrective actions instead of replacements at the same threshold on PHM estimates: "
            f"{row['corrective_steps']:.1f} corrective steps and {row['failures']:.2f} failures per episode."
        ),
        "oracle_corrective": (
            f"Corrective actions on the true state at the Oracle's threshold: {row['corrective_steps']:.1f} corrective "
            f"steps, {row['failures']:.2f} failures and availability {row['availability']:.3f}."
        ),
    }
    return parts[key] + rel


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=30, help="evaluation episodes per policy (default 30)")
    parser.add_argument("--tune-episodes", type=int, default=10, help="training episodes per grid value (default 10)")
    parser.add_argument("--eval-seed", type=int, default=10_000, help="first evaluation seed (default 10000)")
    parser.add_argument("--periods", type=float, nargs="+", default=PERIODS, help=f"Periodic grid, s (default {PERIODS})")
    parser.add_argument("--thresholds", type=float, nargs="+", default=THRESHOLDS, help=f"RUL threshold grid, s (default {THRESHOLDS})")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    args = parse_with_smoke(parser, argv, SMOKE)
    if args.episodes < 2 or args.tune_episodes < 1:
        parser.error("--episodes must be >= 2 and --tune-episodes >= 1")
    progress = not args.no_progress
    command = shlex.join([".venv/bin/python", "experiments/studies/env_decision.py", *(sys.argv[1:] if argv is None else argv)])

    started = time.perf_counter()
    timings: dict[str, float] = {}
    actions = ActionMap.from_env(env_factory("oracle")())
    train = range(args.tune_episodes)
    test = range(args.eval_seed, args.eval_seed + args.episodes)
    periods = [int(p) if float(p).is_integer() else p for p in args.periods]
    thresholds = [int(t) if float(t).is_integer() else t for t in args.thresholds]

    def timed(label: str, fn):
        t = time.perf_counter()
        out = fn()
        timings[label] = time.perf_counter() - t
        print(f"  {label}: {timings[label]:.1f} s", flush=True)
        return out

    print(f"tuning on training seeds {train.start}..{train.stop - 1}", flush=True)
    best_period, period_table = timed("tune periodic", lambda: tune(lambda p: Periodic(actions, p), periods, env_factory("sensors"), train, progress))
    best_threshold, threshold_table = timed(
        "tune rul_threshold", lambda: tune(lambda t: RulThreshold(actions, t), thresholds, env_factory("phm"), train, progress)
    )
    best_oracle, oracle_table = timed("tune oracle", lambda: tune(lambda t: Oracle(actions, t), thresholds, env_factory("oracle"), train, progress))

    plan = [  # key, label, policy, obs_mode, parameter
        ("run_to_failure", "RunToFailure", RunToFailure(actions), "sensors", None),
        ("too_early_diagnosis", "too early: RulThreshold(inf), replace at diagnosis", RulThreshold(actions, math.inf), "phm", math.inf),
        ("too_early_periodic", f"too early: Periodic({min(periods)} s)", Periodic(actions, min(periods)), "sensors", min(periods)),
        ("periodic", f"Periodic, tuned ({best_period} s)", Periodic(actions, best_period), "sensors", best_period),
        ("rul_threshold", f"RulThreshold, tuned ({best_threshold} s)", RulThreshold(actions, best_threshold), "phm", best_threshold),
        ("oracle", f"Oracle, tuned ({best_oracle} s)", Oracle(actions, best_oracle), "oracle", best_oracle),
        (
            "rul_threshold_corrective", f"supplementary: RulThreshold corrective ({best_threshold} s)",
            RulThreshold(actions, best_threshold, "corrective"), "phm", best_threshold,
        ),
        (
            "oracle_corrective", f"supplementary: Oracle corrective ({best_oracle} s)",
            Oracle(actions, best_oracle, "corrective"), "oracle", best_oracle,
        ),
    ]
    print(f"evaluating on seeds {test.start}..{test.stop - 1}", flush=True)
    stats: dict[str, EpisodeStats] = {}
    for key, label, policy, mode, _ in plan:
        stats[key] = timed(
            f"evaluate {key}",
            lambda policy=policy, mode=mode, label=label: evaluate(policy, env_factory(mode), test, progress, description=label),
        )

    rows: dict[str, dict[str, Any]] = {}
    for key, label, _, mode, parameter in plan:
        row = stats[key].to_dict()
        row.update(label=label, obs_mode=mode, parameter=None if parameter is None else _number(parameter))
        row["vs_rul_threshold"] = paired(stats[key], stats["rul_threshold"])
        row["vs_oracle"] = paired(stats[key], stats["oracle"])
        rows[key] = row

    condition_based = rows["rul_threshold"]["mean_cost"]
    checks = {
        key: {
            "more_than_rul_threshold": rows[key]["vs_rul_threshold"]["clearly_more"],
            "more_than_oracle": rows[key]["vs_oracle"]["clearly_more"],
            "ratio_to_rul_threshold": rows[key]["mean_cost"] / condition_based,
        }
        for key in ("run_to_failure", "too_early_diagnosis", "too_early_periodic", "periodic")
    }
    decision_real = all(c["more_than_rul_threshold"] and c["more_than_oracle"] for c in checks.values())
    total = time.perf_counter() - started
    result = {
        "question": "do the default costs make the maintenance decision real: do run-to-failure, too-early and periodic "
        "maintenance each cost clearly more than condition-based maintenance (RulThreshold on PHM, Oracle)?",
        "decision_real": decision_real,
        "checks": checks,
        "command": command,
        "environment": {
            "id": ENV_ID, "horizon": 500, "step_seconds": 1.0, "continue_after_failure": True,
            "costs": asdict(CostModel()), "wear": {"every maintainable component": asdict(WearConfig())},
            "action_meanings": list(actions.action_meanings),
        },
        "seeds": {"tuning": [train.start, train.stop - 1], "evaluation": [test.start, test.stop - 1]},
        "tuning": {
            "periodic": {"obs_mode": "sensors", "grid_s": periods, "best_s": best_period, "table": period_table},
            "rul_threshold": {"obs_mode": "phm", "grid_s": thresholds, "best_s": best_threshold, "table": threshold_table},
            "oracle": {"obs_mode": "oracle", "grid_s": thresholds, "best_s": best_oracle, "table": oracle_table},
        },
        "policies": rows,
        "ci_method": "normal approximation: mean +- 1.96 sd / sqrt(n), sd with ddof=1 (costs and paired differences)",
        "timings_s": {**timings, "total": total},
        "machine": {"python": platform.python_version(), "platform": platform.platform(), "numpy": np.__version__},
    }
    args.out.mkdir(parents=True, exist_ok=True)
    write_json(args.out / "decision.json", result)
    write_text(args.out / "decision.md", markdown(result))
    print(markdown(result))
    print(f"wrote {args.out / 'decision.json'} and decision.md in {total:.0f} s ({total / 60:.1f} min)")
    return result


def markdown(result: dict[str, Any]) -> str:
    rows = result["policies"]
    env = result["environment"]
    c = env["costs"]
    lines = [
        "# Does the environment's default cost model make the maintenance decision real?",
        "",
        f"`{env['id']}`, defaults: horizon {env['horizon']} steps of {env['step_seconds']:g} s, "
        f"continue_after_failure=True; costs: corrective {c['corrective']:g}/step, replacement {c['replacement']:g} "
        f"+ {c['replace_downtime']} steps down, failure {c['failure']:g} + {c['failure_downtime']} steps down, "
        f"lost production {c['lost_production']:g}/step down. Wear: one fault at a time, linear drift at "
        f"{env['wear']['every maintainable component']['rate']} of the nominal-to-limit distance per s, arriving "
        f"{env['wear']['every maintainable component']['arrival']} s after each (re)start.",
        "",
        f"Tuning seeds {result['seeds']['tuning'][0]}..{result['seeds']['tuning'][1]}; evaluation seeds "
        f"{result['seeds']['evaluation'][0]}..{result['seeds']['evaluation'][1]} (the same for every policy, so "
        "differences are paired per seed). Cost: mean per episode [95 % CI, normal approximation]. "
        "Δ: paired cost difference to the tuned RulThreshold and to the Oracle [95 % CI].",
        "",
        "| policy | obs_mode | cost [95 % CI] | failures | availability | maintenance actions | Δ vs RulThreshold | Δ vs Oracle |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in rows.values():
        lines.append(
            f"| {row['label']} | {row['obs_mode']} | {_fmt_ci(row)} | {row['failures']:.2f} | {row['availability']:.3f} | "
            f"{row['maintenance_actions']:.1f} | {_fmt_diff(row['vs_rul_threshold'])} | {_fmt_diff(row['vs_oracle'])} |"
        )
    lines += ["", "Cost breakdown (mean per episode):", ""]
    lines += ["| policy | corrective | replacement | failure | lost production |", "|---|---|---|---|---|"]
    for row in rows.values():
        b = row["cost_breakdown"]
        lines.append(f"| {row['label']} | {b['corrective']:.1f} | {b['replacement']:.1f} | {b['failure']:.1f} | {b['lost_production']:.1f} |")
    lines += ["", "## Per policy", ""]
    for key, row in rows.items():
        lines.append(f"- **{row['label']}**: {sentence(key, row, rows)}")
    lines += ["", "## Verdict", ""]
    verdict = "yes" if result["decision_real"] else "no"
    lines.append(
        f"Decision real: **{verdict}**. Each of run-to-failure, too early (both kinds) and the tuned periodic policy "
        "must cost clearly more (paired 95 % interval above 0) than both the tuned RulThreshold and the Oracle:"
    )
    lines.append("")
    for key, check in result["checks"].items():
        lines.append(
            f"- {rows[key]['label']}: {check['ratio_to_rul_threshold']:.2f}x the RulThreshold cost; clearly more than "
            f"RulThreshold: {check['more_than_rul_threshold']}; than Oracle: {check['more_than_oracle']}"
        )
    lines += ["", "## Tuning (training seeds)", ""]
    for name, tuning in result["tuning"].items():
        lines.append(f"{name} ({tuning['obs_mode']}), best {tuning['best_s']} s:")
        lines.append("")
        lines.append("| parameter (s) | cost [95 % CI] | failures | availability | maintenance actions |")
        lines.append("|---|---|---|---|---|")
        for r in tuning["table"]:
            lines.append(f"| {r['parameter']} | {_fmt_ci(r)} | {r['failures']:.2f} | {r['availability']:.3f} | {r['maintenance_actions']:.1f} |")
        lines.append("")
    t = result["timings_s"]
    lines += [
        "## Reproduce",
        "",
        "```bash",
        result["command"],
        "```",
        "",
        f"Took {t['total']:.0f} s ({t['total'] / 60:.1f} min) on {result['machine']['platform']}, Python {result['machine']['python']}.",
        "",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    main()
