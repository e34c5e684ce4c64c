"""The benchmark run: tune the rules, evaluate every policy on the common seeds, write the outputs."""

from __future__ import annotations

import os
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
from agents.benchmark.runners import runner_for
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
from agents.benchmark.tuned import TUNED_RULES_FILE, TunedRules, environment_settings, fingerprint, read_tuned, write_tuned
from agents.benchmark.tuning import rule_builders, tune_rules
from agents.conventions import TRAINING_SEED, VALIDATION_SEED, pickled, refuse_pickle
from agents.policies import ActionMap
from ea_gym.env import env_id
from ea_gym.files import check_output_directory, json_ready, staged_output, write_json, write_text
from ea_gym.threads import single_threaded_torch

__all__ = ["run_benchmark", "TUNE_EPISODES", "MAX_ENVS"]

#: tuning episodes per grid value: a PHM policy's cost is decided by rare failures (a few in a hundred
#: episodes, 480 each), which 30 episodes mostly miss
TUNE_EPISODES = 300
#: the most systems stepped at once: 600 phm systems hold 570 MB; the more, the cheaper each system's step
#: (150 systems 8,800 env-steps per CPU second, 600 systems 12,900)
MAX_ENVS = 1200


def run_benchmark(
    episodes: int, seed: int, out: Path, ppo: Path | None, tune_episodes: int | None = None, progress: bool = True, *,
    tune: bool = False, tuned_file: Path | None = None, write_tuned_to: Path | None = None, allow_stale: bool = False,
    max_envs: int = MAX_ENVS, ppo_policies: Mapping[str, Path] | None = None, grids: Mapping[str, Sequence[float]] | None = None,
    env_kwargs: Mapping[str, Any] | None = None, timeline_seed: int | None = None, command: str | None = None,
    command_note: str | None = None, trust_pickle: bool = False, ray: str | None = None,
) -> dict[str, Any]:
    """Evaluate and compare the maintenance policies (the rules tuned now or read from a file); write the results to
    ``out`` and return what ``benchmark.json`` holds.

    Args:
        episodes: evaluation episodes per policy (>= 2 for confidence intervals; 1 gives none).
        seed: benchmark seed: evaluation seeds ``100_000 + seed * 10_000 + i``, i < episodes.
        out: output directory (created): benchmark.json, benchmark.md, cost_distribution.png,
            timelines.png, timelines.json, written beside it and moved in together when the run completes.
        ppo: directory of a trained agent (``ea-gym train --out DIR``) evaluated as ``ppo`` on its own
            training obs_mode; None, or a directory without a model, skips it (noted in the outputs).
        tune_episodes: with ``tune``, the tuning episodes (seeds 0 .. tune_episodes - 1) per grid
            value (default ``TUNE_EPISODES``); refused without ``tune``.
        progress: progress bars and one line per stage.
        tune: grid-search the rules on the tuning seeds; otherwise read their tuned settings from ``tuned_file``.
        tuned_file: the tuned settings to read (default ``TUNED_RULES_FILE``); refused with ``tune``.
        write_tuned_to: with ``tune``, write the tuned settings there (``tuned.TunedRules``), with the outputs.
        allow_stale: use a tuned file made on another environment instead of refusing it (the outputs say so).
        max_envs: the most systems stepped at once on one vector environment; the policies of one obs_mode (and
            the values of one grid) run side by side on it; the timelines step one environment.
        ppo_policies: more trained agents, name -> directory (e.g. ``{"ppo_sensors": ..., "ppo_oracle": ...}``),
            for the value-of-information comparison; missing ones are skipped with a note.
        grids: with ``tune``, tuning grids by policy (``"oracle"``, ``"rul_threshold"``: thresholds in
            s, tried with each of ``ACTIONS``; ``"corrective_band"``: bands, each a number or a mapping
            per component; ``"periodic"``: periods in s); missing keys take ``DEFAULT_GRIDS``.
        env_kwargs: more keyword arguments of the environment (e.g. ``{"horizon": 100}``), for every
            policy, the tuning and the timelines (part of the tuned settings' fingerprint).
        timeline_seed: the episode of the timelines (default the first evaluation seed).
        command: the command line that reproduces this run, written into the outputs (default the
            equivalent ``ea-gym benchmark`` command).
        command_note: a sentence written under the command in the markdown.
        trust_pickle: also load agents saved as stable-baselines3's files, which run any code they hold when
            unpickled; without it they are refused before any work (``agents.conventions.refuse_pickle``).
        ray: the episodes as Ray tasks (``runners.RayRunner``, same records) on ``"local"`` Ray or a cluster's address.
    """
    started = time.perf_counter()
    out = Path(out)
    env_kwargs = dict(env_kwargs or {})
    evaluation, tuning, grids, extra = _checked(out, episodes, seed, tune, tune_episodes, tuned_file, write_tuned_to, grids, env_kwargs,
                                                ppo_policies, max_envs, ppo, trust_pickle)
    timeline_seed = evaluation.start if timeline_seed is None else int(timeline_seed)
    if command is None:
        command = _default_command(episodes, seed, out, ppo, tune, tuning, tuned_file, write_tuned_to, allow_stale)
        command_note = _defaults_note(command_note, extra, grids, env_kwargs)
    stopwatch, runner = Stopwatch(progress), runner_for(ray, [Path(d) for d in (ppo, *extra.values()) if d is not None and pickled(Path(d))])
    make = lambda mode: vector_env_factory(mode, **env_kwargs)  # noqa: E731
    actions, environment, settings = _environment(env_kwargs)
    builders = rule_builders(actions)
    # the isolation network is small: a second torch thread only waits (3.6x slower on 2 loaded cores)
    with single_threaded_torch():
        if tune:
            stopwatch.say(f"tuning on seeds {tuning.start}..{tuning.stop - 1}")
            tuned = TunedRules(*tune_rules(grids, builders, make, tuning, stopwatch, max_envs, runner), tuning_seeds=tuning, command=command,
                               settings=settings, fingerprint=fingerprint(settings), timings_s=dict(stopwatch.timings), machine=_machine())
        else:
            tuned = _read_rules(TUNED_RULES_FILE if tuned_file is None else Path(tuned_file), settings, allow_stale)
        source = _source(tuned, settings, write_tuned_to if tune else tuned_file or TUNED_RULES_FILE, tune, stopwatch)
        learned = {"ppo": None if ppo is None else Path(ppo), **extra}
        plan, skipped = plan_policies(tuned.rules, builders, actions, learned, stopwatch.say, trust_pickle)

        stopwatch.say(f"evaluating on seeds {evaluation.start}..{evaluation.stop - 1}")
        order = [n for n in (*EVALUATION_ORDER, *extra) if n in plan]
        stats, timelines = evaluate_policies(plan, order, make, evaluation, timeline_seed, env_kwargs, stopwatch, max_envs, runner)
    rows, ranking = policy_rows(plan, order, stats)
    rows = json_ready(rows)
    with staged_output(out, last="benchmark.json") as staging:  # every output appears together when the run completes
        _write_figures(staging, rows, timelines, stopwatch)
        stopwatch.timings["total"] = time.perf_counter() - started
        result = _result(rows, ranking, skipped, _seeds(evaluation, tuned.tuning_seeds, seed, timeline_seed),
                         {"reproduce": command, "note": command_note}, environment, tuned.tables, source,
                         value_of_information(plan, order, stats), stopwatch.timings)
        _write_reports(staging, result, tuned if tune else None, write_tuned_to, stopwatch)
    stopwatch.say(f"wrote {out}/benchmark.json, benchmark.md, cost_distribution.png, timelines.png in {stopwatch.timings['total']:.0f} s")
    return result


def _read_rules(path: Path, settings: Mapping[str, Any], allow_stale: bool) -> TunedRules:
    """The tuned settings in ``path`` (``tuned.read_tuned``), every tuned rule's among them; stale ones only when allowed."""
    tuned, _ = read_tuned(path, settings, allow_stale)
    missing = sorted(set(DEFAULT_GRIDS) - set(tuned.rules))
    if missing:
        raise ValueError(f"--tuned: {path} has no tuned setting for {', '.join(missing)}")
    return tuned


def _source(tuned: TunedRules, settings: Mapping[str, Any], path: Path | None, tune: bool, stopwatch: Stopwatch) -> dict[str, Any]:
    """Where the tuned settings came from, for the outputs (a tuning run writes them to ``path`` with the outputs)."""
    current = fingerprint(settings)
    if not tune:
        assert path is not None  # the default file when none was given
        stale = tuned.fingerprint != current
        stopwatch.say(f"tuned settings from {display_path(path)}" + (" (STALE: tuned on another environment)" if stale else ""))
    return {"tuned": "in this run" if tune else "read from the file", "file": None if path is None else display_path(path),
            "stale": tuned.fingerprint != current, "command": tuned.command, "fingerprint": tuned.fingerprint,
            "current_fingerprint": current}


def _check_writable(out: Path, write_tuned_to: Path | None) -> None:
    """The output directory and the tuned settings' file can be written (``files.OutputError`` naming them otherwise)."""
    check_output_directory(out)
    if write_tuned_to is not None:
        check_output_directory(Path(write_tuned_to).parent)
        if Path(write_tuned_to).is_dir():
            raise ValueError(f"--write-tuned: {write_tuned_to} is a directory; expected a file to write")


def _checked(
    out: Path, episodes: int, seed: int, tune: bool, tune_episodes: int | None, tuned_file: Path | None, write_tuned_to: Path | None,
    grids: Mapping[str, Sequence[Any]] | None, env_kwargs: Mapping[str, Any], ppo_policies: Mapping[str, Path] | None, max_envs: int,
    ppo: Path | None, trust_pickle: bool,
) -> tuple[range, range, dict[str, tuple[Any, ...]], dict[str, Path | None]]:
    """run_benchmark's arguments checked before any work: the outputs writable, the evaluation and tuning seeds, the grids,
    the extra agents (and no agent of pickled files unless ``trust_pickle``)."""
    _check_writable(out, write_tuned_to)
    for directory in (ppo, *(ppo_policies or {}).values()):
        if directory is not None:
            refuse_pickle(Path(directory), trust_pickle)
    for reserved in ("obs_mode", "continue_after_failure"):
        if reserved in env_kwargs:
            raise ValueError(f"env_kwargs must not set {reserved!r}: the benchmark sets it")
    if not tune:
        for name, given in (("--tune-episodes", tune_episodes), ("--write-tuned", write_tuned_to), ("grids", grids)):
            if given is not None:
                raise ValueError(f"{name} applies to tuning only: add --tune")
    elif tuned_file is not None:
        raise ValueError("--tuned reads tuned settings, --tune makes them: give one of the two")
    if not (isinstance(max_envs, int) and max_envs >= 1):
        raise ValueError(f"max_envs must be a positive int, got {max_envs!r}")
    evaluation = evaluation_seeds(seed, episodes)
    tuning = tuning_seeds(TUNE_EPISODES if tune_episodes is None else tune_episodes)
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
    return evaluation, tuning, merged, extra


def _default_command(
    episodes: int, seed: int, out: Path, ppo: Path | None, tune: bool, tuning: range, tuned_file: Path | None,
    write_tuned_to: Path | None, allow_stale: bool,
) -> str:
    """The ``ea-gym benchmark`` command of these arguments (the other arguments at their defaults)."""
    words = ["ea-gym", "benchmark", "--episodes", str(episodes), "--seed", str(seed), "--out", display_path(out)]
    if tune:
        words += ["--tune", "--tune-episodes", str(len(tuning))]
        words += ["--write-tuned", display_path(write_tuned_to)] if write_tuned_to is not None else []
    else:
        words += ["--tuned", display_path(tuned_file)] if tuned_file is not None else []
        words += ["--allow-stale"] if allow_stale else []
    words += ["--ppo", display_path(ppo)] if ppo is not None else ["--no-ppo"]
    return shlex.join(words)


def _defaults_note(
    note: str | None, extra: Mapping[str, Path | None], grids: Mapping[str, Sequence[Any]], env_kwargs: Mapping[str, Any],
) -> str | None:
    """``note``, or, when the run used arguments the command line has no flag for, a sentence naming them."""
    custom = {k: list(v) for k, v in grids.items()} if grids != DEFAULT_GRIDS else {}
    if not (extra or custom or env_kwargs):
        return note
    return note or (
        "The command reproduces the defaults only: this run also used "
        + ", ".join(f"{k}={v}" for k, v in (("ppo_policies", {k: str(v) for k, v in extra.items()}),
                                            ("grids", custom),
                                            ("env_kwargs", env_kwargs)) if v)
        + " (agents.benchmark.run_benchmark)."
    )


def _environment(env_kwargs: Mapping[str, Any]) -> tuple[ActionMap, dict[str, Any], dict[str, Any]]:
    """The environment's actions, its description for benchmark.json and the settings the tuning depends on
    (``tuned.environment_settings``), from one probe environment."""
    probe = env_factory("oracle", **env_kwargs)()
    try:
        actions = ActionMap.from_env(probe)
        base = probe.unwrapped
        environment = {"id": env_id(env_kwargs.get("system")), "continue_after_failure": True, "env_kwargs": json_ready(env_kwargs),
                       "horizon": int(base.config.horizon), "step_seconds": float(base.config.step_seconds),
                       "action_meanings": list(actions.action_meanings)}
        settings = environment_settings(probe, env_kwargs)
    finally:
        probe.close()
    return actions, environment, settings


def _machine() -> dict[str, Any]:
    return {"python": platform.python_version(), "platform": platform.platform(), "numpy": np.__version__, "cpus": os.cpu_count()}


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
    """cost_distribution.png, timelines.png and timelines.json in ``out``."""
    stopwatch.timed("figures", lambda: (plot_cost_distribution(rows, out / "cost_distribution.png"),
                                        plot_timelines(timelines, rows, out / "timelines.png")))
    write_json(out / "timelines.json", json_ready(timelines))


def _write_reports(out: Path, result: Mapping[str, Any], tuned: TunedRules | None, write_tuned_to: Path | None, stopwatch: Stopwatch) -> None:
    """benchmark.json and benchmark.md in ``out``; the settings of a tuning run (``tuned``) in ``write_tuned_to`` when given."""
    write_json(out / "benchmark.json", result)
    write_text(out / "benchmark.md", markdown(result))
    if tuned is not None and write_tuned_to is not None:
        write_tuned(write_tuned_to, tuned)
        stopwatch.say(f"wrote the tuned settings to {write_tuned_to}")


def _result(
    rows: Mapping[str, Any], ranking: list[str], skipped: Mapping[str, str], seeds: Mapping[str, Any], commands: Mapping[str, Any],
    environment: Mapping[str, Any], tables: Mapping[str, Any], source: Mapping[str, Any], voi: Mapping[str, Any],
    timings: Mapping[str, float],
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
        "tuned_settings": json_ready(source),
        "value_of_information": voi,
        "ci_method": "normal approximation: mean +- 1.96 sd / sqrt(n), sd with ddof=1 (costs and paired differences)",
        "timings_s": timings,
        "machine": _machine(),
    })
