"""Training maintenance policies with stable-baselines3 on the batched environment.

`train` builds the batched `MaintenanceVecEnv` (or a `SubprocVecEnv` of single environments, for
comparison), normalises observations and rewards with `VecNormalize`, and trains PPO, A2C or DQN with a
progress bar, periodic evaluation on held-out seeds, checkpoints and, when tensorboard is installed,
TensorBoard logs. The selected policy, its normalisation statistics and its optimizer's state land in
the output directory as an agent directory of ``agents.agent_files`` (JSON and safetensors: loading it
runs no code from the files). stable-baselines3's own files (``model.zip``, ``vecnormalize.pkl``) are
unpickled on loading; they are read only with ``trust_pickle=True`` (``--trust-pickle``), to resume from
them or to convert them (``convert_agent``).
"""

from __future__ import annotations

import importlib.util
import shutil
import time
import warnings
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any, cast

import gymnasium as gym
import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback, EvalCallback
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.policies import ActorCriticPolicy, BasePolicy
from stable_baselines3.common.vec_env import SubprocVecEnv, VecEnv, VecMonitor, VecNormalize, sync_envs_normalization

import ea_gym  # noqa: F401 - registers the environments
from agents.agent_files import (
    ALGORITHMS,
    AgentDescription,
    Normalization,
    TrainedEnvironment,
    build_policy,
    load_optimizer,
    load_sb3,
    load_weights,
    read_agent,
    save_agent,
)
from agents.conventions import (
    AGENT_FILE,
    OPTIMIZER_FILE,
    POLICY_FILE,
    SB3_MODEL_FILE,
    SUMMARY_FILE,
    TRAINING_SEED,
    VALIDATION_SEED,
    pickled,
    refuse_pickle,
)
from agents.hyperparameters import check_hyperparameters
from agents.imitation import clone
from agents.initial_policy import initial_probabilities, start_from
from agents.learning import check_steps, learn_steps
from agents.observations import LearnerView, normalised_keys
from agents.shaping import WearShaping
from ea_gym.documents import read_document
from ea_gym.env import env_id
from ea_gym.env.config import EnvConfig
from ea_gym.env.sb3 import MaintenanceVecEnv
from ea_gym.files import write_atomic, write_json
from ea_gym.threads import single_threaded_torch

#: an output directory's sub-directories (agent directories): the policy of every evaluation, and the last policy
CHECKPOINTS_DIRECTORY = "checkpoints"
LAST_DIRECTORY = "last"


@dataclass(frozen=True)
class TrainingRun:
    """One training run's settings, written beside the model as ``training.json``."""

    algo: str = "ppo"
    timesteps: int = 200_000
    obs_mode: str = "phm"
    n_envs: int = 16
    seed: int = 0
    vec_env: str = "batched"  # or "subproc"
    eval_every: int = 20_000  # environment steps between evaluations, each one checkpointed
    eval_episodes: int = 32  # validation episodes per evaluation: 8 gave rewards too noisy to pick a checkpoint by
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    hyperparameters: dict[str, Any] = field(default_factory=dict)
    teacher: str | None = None  # a rule of TEACHERS cloned before learning (PPO and A2C only)
    teacher_parameter: float | dict[str, float] | None = None  # its threshold or period (s) or band(s); None: TEACHERS' default
    teacher_steps: int = 100_000  # environment steps the teacher runs for the cloning (and each DAgger round)
    dagger_rounds: int = 0  # DAgger rounds after the cloning: the learner acts, the teacher labels (agents.imitation)
    activity: bool = True  # the learner also sees each element's EA on a log scale (agents.observations); runs saved without the field did not
    suspect_wear: bool = True  # the learner also sees the suspect's wear (agents.observations); runs saved without the field did not
    wear_shaping: bool = True  # training rewards shaped with the true wear (agents.shaping); validation uses the environment's
    shaping_onset: float = 0.3  # the wear from which the shaping's potential falls (agents.shaping); runs saved without the field had 0
    initial_carry_on: float | None = 0.8  # a new PPO or A2C policy's probability of carrying on (agents.initial_policy); None: uniform


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


def make_vec_env(run: TrainingRun, n_envs: int, seed: int, kind: str | None = None, shaped: bool = False) -> VecEnv:
    """The training (or validation) environments, seeded seed, seed + 1, ...; ``shaped``: with the run's
    reward shaping (``agents.shaping``, training only)."""
    kind = kind or run.vec_env
    kwargs = {"obs_mode": run.obs_mode, "continue_after_failure": True, **run.env_kwargs}
    if kind == "batched":
        env: VecEnv = MaintenanceVecEnv(n_envs, **kwargs)
    elif kind == "subproc":
        env = SubprocVecEnv([lambda: gym.make(env_id(kwargs.get("system")), **kwargs) for _ in range(n_envs)])
    else:
        raise ValueError(f"vec_env must be 'batched' or 'subproc', got {kind!r}")
    env.seed(seed)
    # VecMonitor: the environment's own episode returns and lengths, for the logs and the evaluation callback
    monitored: VecEnv = VecMonitor(env)
    if run.wear_shaping:  # unshaped (scale 0) on validation: the same wrappers, for SB3's synchronised normalisation
        scale = monitored.get_attr("core")[0].config.costs.failure if shaped else 0.0
        monitored = WearShaping(monitored, gamma=hyperparameters(run).get("gamma", 0.99), scale=scale, onset=run.shaping_onset)
    return LearnerView(monitored, activity=run.activity, suspect_wear=run.suspect_wear)


def normalize(env: VecEnv, training: bool = True) -> VecNormalize:
    """Standardise the unbounded observation keys (see ``agents.observations``) and the rewards."""
    return VecNormalize(env, training=training, norm_obs=True, norm_reward=training, gamma=0.99,
                        norm_obs_keys=normalised_keys(cast(gym.spaces.Dict, env.observation_space)))


def default_hyperparameters(algo: str, n_envs: int, cloned: bool = False, episode_steps: int = EnvConfig().horizon) -> dict[str, Any]:
    """Settings that train in minutes on two cores (episodes of ``episode_steps``, 500 by default).

    A policy cloned from a teacher is fine-tuned gently (smaller steps and clipping, no entropy bonus)
    so that the first updates, on a value function fitted to the teacher, do not undo the cloning. A new
    policy makes 10 passes over each rollout without an entropy bonus (stable-baselines3's own defaults):
    with 5 passes and a bonus of 0.01, 200,000 steps left one fault type's corrective action a
    state-independent dither, which keeps the part healthy while training samples it and which the
    deterministic policy never takes (``experiments/results/from_scratch``). Each of its rollouts is one
    whole episode of every environment: the environments start together and every episode lasts
    ``episode_steps``, so rollouts of 128 steps each held the same quarter of every episode, the first
    quarter (the fault barely arrived) with little to learn from, and the learner fitted one stretch of
    the episodes after another (rollouts of 16 x 500 steps, 25 updates in 200,000 steps: 106.0, 131.0 and
    117.8 per episode on training seeds 0, 1 and 2, mean 118.3, against 115.0, 102.6 and 187.2, mean
    134.9, with 16 x 128).
    """
    if algo == "ppo":
        if cloned:
            return {"n_steps": max(4096 // n_envs, 32), "batch_size": 512, "n_epochs": 5, "gamma": 0.99,
                    "gae_lambda": 0.95, "learning_rate": 5e-5, "ent_coef": 0.0, "clip_range": 0.1}
        return {"n_steps": episode_steps, "batch_size": 256, "n_epochs": 10, "gamma": 0.99,
                "gae_lambda": 0.95, "learning_rate": 3e-4, "ent_coef": 0.0}
    if algo == "a2c":
        return {"n_steps": 16, "gamma": 0.99, "learning_rate": 7e-4, "ent_coef": 0.01}
    return {"buffer_size": 100_000, "learning_starts": 5_000, "batch_size": 256, "gamma": 0.99,
            "exploration_fraction": 0.2, "target_update_interval": 2_000, "train_freq": 4}


def hyperparameters(run: TrainingRun) -> dict[str, Any]:
    """The algorithm's keyword arguments for ``run``: ``default_hyperparameters``, updated by the run's own."""
    episode_steps = int(run.env_kwargs.get("horizon", EnvConfig().horizon))
    return {**default_hyperparameters(run.algo, run.n_envs, cloned=run.teacher is not None, episode_steps=episode_steps), **run.hyperparameters}


def trained_environment(run: TrainingRun) -> TrainedEnvironment:
    """The environment ``make_vec_env`` makes for ``run``, as an agent directory records it."""
    return TrainedEnvironment(env_id(run.env_kwargs.get("system")), run.obs_mode, {"continue_after_failure": True, **run.env_kwargs},
                              run.activity, run.suspect_wear)


def train(
    run: TrainingRun, out: Path, resume: Path | None = None, progress_bar: bool = True, trust_pickle: bool = False,
) -> dict[str, Any]:
    """Train, evaluate and checkpoint; returns the summary written to ``out/training.json``.

    Every ``run.eval_every`` steps the policy is evaluated on ``run.eval_episodes`` validation episodes
    and checkpointed in ``out/checkpoints/<algo>_<steps>_steps`` (a teacher's clone too, at 0 steps); the
    last policy lands in ``out/last`` and is evaluated when its step was not. ``out`` itself becomes the
    evaluated policy with the best mean validation reward (an agent directory of ``agents.agent_files``,
    as the others: weights, optimizer state and the normalisation statistics it was evaluated with), and
    ``out/training.json`` the summary: the run, every evaluation's rewards and the one selected.

    Args:
        resume: an agent directory to continue from (an earlier ``out`` or one of its checkpoints): the
            policy's weights, the optimizer's state, the normalisation statistics, the hyperparameters
            and the step count are restored; the algorithm's other state (PPO's rollout, DQN's replay
            buffer) starts afresh, as it does from stable-baselines3's files. With ``trust_pickle``, also
            a stable-baselines3 checkpoint ``.zip`` (its ``vecnormalize`` file beside it) or a directory
            holding ``model.zip`` and ``vecnormalize.pkl``.
        trust_pickle: let stable-baselines3 unpickle ``resume``'s files, which runs any code they hold;
            without it they are refused (``agents.conventions.UntrustedFileError``) before any work.
    """
    _check_run(run)
    stored = None
    if resume is not None:
        resume = Path(resume)
        if not refuse_pickle(resume, trust_pickle):
            stored = read_agent(resume)
            _check_resumable(run, stored)
    settings = hyperparameters(run) if stored is None else {**stored.hyperparameters, **run.hyperparameters}
    check_hyperparameters(run.algo, settings, "hyperparameters")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tensorboard = str(out / "tensorboard") if importlib.util.find_spec("tensorboard") else None
    env = make_vec_env(run, run.n_envs, TRAINING_SEED + run.seed * run.n_envs, shaped=True)
    # validation episodes run 8 at a time on the batched env
    evaluation_env = make_vec_env(run, min(run.eval_episodes, 8), VALIDATION_SEED, kind="batched")
    model, env = make_model(run, env, settings, tensorboard, resume, stored)
    evaluation_env = normalize(evaluation_env, training=False)
    evaluation_env.obs_rms = env.obs_rms
    environment = trained_environment(run)

    def store(directory: Path) -> None:
        save_agent(directory, model, env, environment, settings)

    started = time.perf_counter()
    cloning = None
    candidates: list[Evaluation] = []  # every evaluated policy, in the order evaluated
    if run.teacher is not None and resume is None:
        if run.algo == "dqn":
            raise ValueError("a teacher can only be cloned into PPO or A2C (an actor-critic), not DQN")
        with single_threaded_torch():
            learner, view = cast(OnPolicyAlgorithm, model), cast(LearnerView, env.venv)  # PPO or A2C; make_vec_env wraps a LearnerView
            cloning = asdict(clone(learner, env, make_teacher(run, env), run.teacher_steps, restore=view.inverse, dagger_rounds=run.dagger_rounds))
            # the cloned policy is a candidate too: reinforcement learning must beat it to replace it
            rewards = episode_rewards(model, evaluation_env, run.eval_episodes)
        cloning["validation_reward"] = float(np.mean(rewards))
        store(out / _checkpoint(run, 0))
        candidates.append(Evaluation(0, rewards, _checkpoint(run, 0)))
    # every evaluation checkpoints the policy it evaluated, with the normalisation statistics it saw
    evaluation = EvalCallback(evaluation_env, n_eval_episodes=run.eval_episodes, eval_freq=max(run.eval_every // run.n_envs, 1),
                              callback_after_eval=SaveAgent(lambda steps: store(out / _checkpoint(run, steps))), deterministic=True, verbose=0,
                              log_path=str(out / "evaluations"))  # with a log path it keeps every evaluation's rewards
    # the environments' numpy shares the process: a second torch thread fights its BLAS threads (20x slower here)
    first_step = 0 if resume is None else model.num_timesteps  # a new model counts from 0
    with single_threaded_torch():
        learn_steps(model, run.timesteps, evaluation, progress_bar, reset_num_timesteps=resume is None)
        wall = time.perf_counter() - started
        store(out / LAST_DIRECTORY)
        candidates += _learned(run, model, env, evaluation)
    selected = _select(out, run, candidates)
    steps = model.num_timesteps - first_step
    summary = {"run": asdict(run), "steps": steps, "wall_time_s": round(wall, 1), "steps_per_s": round(steps / wall, 1),
               "resumed_from": None if resume is None else str(resume), "cloning": cloning, "selected": selected,
               "last": {"steps": model.num_timesteps, "directory": LAST_DIRECTORY}, "evaluations": [c.to_dict() for c in candidates]}
    write_json(out / SUMMARY_FILE, summary)
    env.close()
    return summary


@dataclass(frozen=True)
class Evaluation:
    """One evaluated policy: its step count, its validation episodes' rewards and its agent directory
    (relative to the output directory)."""

    steps: int
    rewards: list[float]
    directory: str

    @property
    def mean_reward(self) -> float:
        return float(np.mean(self.rewards))

    def to_dict(self) -> dict[str, Any]:
        return {"steps": self.steps, "mean_reward": round(self.mean_reward, 3), "std_reward": round(float(np.std(self.rewards)), 3),
                "directory": self.directory}


def _learned(run: TrainingRun, model: BaseAlgorithm, env: VecNormalize, evaluation: EvalCallback) -> list[Evaluation]:
    """The evaluations made while learning and, when its step was not among them, the last model's (in ``last``)."""
    candidates = [Evaluation(int(steps), [float(r) for r in rewards], _checkpoint(run, int(steps)))
                  for steps, rewards in zip(evaluation.evaluations_timesteps, evaluation.evaluations_results)]
    if model.num_timesteps not in evaluation.evaluations_timesteps:  # the last model is a candidate too
        sync_envs_normalization(env, evaluation.eval_env)
        candidates.append(Evaluation(model.num_timesteps, episode_rewards(model, evaluation.eval_env, run.eval_episodes), LAST_DIRECTORY))
    return candidates


def episode_rewards(model: BaseAlgorithm, env: VecEnv, episodes: int) -> list[float]:
    """The deterministic policy's reward in each of ``episodes`` validation episodes (EvalCallback's evaluation)."""
    rewards, _ = evaluate_policy(model, env, n_eval_episodes=episodes, deterministic=True, return_episode_rewards=True)
    return [float(reward) for reward in cast(list[float], rewards)]


def _checkpoint(run: TrainingRun, steps: int) -> str:
    """The agent directory of the checkpoint after ``steps`` environment steps, relative to the output directory."""
    return f"{CHECKPOINTS_DIRECTORY}/{run.algo}_{steps}_steps"


def make_model(
    run: TrainingRun, env: VecEnv, settings: dict[str, Any], tensorboard: str | None, resume: Path | None, stored: AgentDescription | None,
) -> tuple[BaseAlgorithm, VecNormalize]:
    """The model to train and its normalised environment: new, resumed from an agent directory (``stored``
    read from ``resume``), or resumed from stable-baselines3's files (``resume`` without ``stored``: trusted)."""
    if resume is not None and stored is None:
        return load_sb3(resume / SB3_MODEL_FILE if resume.is_dir() else resume, run.algo, env, seed=run.seed)
    normalized = normalize(env)
    policy: Any = "MultiInputPolicy" if stored is None else stored.policy_class
    policy_kwargs = None if stored is None else stored.policy_kwargs
    with warnings.catch_warnings():
        # rollouts of whole episodes (16 x 500 steps) are not a multiple of the minibatch: each pass ends on a smaller one, as intended
        warnings.filterwarnings("ignore", message="You have specified a mini-batch size", category=UserWarning)
        model = ALGORITHMS[run.algo](policy, normalized, seed=run.seed, verbose=0, tensorboard_log=tensorboard, policy_kwargs=policy_kwargs,
                                     **settings)
    if stored is None and run.initial_carry_on is not None and isinstance(model.policy, ActorCriticPolicy):
        meanings, core = env.get_attr("action_meanings")[0], env.get_attr("core")[0]
        start_from(model.policy, initial_probabilities(meanings, core.config.costs, run.initial_carry_on))
    if stored is not None and resume is not None:
        stored.normalization.restore(normalized)
        load_weights(model.policy, resume)
        load_optimizer(model.policy.optimizer, stored, resume)
        model.num_timesteps = stored.num_timesteps
    return model, normalized


class SaveAgent(BaseCallback):
    """Calls ``save(num_timesteps)`` every ``every`` calls (CheckpointCallback's schedule; every call as an
    EvalCallback's ``callback_on_new_best``)."""

    def __init__(self, save: Callable[[int], None], every: int = 1):
        super().__init__()
        self.save, self.every = save, every

    def _on_step(self) -> bool:
        if self.n_calls % self.every == 0:
            self.save(self.num_timesteps)
        return True


def _check_run(run: TrainingRun) -> None:
    """Refuse, before any work, a run that cannot train as asked."""
    if run.algo not in ALGORITHMS:
        raise ValueError(f"algo must be one of {sorted(ALGORITHMS)}, got {run.algo!r}")
    if run.timesteps <= 0 or run.n_envs <= 0:
        raise ValueError(f"timesteps and n_envs must be positive, got {run.timesteps} and {run.n_envs}")
    check_steps(run.timesteps, run.n_envs)
    if run.dagger_rounds and run.teacher is None:
        raise ValueError(f"dagger_rounds ({run.dagger_rounds}) needs a teacher to label the learner's steps")


def _check_resumable(run: TrainingRun, stored: AgentDescription) -> None:
    """The run's algorithm and environment must be the agent's (else its spaces or its statistics would not fit)."""
    environment = trained_environment(run)
    for name, agent, here in (("algo", stored.algorithm, run.algo), ("obs_mode", stored.environment.obs_mode, environment.obs_mode),
                              ("env_kwargs", stored.environment.env_kwargs, environment.env_kwargs),
                              ("activity", stored.environment.activity, environment.activity),
                              ("suspect_wear", stored.environment.suspect_wear, environment.suspect_wear),
                              ("env id", stored.environment.env_id, environment.env_id)):
        if agent != here:
            raise ValueError(f"resume: the agent was trained with {name} {agent!r}, this run has {here!r}")


def _select(out: Path, run: TrainingRun, candidates: list[Evaluation]) -> dict[str, Any]:
    """Copy the evaluated policy with the best mean validation reward into ``out`` (the earliest of equals)."""
    best = max(candidates, key=lambda candidate: candidate.mean_reward)
    for name in (POLICY_FILE, OPTIMIZER_FILE, AGENT_FILE):  # agent.json last: it marks a complete agent
        write_atomic(out / name, partial(shutil.copyfile, out / best.directory / name))
    return {"checkpoint": f"{best.steps} steps", "steps": best.steps, "directory": best.directory,
            "validation_reward": round(best.mean_reward, 3),
            "why": f"best mean validation reward ({best.mean_reward:.1f} over {run.eval_episodes} validation episodes)"}


def load_policy(directory: Path, obs_mode: str | None = None, trust_pickle: bool = False) -> NormalizedPolicy:
    """A trained policy with SB3's ``predict``, seeing raw observations as it did in training.

    Args:
        directory: an agent directory (``agents.agent_files``); with ``trust_pickle``, also a directory of
            stable-baselines3's files (``model.zip``, ``vecnormalize.pkl``, ``training.json``).
        obs_mode: the obs_mode reported (default the agent's).
        trust_pickle: let stable-baselines3 unpickle such files, which runs any code they hold; without
            it they are refused (``agents.conventions.UntrustedFileError``).
    """
    directory = Path(directory)
    if refuse_pickle(directory, trust_pickle):
        run = summary_run(directory)
        model, normalization = load_sb3(directory / SB3_MODEL_FILE, run.algo, make_vec_env(run, 1, 0, kind="batched"))
        view = cast(LearnerView, normalization.venv)
        return NormalizedPolicy(model.policy, Normalization.of(normalization), view, obs_mode or run.obs_mode, model.num_timesteps)
    description = read_agent(directory)
    environment = description.environment
    expected_id = env_id(environment.env_kwargs.get("system"))
    if environment.env_id != expected_id:
        raise ValueError(f"{directory / AGENT_FILE}: the agent was trained on {environment.env_id!r}, not {expected_id!r}")
    run = TrainingRun(algo=description.algorithm, obs_mode=environment.obs_mode, env_kwargs=environment.env_kwargs, activity=environment.activity,
                      suspect_wear=environment.suspect_wear)
    view = cast(LearnerView, make_vec_env(run, 1, 0, kind="batched"))
    expected = {key: space.shape for key, space in description.observation_space.spaces.items()}
    seen = {key: space.shape for key, space in cast(gym.spaces.Dict, view.observation_space).spaces.items()}
    if expected != seen:
        raise ValueError(f"{directory / AGENT_FILE}: the agent observes {expected}, its environment now gives {seen}")
    return NormalizedPolicy(build_policy(description, directory), description.normalization, view, obs_mode or run.obs_mode,
                            description.num_timesteps)


def summary_run(directory: Path) -> TrainingRun:
    """The run ``directory/training.json`` records (runs saved before the ``activity`` or ``suspect_wear`` field did not see it,
    those before ``shaping_onset`` shaped from nominal on; their ``checkpoint_every``, from before every
    evaluation was checkpointed, is dropped)."""
    path = Path(directory) / SUMMARY_FILE
    try:
        recorded = {key: value for key, value in read_document(path)["run"].items() if key != "checkpoint_every"}
        return TrainingRun(**{"activity": False, "suspect_wear": False, "shaping_onset": 0.0, **recorded})
    except (ValueError, KeyError, TypeError) as error:
        raise ValueError(f"{path}: cannot read the training run ({error})") from None


def convert_agent(source: Path, destination: Path, trust_pickle: bool = False) -> Path:
    """Write an agent of stable-baselines3's files (``model.zip``, ``vecnormalize.pkl`` and ``training.json``
    of an earlier ``ea-gym train``) as an agent directory of ``agents.agent_files``, ``training.json`` copied.

    The source is unpickled: refused (``UntrustedFileError``) unless ``trust_pickle``.
    """
    source, destination = Path(source), Path(destination)
    if not source.is_dir() or pickled(source) is None or not (source / SB3_MODEL_FILE).is_file():
        raise ValueError(f"{source}: expected a directory holding stable-baselines3's {SB3_MODEL_FILE} and its normalisation")
    refuse_pickle(source, trust_pickle)
    run = summary_run(source)
    model, normalization = load_sb3(source / SB3_MODEL_FILE, run.algo, make_vec_env(run, 1, 0, kind="batched"))
    save_agent(destination, model, normalization, trained_environment(run), hyperparameters(run))
    write_atomic(destination / SUMMARY_FILE, lambda tmp: shutil.copyfile(source / SUMMARY_FILE, tmp))
    return destination


@dataclass
class NormalizedPolicy:
    """A trained policy with the learner's view of the observations and the normalisation it was trained with.

    Attributes:
        policy: the stable-baselines3 policy.
        normalization: the observation normalisation's statistics (``VecNormalize`` in training).
        view: the ``LearnerView`` the policy was trained through (RUL on a log scale, wear, activity, suspect's wear).
        obs_mode: the environment's obs_mode.
        num_timesteps: environment steps the policy was trained for.
    """

    policy: BasePolicy
    normalization: Normalization
    view: LearnerView
    obs_mode: str
    num_timesteps: int

    def predict(
        self, observation: Mapping[str, Any], state: Any = None, episode_start: Any = None, deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """SB3's ``predict`` on environment observations (one, or a batch with a leading axis)."""
        batched = observation["time_since_maintenance"].ndim == 2
        batch = dict(observation) if batched else {key: value[None] for key, value in observation.items()}
        learner_view = self.normalization.normalize_obs(self.view.forward(batch))
        actions, state = self.policy.predict(learner_view, state, episode_start, deterministic)
        return (actions if batched else actions[0]), state
