"""Tuning the rule-based policies: each rule's grid searched on the tuning seeds, the best value kept."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from agents.benchmark.batches import evaluate_side_by_side
from agents.benchmark.runners import BatchRunner
from agents.benchmark.settings import ACTIONS, DEFAULT_GRIDS, QUIET_BAND, RULES
from agents.benchmark.stopwatch import Stopwatch
from agents.evaluation import tuning_row
from agents.policies import ActionMap, CorrectiveBand, Oracle, Periodic, RulThreshold

__all__ = ["RuleBuilder", "rule_builders", "tune_rules"]

#: (tuned value, action or None) -> policy
RuleBuilder = Callable[[Any, Any], Any]


def rule_builders(actions: ActionMap) -> dict[str, RuleBuilder]:
    """The tuned rules' constructors by name: ``builder(value, action)`` (action None for rules without one)."""
    classes = actions.diagnosis_classes[1:]
    quiet_band = {c: b for c, b in QUIET_BAND.items() if c in classes}
    return {
        "oracle": lambda v, a: Oracle(actions, v, action=a),
        "rul_threshold": lambda v, a: RulThreshold(actions, v, action=a),
        "corrective_band": lambda v, a: CorrectiveBand(actions, _band_for(v, classes), quiet_band=quiet_band),
        "periodic": lambda v, a: Periodic(actions, v),
    }


def _band_for(band: Any, classes: Sequence[str]) -> Any:
    """A grid value for the system's fault classes: per-component bands name the spring-mass-damper's
    components; on a system with others, every component takes the value's narrowest band."""
    if isinstance(band, Mapping) and set(band) != set(classes):
        return min(band.values())
    return band


def _parameter(value: Any) -> Any:
    """A grid value as JSON shows it: whole numbers as ints, mappings per component recursively."""
    if isinstance(value, Mapping):
        return {str(k): _parameter(v) for k, v in value.items()}
    return int(value) if isinstance(value, (int, float)) and float(value).is_integer() else value


def tune_rules(
    grids: Mapping[str, Sequence[Any]],
    builders: Mapping[str, RuleBuilder],
    make: Callable[[str], Any],
    seeds: range,
    stopwatch: Stopwatch,
    max_envs: int,
    runner: BatchRunner | None = None,
) -> tuple[dict[str, tuple[Any, str | None]], dict[str, Any]]:
    """Grid-search every tuned rule (``DEFAULT_GRIDS``' names) on ``seeds``.

    Every (action, value) of a rule runs side by side with the others on one vector environment of up
    to ``max_envs`` systems (``batches.evaluate_side_by_side``): the same episodes as one at a time.

    Args:
        grids: the values to try per rule; the oracle and RulThreshold try each with every one of ``ACTIONS``.
        builders: ``rule_builders``.
        make: obs_mode -> vector environment factory (``vector_env_factory``).
        seeds: the tuning seeds.
        stopwatch: times each search; its ``progress`` shows progress bars.
        max_envs: the most systems stepped at once.
        runner: where the episodes run (``runners``; None: one batch after another in this process).

    Returns:
        ``tuned``: name -> (best value, its action or None); ``tables``: name -> the search's table
        (obs_mode, parameter_name, grid, best, action, one row per action and value, actions in
        ``ACTIONS``' order); ties go to the earlier row.
    """
    tuned: dict[str, tuple[Any, str | None]] = {}
    tables: dict[str, Any] = {}
    for name in DEFAULT_GRIDS:
        _, mode, parameter_name = RULES[name]
        grid = [_parameter(v) for v in grids[name]]
        candidates = [(action, value) for action in (ACTIONS if name in ("oracle", "rul_threshold") else (None,)) for value in grid]
        policies = {i: builders[name](value, action) for i, (action, value) in enumerate(candidates)}

        def search(policies: Mapping[int, Any] = policies, mode: str = mode, name: str = name) -> Mapping[Any, Any]:
            return evaluate_side_by_side(policies, make(mode), seeds, stopwatch.progress, max_envs, description=f"tune {name}",
                                         runner=runner)

        stats = stopwatch.timed(f"tune {name}", search)
        rows = [{"action": action, **tuning_row(value, stats[i])} if action else tuning_row(value, stats[i])
                for i, (action, value) in enumerate(candidates)]
        best = min(range(len(rows)), key=lambda i: rows[i]["mean_cost"])
        action, value = candidates[best]
        tuned[name] = (value, action)
        tables[name] = {"obs_mode": mode, "parameter_name": parameter_name, "grid": grid, "best": value, "action": action, "table": rows}
    return tuned, tables
