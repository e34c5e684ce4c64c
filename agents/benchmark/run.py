"""The benchmark run: tune the rules, evaluate every policy on the common seeds, write the outputs."""

from __future__ import annotations

import platform
import shlex
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.benchmark.evaluation import EVALUATION_ORDER, evaluate_policies, plan_policies, policy_rows, value_of_information
from agents.benchmark.figures import plot_cost_distribution, plot_timelines
from agents.benchmark.report import markdown
from agents.benchmark.settings import (
    DEFAULT_GRIDS,
    EVALUATION_SEED_BASE,
    EVALUATION_SEED_STRIDE,
    RULES,
    display_path,
    env_factory,
    evaluation_seeds,
    tuning_seeds,
    vector_env_factory,
)
from agents.benchmark.stopwatch import Stopwatch
from agents.benchmark.tuning import rule_builders, tune_rules
from agents.conventions import TRAINING_SEED, VALIDATION_SEED, refuse_pickle
from agents.policies import ActionMap
from ea_gym.env import env_id
from ea_gym.files import json_ready, write_json, write_text

__all__ = ["run_benchmark"]


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
    trust_pickle: bool = False,
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
        trust_pickle: also load agents saved as stable-baselines3's files, which run any code they hold when
            unpickled; without it they are refused before any work (``agents.conventions.refuse_pickle``).

    Returns:
        The dictionary written to ``benchmark.json``.
    """
    started = time.perf_counter()
    out = Path(out)
    env_kwargs = dict(env_kwargs or {})
    evaluation, tuning, grids, extra = _checked(episodes, seed, tune_episodes, grids, env_kwargs, ppo_policies, ppo, trust_pickle)
    timeline_seed = evaluation.start if timeline_seed is None else int(timeline_seed)
    if command is None:
        command = _default_command(episodes, seed, out, ppo, tune_episodes)
        command_note = _defaults_note(command_note, extra, grids, env_kwargs)
    stopwatch = Stopwatch(progress)
    make = lambda mode: vector_env_factory(mode, **env_kwargs)  # noqa: E731
    actions, environment = _environment(env_kwargs)

    stopwatch.say(f"tuning on seeds {tuning.start}..{tuning.stop - 1}")
    builders = rule_builders(actions)
    tuned, tables = tune_rules(grids, builders, make, tuning, stopwatch, batch_size)
    plan, skipped = plan_policies(tuned, builders, actions, {"ppo": None if ppo is None else Path(ppo), **extra}, stopwatch.say, trust_pickle)

    stopwatch.say(f"evaluating on seeds {evaluation.start}..{evaluation.stop - 1}")
    order = [n for n in (*EVALUATION_ORDER, *extra) if n in plan]
    stats, timelines = evaluate_policies(plan, order, make, evaluation, timeline_seed, env_kwargs, stopwatch, batch_size)
    rows, ranking = policy_rows(plan, order, stats)
    voi = value_of_information(plan, order, stats)

    rows = json_ready(rows)
    _write_figures(out, rows, timelines, stopwatch)
    total = time.perf_counter() - started
    stopwatch.timings["total"] = total
    seeds = _seeds(evaluation, tuning, seed, timeline_seed)
    result = _result(rows, ranking, skipped, seeds, {"reproduce": command, "note": command_note}, environment, tables, voi, stopwatch.timings)
    write_json(out / "benchmark.json", result)
    write_text(out / "benchmark.md", markdown(result))
    stopwatch.say(f"wrote {out}/benchmark.json, benchmark.md, cost_distribution.png, timelines.png in {total:.0f} s")
    return result


def _checked(
    episodes: int, seed: int, tune_episodes: int, grids: Mapping[str, Sequence[Any]] | None, env_kwargs: Mapping[str, Any],
    ppo_policies: Mapping[str, Path] | None, ppo: Path | None, trust_pickle: bool,
) -> tuple[range, range, dict[str, tuple[Any, ...]], dict[str, Path | None]]:
    """run_benchmark's arguments checked before any work: the evaluation and tuning seeds, the grids, the extra agents
    (and no agent of pickled files unless ``trust_pickle``)."""
    for reserved in ("obs_mode", "continue_after_failure"):
        if reserved in env_kwargs:
            raise ValueError(f"env_kwargs must not set {reserved!r}: the benchmark sets it")
    evaluation = evaluation_seeds(seed, episodes)
    tuning = tuning_seeds(tune_episodes)
    merged = {**DEFAULT_GRIDS, **{k: tuple(v) for k, v in (grids or {}).items()}}
    unknown = sorted(set(merged) - set(DEFAULT_GRIDS))
    if unknown:
        raise ValueError(f"grids: unknown policies {unknown}; tuned policies are {sorted(DEFAULT_GRIDS)}")
    for name, grid in merged.items():
        if not grid:
            raise ValueError(f"grids[{name!r}] must hold at least one value")
    extra: dict[str, Path | None] = {str(k): (None if v is None else Path(v)) for k, v in (ppo_policies or {}).items()}
    clash = sorted(set(extra) & {"ppo", *RULES})
    if clash:
        raise ValueError(f"ppo_policies: the names {clash} are taken by the benchmark's own policies")
    for directory in (ppo, *extra.values()):
        if directory is not None:
            refuse_pickle(Path(directory), trust_pickle)
    return evaluation, tuning, merged, extra


def _default_command(episodes: int, seed: int, out: Path, ppo: Path | None, tune_episodes: int) -> str:
    """The ``ea-gym benchmark`` command of these arguments (the other arguments at their defaults)."""
    words = ["ea-gym", "benchmark", "--episodes", str(episodes), "--seed", str(seed), "--out", display_path(out),
             "--tune-episodes", str(tune_episodes)]
    words += ["--ppo", display_path(ppo)] if ppo is not None else ["--no-ppo"]
    return shlex.join(words)


def _defaults_note(
    note: str | None, extra: Mapping[str, Path | None], grids: Mapping[str, Sequence[Any]], env_kwargs: Mapping[str, Any],
) -> str | None:
    """``note``, or, when the run used arguments the command line has no flag for, a sentence naming them."""
    if not (extra or grids != DEFAULT_GRIDS or env_kwargs):
        return note
    return note or (
        "The command reproduces the defaults only: this run also used "
        + ", ".join(f"{k}={v}" for k, v in (("ppo_policies", {k: str(v) for k, v in extra.items()}),
                                            ("grids", {k: list(v) for k, v in grids.items()}),
                                            ("env_kwargs", env_kwargs)) if v)
        + " (agents.benchmark.run_benchmark)."
    )


def _environment(env_kwargs: Mapping[str, Any]) -> tuple[ActionMap, dict[str, Any]]:
    """The environment's actions, and its description for benchmark.json (from one probe environment)."""
    probe = env_factory("oracle", **env_kwargs)()
    try:
        actions = ActionMap.from_env(probe)
        base = probe.unwrapped
        environment = {"id": env_id(env_kwargs.get("system")), "continue_after_failure": True, "env_kwargs": json_ready(env_kwargs),
                       "horizon": int(base.config.horizon), "step_seconds": float(base.config.step_seconds),
                       "action_meanings": list(actions.action_meanings)}
    finally:
        probe.close()
    return actions, environment


def _seeds(evaluation: range, tuning: range, seed: int, timeline_seed: int) -> dict[str, Any]:
    return {
        "episodes": len(evaluation),
        "evaluation": [evaluation.start, evaluation.stop - 1],
        "evaluation_rule": f"{EVALUATION_SEED_BASE} + seed * {EVALUATION_SEED_STRIDE} + i, i < episodes",
        "benchmark_seed": int(seed),
        "tuning": [tuning.start, tuning.stop - 1],
        "training_from": TRAINING_SEED,
        "validation_from": VALIDATION_SEED,
        "timeline": timeline_seed,
    }


def _write_figures(out: Path, rows: Mapping[str, Any], timelines: Mapping[str, Any], stopwatch: Stopwatch) -> None:
    """cost_distribution.png, timelines.png and timelines.json in ``out`` (created)."""
    out.mkdir(parents=True, exist_ok=True)
    stopwatch.timed("figures", lambda: (plot_cost_distribution(rows, out / "cost_distribution.png"),
                                        plot_timelines(timelines, rows, out / "timelines.png")))
    write_json(out / "timelines.json", json_ready(timelines))


def _result(
    rows: Mapping[str, Any], ranking: list[str], skipped: Mapping[str, str], seeds: Mapping[str, Any], commands: Mapping[str, Any],
    environment: Mapping[str, Any], tables: Mapping[str, Any], voi: Mapping[str, Any], timings: Mapping[str, float],
) -> dict[str, Any]:
    """benchmark.json's content."""
    return json_ready({
        "policies": rows,
        "ranking": ranking,
        "skipped": skipped,
        "seeds": seeds,
        "commands": commands,
        "environment": environment,
        "tuning": json_ready(tables),
        "value_of_information": voi,
        "ci_method": "normal approximation: mean +- 1.96 sd / sqrt(n), sd with ddof=1 (costs and paired differences)",
        "timings_s": timings,
        "machine": {"python": platform.python_version(), "platform": platform.platform(), "numpy": np.__version__},
    })
