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
import shutil
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, cast

import gymnasium as gym
import numpy as np
from stable_baselines3 import A2C, DQN, PPO
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback, EvalCallback
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.vec_env import SubprocVecEnv, VecEnv, VecMonitor, VecNormalize

import ea_gym  # noqa: F401 - registers the environments
from agents.conventions import MODEL_FILE, NORMALIZATION_FILE, SUMMARY_FILE, TRAINING_SEED, VALIDATION_SEED
from agents.imitation import clone
from agents.observations import LearnerView, normalised_keys
from ea_gym.env import ENV_ID
from ea_gym.env.sb3 import MaintenanceVecEnv
from ea_gym.files import write_json
from ea_gym.threads import single_threaded_torch

ALGORITHMS: dict[str, type[BaseAlgorithm]] = {"ppo": PPO, "a2c": A2C, "dqn": DQN}


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
    eval_episodes: int = 32  # validation episodes per evaluation: 8 gave rewards too noisy to pick a checkpoint by
    checkpoint_every: int = 50_000
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    hyperparameters: dict[str, Any] = field(default_factory=dict)
    teacher: str | None = None  # a rule of TEACHERS cloned before learning (PPO and A2C only)
    teacher_parameter: float | dict[str, float] | None = None  # its threshold or period (s) or band(s); None: TEACHERS' default
    teacher_steps: int = 100_000  # environment steps the teacher runs for the cloning (and each DAgger round)
    dagger_rounds: int = 0  # DAgger rounds after the cloning: the learner acts, the teacher labels (agents.imitation)
    activity: bool = True  # the learner also sees each element's EA on a log scale (agents.observations); runs saved without the field did not


#: rule policies a learner can start from (``agents.imitation``): class, default parameter, keyword
#: arguments. The defaults: the benchmark's tuned oracle threshold and period (s,
#: experiments/results/benchmark); 10 s for the RUL threshold, the best of 5, 10 and 15 s on 60
#: development episodes (seeds 300030 on), where the benchmark's 5 s failed 5 times and 10 s once;
#: "corrective_band", CorrectiveBand's bands of an earlier chain's benchmark; "corrective_band_quiet" adds
#: the damper's quiet band, with the bands of the current chain (92.9 per episode on the 300 tuning
#: seeds, against 92.0 for the damper's 0.7 and 93.6 for the storage parts' 0.8: the wider margin of the
#: two near-best, for a clone that acts a step late)
TEACHERS: dict[str, tuple[str, float | dict[str, float], dict[str, Any]]] = {
    "rul_threshold": ("RulThreshold", 10.0, {}),
    "corrective_band": ("CorrectiveBand", {"k": 0.8, "m": 0.8, "b": 0.4}, {}),
    "corrective_band_quiet": ("CorrectiveBand", {"k": 0.85, "m": 0.85, "b": 0.6}, {"quiet_band": {"b": 0.3}}),
    "oracle": ("Oracle", 2.0, {}),
    "oracle_corrective": ("Oracle", 2.0, {"action": "corrective"}),
    "periodic": ("Periodic", 120.0, {}),
}


def make_teacher(run: TrainingRun, env: VecEnv) -> Any:
    """The rule policy ``run.teacher`` for ``env`` (it refuses an obs_mode it cannot read)."""
    from agents import policies

    if run.teacher not in TEACHERS:
        raise ValueError(f"teacher must be one of {sorted(TEACHERS)}, got {run.teacher!r}")
    name, default, kwargs = TEACHERS[run.teacher]
    return getattr(policies, name)(env, default if run.teacher_parameter is None else run.teacher_parameter, **kwargs)


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
    # VecMonitor: episode returns and lengths for the logs and the evaluation callback
    return LearnerView(VecMonitor(env), activity=run.activity)


def normalize(env: VecEnv, training: bool = True) -> VecNormalize:
    """Standardise the unbounded observation keys (see ``agents.observations``) and the rewards."""
    return VecNormalize(env, training=training, norm_obs=True, norm_reward=training, gamma=0.99,
                        norm_obs_keys=normalised_keys(cast(gym.spaces.Dict, env.observation_space)))


def default_hyperparameters(algo: str, n_envs: int, cloned: bool = False) -> dict[str, Any]:
    """Settings that train in minutes on two cores (episodes are 500 steps).

    A policy cloned from a teacher is fine-tuned gently (smaller steps and clipping, no entropy bonus)
    so that the first updates, on a value function fitted to the teacher, do not undo the cloning.
    """
    if algo == "ppo":
        if cloned:
            return {"n_steps": max(4096 // n_envs, 32), "batch_size": 512, "n_epochs": 5, "gamma": 0.99,
                    "gae_lambda": 0.95, "learning_rate": 5e-5, "ent_coef": 0.0, "clip_range": 0.1}
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
    if run.dagger_rounds and run.teacher is None:
        raise ValueError(f"dagger_rounds ({run.dagger_rounds}) needs a teacher to label the learner's steps")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    algorithm = ALGORITHMS[run.algo]
    env = make_vec_env(run, run.n_envs, TRAINING_SEED + run.seed * run.n_envs)
    # validation episodes run 8 at a time on the batched env
    evaluation_env = make_vec_env(run, min(run.eval_episodes, 8), VALIDATION_SEED, kind="batched")
    if resume is not None:
        env = VecNormalize.load(str(_normalization_beside(resume)), env)
        model = algorithm.load(str(resume), env=env, seed=run.seed)
    else:
        env = normalize(env)
        hyperparameters = {**default_hyperparameters(run.algo, run.n_envs, cloned=run.teacher is not None), **run.hyperparameters}
        tensorboard = str(out / "tensorboard") if importlib.util.find_spec("tensorboard") else None
        model = algorithm("MultiInputPolicy", env, seed=run.seed, verbose=0, tensorboard_log=tensorboard, **hyperparameters)
    evaluation_env = normalize(evaluation_env, training=False)
    evaluation_env.obs_rms = env.obs_rms
    started = time.perf_counter()
    cloning = None
    if run.teacher is not None and resume is None:
        if run.algo == "dqn":
            raise ValueError("a teacher can only be cloned into PPO or A2C (an actor-critic), not DQN")
        with single_threaded_torch():
            learner, view = cast(OnPolicyAlgorithm, model), cast(LearnerView, env.venv)  # PPO or A2C; make_vec_env wraps a LearnerView
            cloning = asdict(clone(learner, env, make_teacher(run, env), run.teacher_steps, restore=view.inverse, dagger_rounds=run.dagger_rounds))
            # the cloned policy is a candidate too: reinforcement learning must beat it to replace it
            rewards, _ = evaluate_policy(model, evaluation_env, n_eval_episodes=run.eval_episodes, deterministic=True)
        cloning["validation_reward"] = float(np.mean(rewards))
        _checkpoint(model, env, out, run.algo, 0)
    steps_per_call = max(run.n_envs, 1)
    callbacks = CallbackList([
        EvalCallback(evaluation_env, n_eval_episodes=run.eval_episodes, eval_freq=max(run.eval_every // steps_per_call, 1),
                     best_model_save_path=str(out / "best"), log_path=str(out / "evaluations"), deterministic=True),
        CheckpointCallback(save_freq=max(run.checkpoint_every // steps_per_call, 1), save_path=str(out / "checkpoints"),
                           name_prefix=run.algo, save_vecnormalize=True),
    ])
    # the environments' numpy shares the process: a second torch thread fights its BLAS threads (20x slower here)
    with single_threaded_torch():
        model.learn(total_timesteps=run.timesteps, callback=callbacks, progress_bar=progress_bar, reset_num_timesteps=resume is None)
    wall = time.perf_counter() - started
    _checkpoint(model, env, out, run.algo, model.num_timesteps)
    selected = _select(out, run, cloning, model.num_timesteps)
    summary = {"run": asdict(run), "wall_time_s": round(wall, 1), "steps_per_s": round(run.timesteps / wall, 1),
               "resumed_from": None if resume is None else str(resume), "cloning": cloning, "selected": selected}
    write_json(out / SUMMARY_FILE, summary)
    env.close()
    return summary


def _checkpoint(model: BaseAlgorithm, env: VecNormalize, out: Path, algo: str, steps: int) -> None:
    """Save the model and its normalisation under CheckpointCallback's names."""
    (out / "checkpoints").mkdir(parents=True, exist_ok=True)
    model.save(str(out / "checkpoints" / f"{algo}_{steps}_steps.zip"))
    env.save(str(out / "checkpoints" / f"{algo}_vecnormalize_{steps}_steps.pkl"))


def _select(out: Path, run: TrainingRun, cloning: dict[str, Any] | None, final_steps: int) -> dict[str, Any]:
    """Copy the checkpoint with the best validation reward to ``out/model.zip`` and its normalisation to
    ``out/vecnormalize.pkl``; the final model when no checkpoint was evaluated.

    Candidates are the checkpoints taken at an evaluation (``checkpoint_every`` a multiple of
    ``eval_every``) and the cloned policy before learning.
    """
    checkpoints = out / "checkpoints"
    candidates: list[tuple[float, str]] = []
    if cloning is not None:
        candidates.append((cloning["validation_reward"], "0"))
    log = out / "evaluations" / "evaluations.npz"
    if log.is_file():
        with np.load(log) as evaluations:
            for steps, rewards in zip(evaluations["timesteps"], evaluations["results"]):
                if (checkpoints / f"{run.algo}_{steps}_steps.zip").is_file():
                    candidates.append((float(np.mean(rewards)), str(steps)))
    if candidates:
        best_reward, best = max(candidates, key=lambda c: c[0])
        why = f"best mean validation reward ({best_reward:.1f} over {run.eval_episodes} validation episodes)"
    else:
        best, why = str(final_steps), "no evaluated checkpoint: the final model"
    shutil.copyfile(checkpoints / f"{run.algo}_{best}_steps.zip", out / MODEL_FILE)
    shutil.copyfile(checkpoints / f"{run.algo}_vecnormalize_{best}_steps.pkl", out / NORMALIZATION_FILE)
    return {"checkpoint": f"{best} steps", "why": why}


def _normalization_beside(checkpoint: Path) -> Path:
    """CheckpointCallback names it ``<prefix>_vecnormalize_<steps>_steps.pkl`` next to ``<prefix>_<steps>_steps.zip``."""
    checkpoint = Path(checkpoint)
    if checkpoint.name == MODEL_FILE:
        return checkpoint.with_name(NORMALIZATION_FILE)
    prefix, steps = checkpoint.stem.rsplit("_", 2)[0], checkpoint.stem.rsplit("_", 2)[1]
    return checkpoint.with_name(f"{prefix}_vecnormalize_{steps}_steps.pkl")


def load_policy(directory: Path, obs_mode: str | None = None) -> NormalizedPolicy:
    """A trained policy with SB3's ``predict``, normalising raw observations as during training."""
    directory = Path(directory)
    summary = json.loads((directory / SUMMARY_FILE).read_text())
    algorithm = ALGORITHMS[summary["run"]["algo"]]
    model = algorithm.load(str(directory / MODEL_FILE), device="cpu")
    run = TrainingRun(**{"activity": False, **summary["run"], "n_envs": 1})
    normalization = VecNormalize.load(str(directory / NORMALIZATION_FILE), make_vec_env(run, 1, 0, kind="batched"))
    normalization.training = False
    return NormalizedPolicy(model, normalization, obs_mode or run.obs_mode)


@dataclass
class NormalizedPolicy:
    """A trained model with the observation normalisation it was trained with."""

    model: BaseAlgorithm
    normalization: VecNormalize
    obs_mode: str

    def predict(
        self, observation: Mapping[str, Any], state: Any = None, episode_start: Any = None, deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """SB3's ``predict`` on environment observations (one, or a batch with a leading axis)."""
        batched = observation["time_since_maintenance"].ndim == 2
        batch = dict(observation) if batched else {key: value[None] for key, value in observation.items()}
        learner_view = self.normalization.normalize_obs(cast(LearnerView, self.normalization.venv).forward(batch))
        actions, state = self.model.predict(learner_view, state, episode_start, deterministic)
        return (actions if batched else actions[0]), state
