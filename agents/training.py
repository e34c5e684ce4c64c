"""Training maintenance policies with stable-baselines3 on the batched environment.

`train` builds the batched `MaintenanceVecEnv` (or a `SubprocVecEnv` of single environments, for
comparison), normalises observations and rewards with `VecNormalize`, and trains PPO, A2C or DQN with a
progress bar, periodic evaluation on held-out seeds, checkpoints and, when tensorboard is installed,
TensorBoard logs. Everything needed to reload the policy (the model and the normalisation statistics)
lands in the output directory.
"""

from __future__ import annotations

import importlib.util
import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
from stable_baselines3 import A2C, DQN, PPO
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback, EvalCallback
from stable_baselines3.common.vec_env import SubprocVecEnv, VecEnv, VecMonitor, VecNormalize

import ea_gym  # noqa: F401 - registers the environments
from ea_gym.env.sb3 import MaintenanceVecEnv
from ea_gym.files import write_json
from ea_gym.threads import single_threaded_torch

ALGORITHMS: dict[str, type[BaseAlgorithm]] = {"ppo": PPO, "a2c": A2C, "dqn": DQN}
ENV_ID = "ea_gym/SpringMassDamper-v0"
#: seeds of the training environments start here; evaluation seeds (agents.evaluation) never overlap
TRAINING_SEED = 1_000
VALIDATION_SEED = 5_000
MODEL_FILE = "model.zip"
NORMALIZATION_FILE = "vecnormalize.pkl"


@dataclass(frozen=True)
class TrainingRun:
    """One training run's settings, written beside the model as ``training.json``."""

    algo: str = "ppo"
    timesteps: int = 200_000
    obs_mode: str = "phm"
    n_envs: int = 16
    seed: int = 0
    vec_env: str = "batched"  # or "subproc"
    eval_every: int = 20_000  # environment steps between evaluations
    eval_episodes: int = 8
    checkpoint_every: int = 50_000
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    hyperparameters: dict[str, Any] = field(default_factory=dict)


def make_vec_env(run: TrainingRun, n_envs: int, seed: int, kind: str | None = None) -> VecEnv:
    """The training (or validation) environments, seeded seed, seed + 1, ..."""
    kind = kind or run.vec_env
    kwargs = {"obs_mode": run.obs_mode, "continue_after_failure": True, **run.env_kwargs}
    if kind == "batched":
        env: VecEnv = MaintenanceVecEnv(n_envs, **kwargs)
    elif kind == "subproc":
        env = SubprocVecEnv([lambda: gym.make(ENV_ID, **kwargs) for _ in range(n_envs)])
    else:
        raise ValueError(f"vec_env must be 'batched' or 'subproc', got {kind!r}")
    env.seed(seed)
    return VecMonitor(env)  # episode returns and lengths for the logs and the evaluation callback


def default_hyperparameters(algo: str, n_envs: int) -> dict[str, Any]:
    """Settings that train in minutes on two cores (episodes are 500 steps)."""
    if algo == "ppo":
        return {"n_steps": max(2048 // n_envs, 32), "batch_size": 256, "n_epochs": 5, "gamma": 0.99,
                "gae_lambda": 0.95, "learning_rate": 3e-4, "ent_coef": 0.01}
    if algo == "a2c":
        return {"n_steps": 16, "gamma": 0.99, "learning_rate": 7e-4, "ent_coef": 0.01}
    return {"buffer_size": 100_000, "learning_starts": 5_000, "batch_size": 256, "gamma": 0.99,
            "exploration_fraction": 0.2, "target_update_interval": 2_000, "train_freq": 4}


def train(run: TrainingRun, out: Path, resume: Path | None = None, progress_bar: bool = True) -> dict[str, Any]:
    """Train, evaluate and checkpoint; returns the summary written to ``out/training.json``.

    Args:
        resume: a checkpoint (``.zip``) to continue from; its ``vecnormalize`` file is picked up beside it.
    """
    if run.algo not in ALGORITHMS:
        raise ValueError(f"algo must be one of {sorted(ALGORITHMS)}, got {run.algo!r}")
    if run.timesteps <= 0 or run.n_envs <= 0:
        raise ValueError(f"timesteps and n_envs must be positive, got {run.timesteps} and {run.n_envs}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    algorithm = ALGORITHMS[run.algo]
    env = make_vec_env(run, run.n_envs, TRAINING_SEED + run.seed * run.n_envs)
    evaluation_env = make_vec_env(run, 1, VALIDATION_SEED, kind="batched")
    if resume is not None:
        env = VecNormalize.load(str(_normalization_beside(resume)), env)
        model = algorithm.load(str(resume), env=env, seed=run.seed)
    else:
        env = VecNormalize(env, norm_obs=True, norm_reward=True, gamma=0.99)
        hyperparameters = {**default_hyperparameters(run.algo, run.n_envs), **run.hyperparameters}
        tensorboard = str(out / "tensorboard") if importlib.util.find_spec("tensorboard") else None
        model = algorithm("MultiInputPolicy", env, seed=run.seed, verbose=0, tensorboard_log=tensorboard, **hyperparameters)
    evaluation_env = VecNormalize(evaluation_env, norm_obs=True, norm_reward=False, training=False)
    evaluation_env.obs_rms = env.obs_rms
    steps_per_call = max(run.n_envs, 1)
    callbacks = CallbackList([
        EvalCallback(evaluation_env, n_eval_episodes=run.eval_episodes, eval_freq=max(run.eval_every // steps_per_call, 1),
                     best_model_save_path=str(out / "best"), log_path=str(out / "evaluations"), deterministic=True),
        CheckpointCallback(save_freq=max(run.checkpoint_every // steps_per_call, 1), save_path=str(out / "checkpoints"),
                           name_prefix=run.algo, save_vecnormalize=True),
    ])
    started = time.perf_counter()
    # the environments' numpy shares the process: a second torch thread fights its BLAS threads (20x slower here)
    with single_threaded_torch():
        model.learn(total_timesteps=run.timesteps, callback=callbacks, progress_bar=progress_bar, reset_num_timesteps=resume is None)
    wall = time.perf_counter() - started
    model.save(str(out / MODEL_FILE))
    env.save(str(out / NORMALIZATION_FILE))
    summary = {"run": asdict(run), "wall_time_s": round(wall, 1), "steps_per_s": round(run.timesteps / wall, 1),
               "resumed_from": None if resume is None else str(resume)}
    write_json(out / "training.json", summary)
    env.close()
    return summary


def _normalization_beside(checkpoint: Path) -> Path:
    """CheckpointCallback names it ``<prefix>_vecnormalize_<steps>_steps.pkl`` next to ``<prefix>_<steps>_steps.zip``."""
    checkpoint = Path(checkpoint)
    if checkpoint.name == MODEL_FILE:
        return checkpoint.with_name(NORMALIZATION_FILE)
    prefix, steps = checkpoint.stem.rsplit("_", 2)[0], checkpoint.stem.rsplit("_", 2)[1]
    return checkpoint.with_name(f"{prefix}_vecnormalize_{steps}_steps.pkl")


def load_policy(directory: Path, obs_mode: str | None = None):
    """A trained policy with SB3's ``predict``, normalising raw observations as during training."""
    directory = Path(directory)
    summary = json.loads((directory / "training.json").read_text())
    algorithm = ALGORITHMS[summary["run"]["algo"]]
    model = algorithm.load(str(directory / MODEL_FILE), device="cpu")
    run = TrainingRun(**{**summary["run"], "n_envs": 1})
    normalization = VecNormalize.load(str(directory / NORMALIZATION_FILE), make_vec_env(run, 1, 0, kind="batched"))
    normalization.training = False
    return NormalizedPolicy(model, normalization, obs_mode or run.obs_mode)


@dataclass
class NormalizedPolicy:
    """A trained model with the observation normalisation it was trained with."""

    model: BaseAlgorithm
    normalization: VecNormalize
    obs_mode: str

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        batched = observation["time_since_maintenance"].ndim == 2
        batch = observation if batched else {key: value[None] for key, value in observation.items()}
        actions, state = self.model.predict(self.normalization.normalize_obs(batch), state, episode_start, deterministic)
        return (actions if batched else actions[0]), state
