"""Training PPO with Ray RLlib (new API stack) on the native vector environment.

The environment reaches RLlib's env runners, which are other processes (on other machines with a
cluster), as an env creator registered under ``ENV_ID`` with ``ray.tune.registry.register_env``:
RLlib calls it with ``num_envs`` (its vector entry point) and gets the native vector environment
(``gym_env_vectorize_mode="vector_entry_point"``), which autoresets in gymnasium's NEXT_STEP mode,
the one RLlib's env runners assume; ``vectorize="sync"`` instead gives RLlib single environments to
wrap in gymnasium's ``SyncVectorEnv`` (its default). The creator is imported by name in the workers,
so ea-gym must be installed there. The Dict observation is flattened and standardised by RLlib's
``FlattenObservations`` and ``MeanStdFilter`` connectors.

Every finished episode is counted by its end (``EPISODE_COUNTS``): 500 steps (the horizon) unless the
machine failed (only without ``continue_after_failure``). RLlib and Ray are imported inside the
functions: the optional extra ``ea-gym[rllib]``.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

from agents.conventions import SUMMARY_FILE, TRAINING_SEED
from ea_gym.env import ENV_ID
from ea_gym.files import json_ready, write_json

__all__ = ["RLlibRun", "EPISODE_COUNTS", "env_creator", "register", "ppo_config", "build_algorithm", "train_iterations", "train_rllib"]

#: the counters of finished episodes in RLlib's env-runner metrics: horizon (truncated at the horizon),
#: failed (terminated by a failure) and other (any other length: wrong episode boundaries)
EPISODE_COUNTS = ("episodes_at_horizon", "episodes_failed", "episodes_other_length")
VECTORIZE_MODES = ("vector_entry_point", "sync")
CHECKPOINT_DIR = "rllib_checkpoint"


@dataclass(frozen=True)
class RLlibRun:
    """One RLlib PPO run's settings, written into ``training.json``."""

    timesteps: int = 200_000
    obs_mode: str = "phm"
    num_env_runners: int = 2
    envs_per_env_runner: int = 8
    vectorize: str = "vector_entry_point"  # the native vector env, or "sync": gymnasium's SyncVectorEnv of single envs
    seed: int = 0
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    hyperparameters: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("timesteps", "num_env_runners", "envs_per_env_runner"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= (0 if name == "num_env_runners" else 1)):
                raise ValueError(f"{name} must be an integer >= {0 if name == 'num_env_runners' else 1}, got {value!r}")
        if self.vectorize not in VECTORIZE_MODES:
            raise ValueError(f"vectorize must be one of {VECTORIZE_MODES}, got {self.vectorize!r}")

    @property
    def env_config(self) -> dict[str, Any]:
        """The environment's keyword arguments (``continue_after_failure`` as in ``ea-gym train``)."""
        return {"obs_mode": self.obs_mode, "continue_after_failure": True, **self.env_kwargs}


def env_creator(config: Mapping[str, Any]) -> Any:
    """RLlib's env creator: the native vector environment of ``config["num_envs"]`` systems when RLlib asks
    for a vector (its vector entry point), else one environment; the rest of ``config`` are the
    environment's keyword arguments."""
    import gymnasium as gym

    import ea_gym  # noqa: F401 - registers the environments in this worker

    kwargs = {key: value for key, value in dict(config).items() if key != "num_envs"}
    if "num_envs" in config:
        return gym.make_vec(ENV_ID, num_envs=int(config["num_envs"]), vectorization_mode="vector_entry_point", **kwargs)
    return gym.make(ENV_ID, **kwargs)


def register() -> str:
    """Register ``env_creator`` with Ray Tune's registry under ``ENV_ID`` (seen by every worker); returns the name."""
    from ray.tune.registry import register_env

    register_env(ENV_ID, env_creator)
    return ENV_ID


def count_episode(*, episode: Any, metrics_logger: Any, horizon: int, **_: Any) -> None:
    """RLlib's ``on_episode_end`` callback: one more episode in one of ``EPISODE_COUNTS``."""
    if episode.is_terminated:
        kind = EPISODE_COUNTS[1]
    elif len(episode) == horizon and episode.is_truncated:
        kind = EPISODE_COUNTS[0]
    else:
        kind = EPISODE_COUNTS[2]
    metrics_logger.log_value(kind, 1, reduce="lifetime_sum")


def default_hyperparameters(run: RLlibRun) -> dict[str, Any]:
    """PPO's settings: a batch of 4000 steps (8 episodes of 500 steps), the SB3 trainer's learning rate and entropy bonus."""
    return {"train_batch_size_per_learner": 4000, "minibatch_size": 500, "num_epochs": 5, "lr": 3e-4, "gamma": 0.99,
            "lambda_": 0.95, "entropy_coeff": 0.01, "vf_clip_param": 1e4}


def ppo_config(run: RLlibRun) -> Any:
    """RLlib's ``PPOConfig`` of ``run`` (registers the env creator first)."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.connectors.env_to_module import FlattenObservations, MeanStdFilter

    from ea_gym.env.config import EnvConfig

    horizon = int(run.env_config.get("horizon", EnvConfig().horizon))
    return (
        PPOConfig()
        .environment(register(), env_config=run.env_config)
        .env_runners(
            num_env_runners=run.num_env_runners,
            num_envs_per_env_runner=run.envs_per_env_runner,
            gym_env_vectorize_mode=run.vectorize,
            sample_timeout_s=None,  # the PHM chain steps slowly on a loaded machine: wait for every env runner's batch
            env_to_module_connector=lambda env, spaces=None, device=None: [FlattenObservations(), MeanStdFilter()],
        )
        .training(**{**default_hyperparameters(run), **run.hyperparameters})
        .callbacks(on_episode_end=partial(count_episode, horizon=horizon))
        .debugging(seed=TRAINING_SEED + run.seed)
    )


def build_algorithm(run: RLlibRun, address: str | None = None, num_cpus: int | None = None) -> Any:
    """RLlib's PPO of ``run``, its env runners started on Ray (``ray_cluster.connect(address, num_cpus)``)."""
    from agents.ray_cluster import connect

    connect(address, num_cpus)
    return ppo_config(run).build_algo()


def train_iterations(algorithm: Any, timesteps: int, say: Any = print) -> list[dict[str, Any]]:
    """``algorithm.train()`` until ``timesteps`` environment steps were sampled; each iteration's figures
    (``iteration_s``: its wall time, sampling and learning), one line each to ``say``."""
    from ea_gym.threads import single_threaded_torch

    iterations: list[dict[str, Any]] = []
    with single_threaded_torch():  # the learner shares the driver's cores with the env runners
        while not iterations or iterations[-1]["env_steps_sampled"] < timesteps:
            started = time.perf_counter()
            result = algorithm.train()
            iterations.append({**_iteration(result), "iteration_s": round(time.perf_counter() - started, 2)})
            say(_line(iterations[-1]))
    return iterations


def train_rllib(
    run: RLlibRun, out: Path, address: str | None = None, num_cpus: int | None = None, say: Any = print, checkpoint: bool = True,
) -> dict[str, Any]:
    """Train PPO for ``run.timesteps`` environment steps; write ``out/training.json`` and, with ``checkpoint``,
    RLlib's checkpoint (``out/rllib_checkpoint``, RLlib's own format). Returns the summary written.

    Args:
        address: a Ray cluster's address (``"auto"`` or ``HOST:PORT``); None starts a local Ray.
        num_cpus: the local Ray's CPUs (None: every core); unused with an address.
        say: where the one line per iteration goes.
    """
    import ray

    out = Path(out)
    algorithm = build_algorithm(run, address, num_cpus)
    started = time.perf_counter()
    iterations = train_iterations(algorithm, run.timesteps, say)
    wall = time.perf_counter() - started
    out.mkdir(parents=True, exist_ok=True)
    if checkpoint:
        algorithm.save_to_path(str((out / CHECKPOINT_DIR).resolve()))
    algorithm.stop()
    last = iterations[-1]
    summary = json_ready({
        "run": asdict(run), "backend": "rllib", "ray": ray.__version__, "address": address or "local",
        "wall_time_s": round(wall, 1), "steps_per_s": round(last["env_steps_sampled"] / wall, 1), "env_steps_sampled": last["env_steps_sampled"],
        "episodes": {kind: last[kind] for kind in EPISODE_COUNTS}, "iterations": iterations, "checkpoint": CHECKPOINT_DIR if checkpoint else None,
    })
    write_json(out / SUMMARY_FILE, summary)
    return summary


def _iteration(result: Mapping[str, Any]) -> dict[str, Any]:
    """The figures kept of one ``Algorithm.train()`` result (RLlib's episode lengths and returns are over
    its smoothing window of recent episodes; the episode counts are lifetime sums)."""
    runners = result.get("env_runners", {})
    return json_ready({
        "iteration": result.get("training_iteration"),
        "env_steps_sampled": int(result.get("num_env_steps_sampled_lifetime", runners.get("num_env_steps_sampled_lifetime", 0))),
        "episode_return_mean": runners.get("episode_return_mean"),
        "episode_len_min": runners.get("episode_len_min"),
        "episode_len_max": runners.get("episode_len_max"),
        **{kind: int(runners.get(kind, 0)) for kind in EPISODE_COUNTS},
    })


def _line(iteration: Mapping[str, Any]) -> str:
    lengths = f"{iteration['episode_len_min']}-{iteration['episode_len_max']}"
    counts = ", ".join(f"{kind} {iteration[kind]}" for kind in EPISODE_COUNTS)
    return (f"iteration {iteration['iteration']}: {iteration['env_steps_sampled']} steps, return {iteration['episode_return_mean']}, "
            f"episode lengths {lengths}; {counts}")
