"""Evaluate a maintenance policy over seeded episodes, and tune a policy parameter by grid search.

``evaluate(policy, env_factory, seeds)`` builds one environment with ``env_factory()`` and runs one
episode per seed (``env.reset(seed=seed)``) to its end (termination or truncation), calling
``policy.predict(observation, state=state, episode_start=...)`` like an SB3 model; with ``batch_size=B`` it
runs up to B episodes side by side on a vector environment ``env_factory(n)`` instead (one batched
``predict`` per step), with the same records. Per episode it records:

- ``cost``: the summed ``info["cost"]["total"]`` (= minus the summed reward), and each item of the
  breakdown summed (``cost_corrective``, ``cost_replacement``, ``cost_failure``, ``cost_lost_production``);
- ``failures``: steps with ``info["failed"]``;
- ``availability``: fraction of the episode's steps the machine was up. A step is down when the machine
  was down at its start (``observation["maintenance_in_progress"]`` before the step) or a replacement
  (ordered or forced by a failure) happened in it. With downtimes >= 1 step (the defaults) these are
  exactly the steps that cost lost production; with a downtime of 0 the replacement step still counts
  as down;
- ``maintenance_actions``: non-zero actions carried out (given while the machine was up), split into
  ``replacements`` and ``corrective_steps``; ``ignored_actions``: non-zero actions given while it was
  down (the environment ignores them);
- ``steps``.

The 95 % confidence interval of the mean cost is the normal approximation mean ± 1.96 s / sqrt(n)
(s the sample standard deviation, ddof = 1): no bootstrap, no randomness in the statistics; it is NaN
(None in ``to_dict``) for fewer than 2 episodes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode

from ea_gym.env.events import ActionKind, Replacement, parse_action, parse_event
from ea_gym.env.infos import COST_ITEMS
from ea_gym.files import finite_or_none

__all__ = ["EpisodeStats", "evaluate", "tune", "tuning_row", "mean_ci95", "COST_BREAKDOWN"]

#: the items an episode's cost is broken down into: the environment's cost items but their total
COST_BREAKDOWN = tuple(item for item in COST_ITEMS if item != "total")
#: the progress bar of ``evaluate``: episodes' worth of steps done, to a tenth
PROGRESS_FORMAT = "{l_bar}{bar}| {n:.1f}/{total:.0f} episodes [{elapsed}<{remaining}]"
_FIELDS = (
    "cost", "failures", "availability", "maintenance_actions", "replacements", "corrective_steps",
    "ignored_actions", "steps", *(f"cost_{item}" for item in COST_BREAKDOWN),
)


def mean_ci95(values: Sequence[float] | np.ndarray) -> tuple[float, float, float]:
    """(mean, low, high): normal approximation mean ± 1.96 sd / sqrt(n), sd with ddof = 1; NaN bounds if n < 2."""
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        raise ValueError("no values")
    mean = float(values.mean())
    if values.size < 2:
        return mean, math.nan, math.nan
    half = 1.96 * float(values.std(ddof=1)) / math.sqrt(values.size)
    return mean, mean - half, mean + half


@dataclass
class EpisodeStats:
    """Per-episode records of one policy and their summaries.

    Attributes:
        seeds: the reset seed of each episode.
        per_episode: name -> array over episodes (see the module docstring for the names).
        policy: the policy's repr.
    """

    seeds: np.ndarray
    per_episode: dict[str, np.ndarray]
    policy: str = ""
    ci_method: str = field(default="normal approximation: mean +- 1.96 sd / sqrt(n), sd with ddof=1")

    @property
    def n(self) -> int:
        return len(self.seeds)

    @property
    def mean_cost(self) -> float:
        return float(np.mean(self.per_episode["cost"]))

    @property
    def ci95(self) -> tuple[float, float]:
        """95 % confidence interval of the mean cost (normal approximation)."""
        _, low, high = mean_ci95(self.per_episode["cost"])
        return low, high

    @property
    def failures(self) -> float:
        """Mean failures per episode."""
        return float(np.mean(self.per_episode["failures"]))

    @property
    def availability(self) -> float:
        """Mean over episodes of the fraction of steps up."""
        return float(np.mean(self.per_episode["availability"]))

    @property
    def maintenance_actions(self) -> float:
        """Mean non-zero actions carried out per episode."""
        return float(np.mean(self.per_episode["maintenance_actions"]))

    @property
    def cost_breakdown(self) -> dict[str, float]:
        """Mean cost per episode of each item."""
        return {item: float(np.mean(self.per_episode[f"cost_{item}"])) for item in COST_BREAKDOWN}

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary and per-episode lists (non-finite numbers as None)."""
        low, high = self.ci95
        return {
            "policy": self.policy,
            "episodes": self.n,
            "mean_cost": self.mean_cost,
            "ci95": [finite_or_none(low), finite_or_none(high)],
            "ci_method": self.ci_method,
            "failures": self.failures,
            "availability": self.availability,
            "maintenance_actions": self.maintenance_actions,
            "replacements": float(np.mean(self.per_episode["replacements"])),
            "corrective_steps": float(np.mean(self.per_episode["corrective_steps"])),
            "cost_breakdown": self.cost_breakdown,
            "seeds": [int(s) for s in self.seeds],
            "per_episode": {key: [finite_or_none(v) for v in np.asarray(values, dtype=float)] for key, values in self.per_episode.items()},
        }


class _Tally:
    """The per-episode records (see the module docstring) of n episodes stepped side by side: n = 1 for
    one environment, n = the batch for a vector environment. Only the episodes marked active at a step
    count it (a vector environment's finished episodes are reset and stepped on, unrecorded)."""

    def __init__(self, n: int, action_meanings: Sequence[str]):
        self.sums = {key: np.zeros(n) for key in _FIELDS if key != "availability"}
        self.down_steps = np.zeros(n)
        kinds = [parse_action(meaning).kind for meaning in action_meanings]
        self._replace = np.array([kind == ActionKind.REPLACE for kind in kinds] + [False])
        self._corrective = np.array([kind == ActionKind.CORRECTIVE for kind in kinds] + [False])

    def step(
        self, actions: np.ndarray, was_down: np.ndarray, costs: Mapping[str, Any], failed: np.ndarray,
        events: Sequence[Sequence[str]], active: np.ndarray,
    ) -> None:
        """Count one step: the actions given (n,), whether each machine was down before it (n,), the step's
        ``info`` entries ``cost`` (item -> (n,)), ``failed`` (n,) and ``events`` (n lists)."""
        s, counted = self.sums, active.astype(float)
        s["steps"] += counted
        s["cost"] += counted * np.asarray(costs["total"], dtype=float)
        for item in COST_BREAKDOWN:
            s[f"cost_{item}"] += counted * np.asarray(costs[item], dtype=float)
        s["failures"] += counted * np.asarray(failed, dtype=bool)
        replaced = np.array([any(isinstance(parse_event(event), Replacement) for event in happened) for happened in events])
        self.down_steps += counted * (was_down | replaced)
        ordered = active & (actions != 0)
        s["ignored_actions"] += ordered & was_down
        carried = ordered & ~was_down
        s["maintenance_actions"] += carried
        known = np.minimum(actions, len(self._replace) - 1)  # an index past the meanings is neither kind
        s["replacements"] += carried & self._replace[known]
        s["corrective_steps"] += carried & self._corrective[known]

    def records(self) -> dict[str, np.ndarray]:
        return {**self.sums, "availability": 1.0 - self.down_steps / self.sums["steps"]}


def _episode(policy: Any, env: Any, seed: int) -> dict[str, float]:
    observation, _ = env.reset(seed=seed)
    tally = _Tally(1, getattr(env.unwrapped, "action_meanings", ()))
    state, start = None, True
    while True:
        action, state = policy.predict(observation, state=state, episode_start=np.array([start]), deterministic=True)
        start = False
        action = np.asarray(action)
        if action.size != 1:
            raise ValueError(f"the policy must return one action for one observation, got shape {action.shape}")
        action = int(action.reshape(-1)[0])
        was_down = bool(np.asarray(observation["maintenance_in_progress"]).reshape(-1)[0] > 0.5)
        observation, _, terminated, truncated, info = env.step(action)
        tally.step(np.array([action]), np.array([was_down]), info["cost"], np.array([info["failed"]]), [info["events"]], np.array([True]))
        if terminated or truncated:
            break
    return {key: float(value[0]) for key, value in tally.records().items()}


def _batch(policy: Any, env: Any, seeds: Sequence[int] | np.ndarray, progress: Any) -> dict[str, np.ndarray]:
    """One episode per seed on a vector environment of ``len(seeds)`` envs, every episode run once to its end."""
    n = len(seeds)
    mode = env.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP)
    if mode != AutoresetMode.NEXT_STEP:  # SAME_STEP puts an episode's last info aside; DISABLED refuses the steps after an end
        raise ValueError(f"a vector environment for evaluation must autoreset in AutoresetMode.NEXT_STEP (Gymnasium's default), got {mode}")
    observation, _ = env.reset(seed=[int(s) for s in seeds])
    tally = _Tally(n, getattr(env.unwrapped, "action_meanings", ()))
    state, start, active = None, np.ones(n, dtype=bool), np.ones(n, dtype=bool)
    # the episodes mostly end together, at the horizon: the bar moves by each step's share of an episode
    horizon, steps, done = _horizon(env), 0, 0.0
    while np.any(active):
        action, state = policy.predict(observation, state=state, episode_start=start, deterministic=True)
        start = np.zeros(n, dtype=bool)
        action = np.asarray(action)
        if action.shape != (n,):
            raise ValueError(f"the policy must return one action per env ({n}) for a batch of observations, got shape {action.shape}")
        action = action.astype(np.int64)
        was_down = np.asarray(observation["maintenance_in_progress"]).reshape(n) > 0.5
        observation, _, terminated, truncated, info = env.step(action)
        tally.step(action, was_down, info["cost"], info["failed"], info["events"], active)
        ended = active & (np.asarray(terminated) | np.asarray(truncated))
        active &= ~ended
        steps += 1
        now = n - active.sum() + (active.sum() * min(steps / horizon, 1.0) if horizon else 0.0)
        progress.update(now - done)
        done = now
    return tally.records()


def _horizon(env: Any) -> int | None:
    """The steps in an episode of ``env`` (an ``ea_gym`` vector environment's horizon), or None where it does not say."""
    core = getattr(env.unwrapped, "core", None)
    return getattr(getattr(core, "config", None), "horizon", None)


def evaluate(
    policy: Any,
    env_factory: Callable[..., Any],
    seeds: Iterable[int],
    progress: bool = True,
    description: str | None = None,
    batch_size: int | None = None,
) -> EpisodeStats:
    """Run one episode per seed and record its numbers.

    Args:
        policy: anything with SB3's ``predict`` (a rule of ``agents.policies`` or an SB3 model), or a
            callable ``policy(env) -> policy`` that builds it from the (first) environment made here.
        env_factory: with ``batch_size`` None, ``() -> env``, e.g. ``lambda: gym.make("ea_gym/SpringMassDamper-v0",
            ...)``: called once, the environment is reset with each seed in turn. With a ``batch_size``,
            ``(n) -> vector env`` of n environments (a gymnasium ``VectorEnv`` that takes a list of
            seeds, e.g. ``lambda n: gym.make_vec(..., num_envs=n, vectorization_mode="vector_entry_point")``).
            Environments are closed at the end.
        seeds: one episode per seed, in order.
        progress: show a tqdm progress bar over the episodes.
        description: the progress bar's label (default the policy's repr).
        batch_size: None, or the most episodes run side by side: the seeds are taken in batches, each
            on one vector environment, every episode run once to its end. The batched environment's
            episodes equal the single environment's bit for bit, so the records are the same (a learned
            policy's batched forward pass may round differently from one observation at a time).
    """
    seeds = np.array([int(s) for s in seeds], dtype=np.int64)
    if seeds.size == 0:
        raise ValueError("seeds must hold at least one seed")
    if batch_size is not None and not (isinstance(batch_size, (int, np.integer)) and batch_size >= 1):
        raise ValueError(f"batch_size must be None or a positive int, got {batch_size!r}")
    from tqdm.auto import tqdm

    label = description
    batches = [seeds] if batch_size is None else [seeds[i : i + batch_size] for i in range(0, seeds.size, batch_size)]
    records: list[dict[str, Any]] = []
    with tqdm(total=seeds.size, desc=label, disable=not progress, leave=False, bar_format=PROGRESS_FORMAT) as bar:
        for batch in batches:
            env = env_factory() if batch_size is None else env_factory(len(batch))
            try:
                if not hasattr(policy, "predict"):
                    if not callable(policy):
                        raise TypeError(f"policy must have a predict method or be a callable env -> policy, got {type(policy).__name__}")
                    policy = policy(env)
                if label is None:
                    label = repr(policy)
                    bar.set_description(label)
                if hasattr(policy, "reset"):
                    policy.reset()
                if batch_size is None:
                    for seed in batch:
                        records.append(_episode(policy, env, int(seed)))
                        bar.update(1)
                else:
                    batched = _batch(policy, env, batch, bar)
                    records += [{key: value[i] for key, value in batched.items()} for i in range(len(batch))]
            finally:
                env.close()
    per_episode = {key: np.array([r[key] for r in records], dtype=float) for key in _FIELDS}
    return EpisodeStats(seeds=seeds, per_episode=per_episode, policy=repr(policy))


def tune(
    policy_factory: Callable[[Any], Any],
    grid: Sequence[Any],
    env_factory: Callable[..., Any],
    seeds: Iterable[int],
    progress: bool = True,
    batch_size: int | None = None,
) -> tuple[Any, list[dict[str, Any]]]:
    """Grid search of one policy parameter on (training) seeds: the value of least mean cost.

    Args:
        policy_factory: ``parameter -> policy`` (or ``parameter -> (env -> policy)``, see ``evaluate``).
        grid: the parameter values tried, in order; ties go to the earlier one.
        env_factory, seeds, progress, batch_size: as in ``evaluate`` (the same seeds for every value).

    Returns:
        (best parameter, table): one JSON-ready row per value with ``parameter``, ``mean_cost``,
        ``ci95``, ``failures``, ``availability``, ``maintenance_actions``, ``cost_breakdown``.
    """
    grid = list(grid)
    if not grid:
        raise ValueError("grid must hold at least one value")
    seeds = list(seeds)
    table = []
    for parameter in grid:
        stats = evaluate(policy_factory(parameter), env_factory, seeds, progress, description=f"tune {parameter!r}", batch_size=batch_size)
        table.append(tuning_row(parameter, stats))
    best = min(range(len(grid)), key=lambda i: table[i]["mean_cost"])
    return grid[best], table


def tuning_row(parameter: Any, stats: EpisodeStats) -> dict[str, Any]:
    """A grid search's JSON-ready row for one value: ``parameter``, ``policy``, ``mean_cost``, ``ci95``,
    ``failures``, ``availability``, ``maintenance_actions``, ``cost_breakdown``."""
    low, high = stats.ci95
    return {
        "parameter": parameter,
        "policy": stats.policy,
        "mean_cost": stats.mean_cost,
        "ci95": [finite_or_none(low), finite_or_none(high)],
        "failures": stats.failures,
        "availability": stats.availability,
        "maintenance_actions": stats.maintenance_actions,
        "cost_breakdown": stats.cost_breakdown,
    }
