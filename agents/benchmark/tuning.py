"""Tuning the rule-based policies: each rule's grid searched on the tuning seeds, the best value kept."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from functools import partial
from typing import Any

from agents.benchmark.settings import ACTIONS, DEFAULT_GRIDS, QUIET_BAND, RULES
from agents.benchmark.stopwatch import Stopwatch
from agents.evaluation import tune
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


def _search(builder: RuleBuilder, action: str | None, grid: Sequence[Any], make_env: Callable[[int], Any], seeds: range,
            progress: bool, batch_size: int) -> tuple[Any, list[dict[str, Any]]]:
    """One rule's grid search with one action: (the best value, the table)."""
    return tune(lambda value: builder(value, action), grid, make_env, seeds, progress, batch_size)


def tune_rules(
    grids: Mapping[str, Sequence[Any]],
    builders: Mapping[str, RuleBuilder],
    make: Callable[[str], Any],
    seeds: range,
    stopwatch: Stopwatch,
    batch_size: int,
) -> tuple[dict[str, tuple[Any, str | None]], dict[str, Any]]:
    """Grid-search every tuned rule (``DEFAULT_GRIDS``' names) on ``seeds``.

    Args:
        grids: the values to try per rule; the oracle and RulThreshold try each with every one of ``ACTIONS``.
        builders: ``rule_builders``.
        make: obs_mode -> vector environment factory (``vector_env_factory``).
        seeds: the tuning seeds.
        stopwatch: times each search; its ``progress`` shows progress bars.
        batch_size: the most episodes run side by side.

    Returns:
        ``tuned``: name -> (best value, its action or None); ``tables``: name -> the search's table
        (obs_mode, parameter_name, grid, best, action, one row per value and action).
    """
    tuned: dict[str, tuple[Any, str | None]] = {}
    tables: dict[str, Any] = {}
    for name in DEFAULT_GRIDS:
        _, mode, parameter_name = RULES[name]
        grid = [_parameter(v) for v in grids[name]]
        candidates = []  # (mean cost, value, action) of the best value per action
        rows: list[dict[str, Any]] = []
        for action in ACTIONS if name in ("oracle", "rul_threshold") else (None,):
            search = partial(_search, builders[name], action, grid, make(mode), seeds, stopwatch.progress, batch_size)
            best, table = stopwatch.timed(f"tune {name}" + (f" ({action})" if action else ""), search)
            candidates.append((min(r["mean_cost"] for r in table), best, action))
            rows += [{"action": action, **r} if action else r for r in table]
        _, best, action = min(candidates, key=lambda c: c[0])  # ties go to the earlier action
        tuned[name] = (best, action)
        tables[name] = {"obs_mode": mode, "parameter_name": parameter_name, "grid": grid, "best": best, "action": action, "table": rows}
    return tuned, tables
