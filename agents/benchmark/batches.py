"""Many policies' episodes side by side on one vector environment.

The benchmark evaluates several policies that read the same obs_mode on the same seeds, and the
tuning evaluates every value of a grid on the same seeds. Each environment step of the PHM chain
costs less per system the more systems it steps at once (8,750 against 6,040 env-steps/s of CPU for
150 against 50 systems here), so ``evaluate_side_by_side`` gives each policy a block of one vector
environment: block i holds policy i's episodes, and ``Blocks`` hands each policy its block's
observations. The episodes are the ones each policy would meet alone (the batched environment's
episodes equal the single environment's bit for bit).
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Mapping, Sequence
from functools import partial
from typing import Any, TypeVar

import numpy as np

from agents.benchmark.runners import BatchRunner, LocalRunner
from agents.evaluation import EpisodeStats, evaluate
from agents.policies import Policy

__all__ = ["Blocks", "evaluate_side_by_side"]

Key = TypeVar("Key", bound=Hashable)


class Blocks:
    """One policy per block of ``block`` consecutive environments of a vector environment.

    ``predict`` splits the batched observation (every entry's leading axis) into the blocks, asks each
    policy for its block's actions with its own recurrent state, and concatenates them.
    """

    def __init__(self, policies: Sequence[Policy], block: int):
        if block < 1 or not policies:
            raise ValueError("Blocks needs at least one policy and a block of at least one environment")
        self.policies = list(policies)
        self.block = int(block)
        self._states: list[Any] = [None] * len(self.policies)

    def reset(self) -> None:
        self._states = [None] * len(self.policies)
        for policy in self.policies:
            reset = getattr(policy, "reset", None)
            if reset is not None:
                reset()

    def predict(
        self, observation: Mapping[str, Any], state: Any = None, episode_start: Any = None, deterministic: bool = True,
    ) -> tuple[np.ndarray, None]:
        n = self.block * len(self.policies)
        starts = np.ones(n, dtype=bool) if episode_start is None else np.asarray(episode_start, dtype=bool).reshape(n)
        actions = []
        for i, policy in enumerate(self.policies):
            part = slice(i * self.block, (i + 1) * self.block)
            view = {key: np.asarray(value)[part] for key, value in observation.items()}
            action, self._states[i] = policy.predict(view, state=self._states[i], episode_start=starts[part], deterministic=deterministic)
            actions.append(np.asarray(action, dtype=np.int64).reshape(self.block))
        return np.concatenate(actions), None

    def __repr__(self) -> str:
        return f"Blocks({', '.join(map(repr, self.policies))}; {self.block} each)"


def evaluate_side_by_side(
    policies: Mapping[Key, Policy],
    make_env: Callable[[int], Any],
    seeds: range | Sequence[int],
    progress: bool,
    max_envs: int,
    description: str = "",
    runner: BatchRunner | None = None,
) -> dict[Key, EpisodeStats]:
    """Every policy on every seed, as many policies per vector environment as ``max_envs`` systems allow.

    Args:
        policies: key -> policy (SB3's ``predict``); each appears at most once per vector environment,
            so a policy's memory between steps stays its own.
        make_env: ``(n) -> vector environment`` of n systems (``settings.vector_env_factory``).
        seeds: one episode per seed and policy.
        progress: a progress bar per vector environment.
        max_envs: the most systems stepped at once (seeds are split into chunks of at most this many).
        description: the progress bars' label.
        runner: where the batches (one vector environment each) run: ``runners.LocalRunner`` (None) or
            ``runners.RayRunner``, which also splits the seeds into a chunk per worker at least.

    Returns:
        key -> that policy's records, its seeds in the order given.
    """
    episodes = np.array([int(s) for s in seeds], dtype=np.int64)
    keys = list(policies)
    if episodes.size == 0 or not keys:
        raise ValueError("evaluate_side_by_side needs at least one seed and one policy")
    if max_envs < 1:
        raise ValueError(f"max_envs must be >= 1, got {max_envs}")
    runner = runner or LocalRunner()
    size = runner.chunk(episodes.size, max_envs)
    batches, groups = [], []  # one vector environment each: a chunk of seeds for a group of policies
    for start in range(0, episodes.size, size):
        chunk = episodes[start : start + size]
        per_env = max(1, max_envs // chunk.size)  # policies per vector environment
        for first in range(0, len(keys), per_env):
            group = keys[first : first + per_env]
            joint = Blocks([policies[key] for key in group], chunk.size)
            batches.append(partial(evaluate, joint, make_env, np.tile(chunk, len(group)), progress and not runner.remote,
                                   description=description, batch_size=chunk.size * len(group)))
            groups.append((group, chunk.size))
    parts: dict[Key, list[EpisodeStats]] = {key: [] for key in keys}
    for (group, n), stats in zip(groups, runner.run(batches)):
        for i, key in enumerate(group):
            part = slice(i * n, (i + 1) * n)
            parts[key].append(EpisodeStats(seeds=stats.seeds[part], per_episode={k: v[part] for k, v in stats.per_episode.items()},
                                           policy=repr(policies[key])))
    return {key: _joined(runs) for key, runs in parts.items()}


def _joined(runs: list[EpisodeStats]) -> EpisodeStats:
    """One policy's records over consecutive seed chunks."""
    if len(runs) == 1:
        return runs[0]
    per_episode = {key: np.concatenate([run.per_episode[key] for run in runs]) for key in runs[0].per_episode}
    return EpisodeStats(seeds=np.concatenate([run.seeds for run in runs]), per_episode=per_episode, policy=runs[0].policy)
