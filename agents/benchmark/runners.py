"""Where the benchmark's batches of episodes run: one after another in this process, or as Ray tasks.

A batch is one ``agents.evaluation.evaluate`` call: a policy (or several side by side,
``batches.Blocks``) on one vector environment of a chunk of seeds; or one timeline episode
(``timelines.record_timeline``). An episode depends on its seed alone, so the records are the same
wherever and in whatever chunks the batches run. ``RayRunner``
sends each batch to a Ray task (one CPU each) on a local Ray or a cluster (``ray start --head``;
every node needs ea-gym installed) and splits the seeds into at least as many chunks as the cluster
has CPUs. A trained agent travels as its files' bytes and is loaded on the worker
(``agents.portable_agent``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Protocol, TypeVar

__all__ = ["Batch", "BatchRunner", "LocalRunner", "RayRunner", "runner_for"]

Result = TypeVar("Result")
#: one batch of episodes: ``() -> Result`` (``agents.evaluation.EpisodeStats``, or a timeline's record)
Batch = Callable[[], Result]


class BatchRunner(Protocol):
    """Runs batches of episodes; ``workers`` is how many run at once, ``remote`` whether elsewhere (no progress bars)."""

    workers: int
    remote: bool

    def run(self, batches: Sequence[Batch[Result]]) -> list[Result]:
        """Every batch's records, in the order given."""
        ...

    def chunk(self, seeds: int, max_envs: int) -> int:
        """The most seeds one batch takes, of ``seeds`` to share out, at most ``max_envs`` systems per batch."""
        ...


class LocalRunner:
    """The batches one after another in this process."""

    workers = 1
    remote = False

    def run(self, batches: Sequence[Batch[Result]]) -> list[Result]:
        return [batch() for batch in batches]

    def chunk(self, seeds: int, max_envs: int) -> int:
        return max_envs


class RayRunner:
    """Each batch a Ray task of one CPU.

    Args:
        address: a cluster's address (``"auto"``, or ``HOST:PORT`` of ``ray start --head``); None starts a
            local Ray of ``num_cpus`` CPUs (None: every core), unless this process already joined one.
    """

    remote = True

    def __init__(self, address: str | None = None, num_cpus: int | None = None):
        from agents.ray_cluster import connect, require_ray

        require_ray("--ray")
        self._ray = connect(address, num_cpus)
        self.workers = max(1, int(self._ray.cluster_resources().get("CPU", 1)))
        self._task = self._ray.remote(num_cpus=1)(_run_batch)

    def run(self, batches: Sequence[Batch[Result]]) -> list[Result]:
        return list(self._ray.get([self._task.remote(batch) for batch in batches]))

    def chunk(self, seeds: int, max_envs: int) -> int:
        return max(1, min(max_envs, math.ceil(seeds / self.workers)))  # a chunk per worker at least


def _run_batch(batch: Batch[Result]) -> Result:
    """A Ray task's body: torch on one thread, as in the local run (the isolation network is small)."""
    from ea_gym.threads import single_threaded_torch

    with single_threaded_torch():
        return batch()


def runner_for(ray: str | None, pickled_agents: Sequence[Path] = ()) -> BatchRunner:
    """``LocalRunner`` for None; ``RayRunner`` for ``"local"`` (a local Ray) or a cluster's address. Trained agents
    travel to the workers as their files' bytes (``agents.portable_agent``), but not agents of stable-baselines3's
    files (``pickled_agents``), which would be unpickled there: those are refused with Ray."""
    if ray is None:
        return LocalRunner()
    if pickled_agents:
        raise ValueError(f"--ray sends agent directories to the workers, not stable-baselines3's files ({pickled_agents[0]}): "
                         "convert them first with ea-gym convert-agent SRC DST --trust-pickle")
    return RayRunner(None if ray == "local" else ray)
