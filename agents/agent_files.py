"""Trained agents as files that run no code when loaded: weights in safetensors, everything else in JSON.

An agent directory (``ea-gym train --out DIR``) holds

- ``agent.json``: the format and its version; the algorithm and its hyperparameters; the number of
  environment steps trained; the stable-baselines3 policy class and its architecture (``net_arch``,
  activation function, features extractor and optimizer by name, with their keyword arguments); the
  observation and action spaces as numbers (a Dict of Box shapes, bounds and dtypes; Discrete n); the
  environment the agent was trained on (id, obs_mode, keyword arguments, and whether the learner saw
  the EA on a log scale and the suspect's wear, ``agents.observations.LearnerView``; agents saved before
  ``suspect_wear`` did not see it); the ``VecNormalize`` statistics as numbers
  (per normalised key the running mean, variance and count, ``clip_obs``, ``epsilon``, the keys, and
  the reward normalisation's settings and return statistics); the optimizer's parameter groups;
- ``policy.safetensors``: the policy's ``state_dict``;
- ``optimizer.safetensors``: the optimizer's per-parameter state (Adam's moments), so that training
  resumes where it stopped.

Loading rebuilds the policy from the JSON, with classes taken from fixed tables (nothing is imported by
name, nothing unpickled), and loads the weights with safetensors. ``Normalization.normalize_obs``
standardises observations exactly as ``VecNormalize.normalize_obs`` does, from the same statistics.

stable-baselines3's own files (``model.zip``, whose ``data`` entry is deserialised with cloudpickle, and
``vecnormalize.pkl``, a pickle) can run code from the file: ``load_sb3`` reads them only for a caller
that trusts them (``--trust-pickle``, ``agents.conventions.refuse_pickle``), e.g. to convert them once.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np
import torch as th
from gymnasium import spaces
from safetensors import SafetensorError
from safetensors.torch import load_file, save
from stable_baselines3 import A2C, DQN, PPO
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.policies import ActorCriticPolicy, BasePolicy, MultiInputActorCriticPolicy
from stable_baselines3.common.running_mean_std import RunningMeanStd
from stable_baselines3.common.torch_layers import CombinedExtractor, FlattenExtractor
from stable_baselines3.common.vec_env import VecEnv, VecNormalize
from stable_baselines3.dqn.policies import DQNPolicy
from stable_baselines3.dqn.policies import MultiInputPolicy as DQNMultiInputPolicy

from agents.agent_document import FORMAT, VERSION, check_net_arch, field_of, read_agent_document
from agents.conventions import AGENT_FILE, OPTIMIZER_FILE, POLICY_FILE, SB3_MODEL_FILE, SB3_NORMALIZATION_FILE
from ea_gym.files import write_atomic, write_json

__all__ = [
    "FORMAT", "VERSION", "ALGORITHMS", "RunningStats", "Normalization", "TrainedEnvironment", "AgentDescription",
    "save_agent", "read_agent", "build_policy", "load_weights", "load_optimizer", "load_sb3",
]

#: the algorithms an agent is trained with, by the name ``agent.json`` and ``ea-gym train --algo`` give them
ALGORITHMS: dict[str, type[BaseAlgorithm]] = {"ppo": PPO, "a2c": A2C, "dqn": DQN}


def _by_name(*classes: type) -> dict[str, type]:
    return {f"{c.__module__}.{c.__qualname__}": c for c in classes}


#: the classes an agent file may name; anything else is refused (nothing is imported by name)
POLICY_CLASSES: dict[str, type] = _by_name(MultiInputActorCriticPolicy, ActorCriticPolicy, DQNMultiInputPolicy, DQNPolicy)
ACTIVATIONS: dict[str, type] = {c.__name__: c for c in (th.nn.Tanh, th.nn.ReLU, th.nn.ELU, th.nn.LeakyReLU, th.nn.SiLU, th.nn.GELU)}
FEATURES_EXTRACTORS: dict[str, type] = {c.__name__: c for c in (CombinedExtractor, FlattenExtractor)}
OPTIMIZERS: dict[str, type] = {c.__name__: c for c in (th.optim.Adam, th.optim.AdamW, th.optim.RMSprop, th.optim.SGD)}
#: the policy's keyword arguments that name a class, and the table each is looked up in
CLASS_ARGUMENTS = {"activation_fn": ACTIVATIONS, "features_extractor_class": FEATURES_EXTRACTORS, "optimizer_class": OPTIMIZERS}


@dataclass(frozen=True)
class RunningStats:
    """``RunningMeanStd``'s numbers: the running mean and variance (per element) and the count of samples."""

    mean: np.ndarray
    var: np.ndarray
    count: float

    @classmethod
    def of(cls, stats: RunningMeanStd) -> RunningStats:
        return cls(np.array(stats.mean, dtype=np.float64), np.array(stats.var, dtype=np.float64), float(stats.count))

    def running_mean_std(self) -> RunningMeanStd:
        stats = RunningMeanStd(shape=self.mean.shape)
        stats.mean, stats.var, stats.count = self.mean.copy(), self.var.copy(), self.count
        return stats

    def to_json(self) -> dict[str, Any]:
        return {"shape": list(self.mean.shape), "mean": _numbers(self.mean), "var": _numbers(self.var), "count": self.count}

    @classmethod
    def from_json(cls, data: Any, where: str) -> RunningStats:
        shape = _shape(field_of(data, "shape", list, where), where)
        mean = _array(field_of(data, "mean", list, where), shape, np.float64, f"{where}.mean")
        var = _array(field_of(data, "var", list, where), shape, np.float64, f"{where}.var")
        if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(var)) and np.all(var >= 0)):
            raise ValueError(f"{where}: means must be finite and variances finite and >= 0")
        count = _number(field_of(data, "count", (int, float), where), f"{where}.count")
        if count < 0:
            raise ValueError(f"{where}.count must be >= 0 (samples seen), got {count}")
        return cls(mean, var, count)


@dataclass(frozen=True)
class Normalization:
    """``VecNormalize``'s standardisation of Dict observations and of rewards, as numbers.

    Attributes:
        observations: per normalised key (``norm_obs_keys``, in order) its running statistics.
        clip_obs: standardised observations are clipped to +-clip_obs.
        epsilon: added to the variance before its square root.
        norm_reward, clip_reward, gamma, returns: the reward normalisation (training only): whether
            rewards are scaled, their clip, the discount of the returns and the returns' statistics.
    """

    observations: dict[str, RunningStats]
    clip_obs: float
    epsilon: float
    norm_reward: bool
    clip_reward: float
    gamma: float
    returns: RunningStats

    @classmethod
    def of(cls, normalization: VecNormalize) -> Normalization:
        """The numbers of a ``VecNormalize`` over Dict observations."""
        if not normalization.norm_obs or not isinstance(normalization.obs_rms, dict):
            raise ValueError("agent files hold the normalisation of Dict observations (VecNormalize with norm_obs=True)")
        keys = list(normalization.norm_obs_keys or [])
        return cls({key: RunningStats.of(normalization.obs_rms[key]) for key in keys}, float(normalization.clip_obs),
                   float(normalization.epsilon), bool(normalization.norm_reward), float(normalization.clip_reward),
                   float(normalization.gamma), RunningStats.of(normalization.ret_rms))

    def normalize_obs(self, observation: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """``VecNormalize.normalize_obs``: the normalised keys standardised, clipped and cast to float32; the others as they are."""
        normalized = dict(observation)
        for key, stats in self.observations.items():
            standardised = (observation[key] - stats.mean) / np.sqrt(stats.var + self.epsilon)
            normalized[key] = np.clip(standardised, -self.clip_obs, self.clip_obs).astype(np.float32)
        return normalized

    def restore(self, normalization: VecNormalize) -> None:
        """Put these statistics into a ``VecNormalize`` made with the same keys (to resume training)."""
        if list(normalization.norm_obs_keys or []) != list(self.observations):
            raise ValueError(f"normalised keys differ: the agent's {list(self.observations)}, the environment's {normalization.norm_obs_keys}")
        normalization.obs_rms = {key: stats.running_mean_std() for key, stats in self.observations.items()}
        normalization.ret_rms = self.returns.running_mean_std()
        normalization.clip_obs, normalization.epsilon = self.clip_obs, self.epsilon
        normalization.norm_reward, normalization.clip_reward, normalization.gamma = self.norm_reward, self.clip_reward, self.gamma

    def to_json(self) -> dict[str, Any]:
        return {"norm_obs_keys": list(self.observations), "obs_rms": {key: s.to_json() for key, s in self.observations.items()},
                "clip_obs": self.clip_obs, "epsilon": self.epsilon, "norm_reward": self.norm_reward, "clip_reward": self.clip_reward,
                "gamma": self.gamma, "ret_rms": self.returns.to_json()}

    @classmethod
    def from_json(cls, data: Any, where: str) -> Normalization:
        keys = field_of(data, "norm_obs_keys", list, where)
        statistics = field_of(data, "obs_rms", dict, where)
        if sorted(map(str, keys)) != sorted(statistics):
            raise ValueError(f"{where}: obs_rms must hold one entry per key of norm_obs_keys {keys}, got {sorted(statistics)}")
        return cls({str(key): RunningStats.from_json(statistics[key], f"{where}.obs_rms.{key}") for key in keys},
                   _positive(field_of(data, "clip_obs", (int, float), where), f"{where}.clip_obs"),
                   _positive(field_of(data, "epsilon", (int, float), where), f"{where}.epsilon"),
                   field_of(data, "norm_reward", bool, where),
                   _positive(field_of(data, "clip_reward", (int, float), where), f"{where}.clip_reward"),
                   _fraction(field_of(data, "gamma", (int, float), where), f"{where}.gamma"),
                   RunningStats.from_json(field_of(data, "ret_rms", dict, where), f"{where}.ret_rms"))


@dataclass(frozen=True)
class TrainedEnvironment:
    """The environment an agent was trained on: ``gym.make(env_id, obs_mode=obs_mode, **env_kwargs)``, seen
    through ``LearnerView(..., activity=activity, suspect_wear=suspect_wear)``."""

    env_id: str
    obs_mode: str
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    activity: bool = False
    suspect_wear: bool = False


@dataclass(frozen=True)
class AgentDescription:
    """``agent.json``, read and checked; classes resolved from the tables of this module."""

    algorithm: str
    hyperparameters: dict[str, Any]
    num_timesteps: int
    policy_class: type
    policy_kwargs: dict[str, Any]
    observation_space: spaces.Dict
    action_space: spaces.Discrete
    environment: TrainedEnvironment
    normalization: Normalization
    optimizer_groups: list[dict[str, Any]] | None


def save_agent(
    directory: Path, model: BaseAlgorithm, normalization: VecNormalize, environment: TrainedEnvironment, hyperparameters: Mapping[str, Any],
) -> Path:
    """Write ``model``'s policy and optimizer state and ``normalization``'s statistics as an agent directory.

    Args:
        hyperparameters: the keyword arguments the algorithm was made with (numbers, strings), for resuming.

    Returns:
        The directory (created). ``agent.json`` is written last: a directory with it is complete.
    """
    directory = Path(directory)
    algorithm = next((name for name, cls in ALGORITHMS.items() if type(model) is cls), None)
    if algorithm is None:
        raise ValueError(f"agent files hold models of {sorted(ALGORITHMS)} ({[c.__name__ for c in ALGORITHMS.values()]}), got {type(model).__name__}")
    policy = model.policy
    optimizer_tensors, optimizer_groups = _optimizer_state(policy.optimizer)
    description = {
        "format": FORMAT,
        "version": VERSION,
        "algorithm": algorithm,
        "hyperparameters": dict(hyperparameters),
        "num_timesteps": int(model.num_timesteps),
        "policy": {"class": _name_of(POLICY_CLASSES, type(policy), "policy class"), "kwargs": _architecture(policy)},
        "observation_space": describe_space(policy.observation_space),
        "action_space": describe_space(policy.action_space),
        "environment": {"id": environment.env_id, "obs_mode": environment.obs_mode, "env_kwargs": dict(environment.env_kwargs),
                        "activity": environment.activity, "suspect_wear": environment.suspect_wear},
        "normalization": Normalization.of(normalization).to_json(),
        "optimizer": {"param_groups": optimizer_groups},
    }
    directory.mkdir(parents=True, exist_ok=True)
    _write_tensors(directory / POLICY_FILE, policy.state_dict())
    _write_tensors(directory / OPTIMIZER_FILE, optimizer_tensors)
    write_json(directory / AGENT_FILE, description)
    return directory


def read_agent(directory: Path) -> AgentDescription:
    """``directory/agent.json`` read and checked (no weights loaded); ValueError naming the field otherwise."""
    data = read_agent_document(directory)  # the checks that need no torch, sizes included
    where = str(Path(directory) / AGENT_FILE)
    algorithm, hyperparameters, num_timesteps = data["algorithm"], data["hyperparameters"], data["num_timesteps"]
    policy = field_of(data, "policy", dict, where)
    policy_class = _class(POLICY_CLASSES, field_of(policy, "class", str, f"{where}: policy"), f"{where}: policy.class")
    observation_space = build_space(field_of(data, "observation_space", dict, where), f"{where}: observation_space")
    action_space = build_space(field_of(data, "action_space", dict, where), f"{where}: action_space")
    if not isinstance(observation_space, spaces.Dict) or not isinstance(action_space, spaces.Discrete):
        raise ValueError(f"{where}: agents act on a Dict observation space with a Discrete action space")
    environment = field_of(data, "environment", dict, where)
    optimizer = field_of(data, "optimizer", dict, where)
    groups = optimizer.get("param_groups")
    if groups is not None and not (isinstance(groups, list) and all(isinstance(g, dict) for g in groups)):
        raise ValueError(f"{where}: optimizer.param_groups must be a list of objects")
    return AgentDescription(
        algorithm=algorithm,
        hyperparameters=hyperparameters,
        num_timesteps=num_timesteps,
        policy_class=policy_class,
        policy_kwargs=_resolve_kwargs(field_of(policy, "kwargs", dict, f"{where}: policy"), f"{where}: policy.kwargs"),
        observation_space=observation_space,
        action_space=action_space,
        environment=TrainedEnvironment(
            env_id=field_of(environment, "id", str, f"{where}: environment"),
            obs_mode=field_of(environment, "obs_mode", str, f"{where}: environment"),
            env_kwargs=field_of(environment, "env_kwargs", dict, f"{where}: environment"),
            activity=field_of(environment, "activity", bool, f"{where}: environment"),
            suspect_wear=field_of({"suspect_wear": False, **environment}, "suspect_wear", bool, f"{where}: environment"),
        ),
        normalization=Normalization.from_json(field_of(data, "normalization", dict, where), f"{where}: normalization"),
        optimizer_groups=groups,
    )


def build_policy(description: AgentDescription, directory: Path) -> BasePolicy:
    """The policy ``agent.json`` describes, on the CPU in evaluation mode, with the weights of ``directory/policy.safetensors``."""
    try:
        policy = description.policy_class(description.observation_space, description.action_space, lambda _: 0.0, **description.policy_kwargs)
    except (TypeError, ValueError, AssertionError) as error:
        raise ValueError(f"{Path(directory) / AGENT_FILE}: policy.kwargs do not build a {description.policy_class.__name__} ({error})") from None
    load_weights(policy, directory)
    policy.set_training_mode(False)
    return cast(BasePolicy, policy)


def load_weights(policy: th.nn.Module, directory: Path) -> None:
    """Load ``directory/policy.safetensors`` into ``policy`` (every tensor, shapes checked)."""
    path = _regular(Path(directory) / POLICY_FILE)
    try:
        tensors = load_file(path, device="cpu")
    except (OSError, SafetensorError, RuntimeError) as error:
        raise ValueError(f"{path}: cannot load the policy's weights ({_first_line(error)})") from None
    mismatch = _weights_mismatch(policy.state_dict(), tensors)
    if mismatch is not None:
        raise ValueError(f"{path}: cannot load the policy's weights: {mismatch}")
    policy.load_state_dict(tensors, strict=True)


def _weights_mismatch(expected: Mapping[str, th.Tensor], found: Mapping[str, th.Tensor]) -> str | None:
    """The first tensor missing, extra or of another shape than the policy agent.json describes needs; None if all fit."""
    for name, tensor in expected.items():
        if name not in found:
            return f"tensor {name!r} (shape {list(tensor.shape)}) is missing"
        if found[name].shape != tensor.shape:
            return f"tensor {name!r} has shape {list(found[name].shape)}; the policy agent.json describes needs {list(tensor.shape)}"
    extra = [name for name in found if name not in expected]
    return f"tensor {extra[0]!r} is not one of the policy's ({len(expected)} tensors)" if extra else None


def load_optimizer(optimizer: th.optim.Optimizer, description: AgentDescription, directory: Path) -> None:
    """Load ``directory/optimizer.safetensors`` and the parameter groups of ``agent.json`` into ``optimizer``."""
    path = _regular(Path(directory) / OPTIMIZER_FILE)
    if description.optimizer_groups is None:
        raise ValueError(f"{Path(directory) / AGENT_FILE}: optimizer.param_groups is missing: the agent cannot resume training")
    try:
        tensors = load_file(path, device="cpu")
        state: dict[int, dict[str, th.Tensor]] = {}
        for key, tensor in tensors.items():
            index, name = key.split(".", 1)
            state.setdefault(int(index), {})[name] = tensor
        groups = [{k: tuple(v) if isinstance(v, list) and k != "params" else v for k, v in g.items()} for g in description.optimizer_groups]
        optimizer.load_state_dict({"state": state, "param_groups": groups})
    except (OSError, SafetensorError, RuntimeError, ValueError, KeyError) as error:
        raise ValueError(f"{path}: cannot load the optimizer's state ({_first_line(error)})") from None


def load_sb3(model_file: Path, algorithm: str, venv: VecEnv, seed: int | None = None) -> tuple[BaseAlgorithm, VecNormalize]:
    """stable-baselines3's ``model.zip`` (or a checkpoint ``<prefix>_<steps>_steps.zip``) and the ``VecNormalize``
    beside it, wrapped around ``venv``. UNPICKLES BOTH FILES: only for files the caller trusts.

    Args:
        seed: for training on: the model is loaded with the normalised ``venv`` as its environment and
            this seed; None: on the CPU, without an environment, to act.
    """
    model_file = Path(model_file)
    if model_file.name == SB3_MODEL_FILE:
        statistics = model_file.with_name(SB3_NORMALIZATION_FILE)
    else:  # CheckpointCallback's names: <prefix>_vecnormalize_<steps>_steps.pkl beside <prefix>_<steps>_steps.zip
        prefix, steps = model_file.stem.rsplit("_", 2)[:2]
        statistics = model_file.with_name(f"{prefix}_vecnormalize_{steps}_steps.pkl")
    normalization = VecNormalize.load(str(statistics), venv)
    if seed is None:
        return ALGORITHMS[algorithm].load(str(model_file), device="cpu"), normalization
    return ALGORITHMS[algorithm].load(str(model_file), env=normalization, seed=seed), normalization


def describe_space(space: spaces.Space) -> dict[str, Any]:
    """A Dict of Boxes, a Box or a Discrete space as numbers (bounds flattened, infinities as "inf")."""
    if isinstance(space, spaces.Dict):
        return {"type": "Dict", "spaces": [[key, describe_space(sub)] for key, sub in space.spaces.items()]}
    if isinstance(space, spaces.Box):
        return {"type": "Box", "shape": list(space.shape), "dtype": str(space.dtype), "low": _numbers(space.low), "high": _numbers(space.high)}
    if isinstance(space, spaces.Discrete):
        return {"type": "Discrete", "n": int(space.n), "start": int(space.start)}
    raise ValueError(f"agent files describe Dict, Box and Discrete spaces, not {type(space).__name__}")


def build_space(data: Any, where: str) -> spaces.Space:
    """The space ``describe_space`` described (a Dict keeps its keys' order)."""
    kind = field_of(data, "type", str, where)
    if kind == "Dict":
        entries = field_of(data, "spaces", list, where)
        if not all(isinstance(e, list) and len(e) == 2 and isinstance(e[0], str) for e in entries):
            raise ValueError(f"{where}.spaces must be a list of [name, space] pairs")
        return spaces.Dict([(key, build_space(sub, f"{where}.{key}")) for key, sub in entries])
    if kind == "Box":
        shape = _shape(field_of(data, "shape", list, where), where)
        dtype = field_of(data, "dtype", str, where)
        if dtype not in ("float32", "float64"):
            raise ValueError(f"{where}.dtype must be 'float32' or 'float64', got {dtype!r}")
        low = _array(field_of(data, "low", list, where), shape, np.dtype(dtype), f"{where}.low")
        high = _array(field_of(data, "high", list, where), shape, np.dtype(dtype), f"{where}.high")
        return spaces.Box(low, high, shape, np.dtype(dtype).type)
    if kind == "Discrete":
        n, start = field_of(data, "n", int, where), field_of(data, "start", int, where)
        if n < 1:
            raise ValueError(f"{where}.n must be >= 1, got {n}")
        return spaces.Discrete(n, start=start)
    raise ValueError(f"{where}.type must be 'Dict', 'Box' or 'Discrete', got {kind!r}")


def _architecture(policy: BasePolicy) -> dict[str, Any]:
    """The policy's constructor arguments besides the spaces and the schedule, classes by name."""
    if not isinstance(policy, (ActorCriticPolicy, DQNPolicy)):
        raise ValueError(f"agent files hold actor-critic and DQN policies, not {type(policy).__name__}")
    kwargs: dict[str, Any] = {
        "net_arch": policy.net_arch,
        "activation_fn": policy.activation_fn,
        "features_extractor_class": policy.features_extractor_class,
        "features_extractor_kwargs": dict(policy.features_extractor_kwargs),
        "normalize_images": bool(policy.normalize_images),
        "optimizer_class": policy.optimizer_class,
        "optimizer_kwargs": dict(policy.optimizer_kwargs),
    }
    if isinstance(policy, ActorCriticPolicy):
        if policy.use_sde:
            raise ValueError("agent files hold policies without gSDE (use_sde=False)")
        kwargs.update(ortho_init=bool(policy.ortho_init), share_features_extractor=bool(policy.share_features_extractor))
    for name, table in CLASS_ARGUMENTS.items():
        kwargs[name] = _name_of(table, kwargs[name], name)
    return kwargs


def _resolve_kwargs(kwargs: dict[str, Any], where: str) -> dict[str, Any]:
    if "net_arch" in kwargs:
        check_net_arch(kwargs["net_arch"], f"{where}.net_arch")
    resolved = dict(kwargs)
    for name, table in CLASS_ARGUMENTS.items():
        if name in resolved:
            resolved[name] = _class(table, resolved[name], f"{where}.{name}")
    return resolved



def _write_tensors(path: Path, tensors: Mapping[str, th.Tensor]) -> None:
    """A safetensors file, atomically; every tensor copied (a module shared under two names, as the actor's and
    the critic's features extractor, is stored twice)."""
    data = save({name: tensor.detach().cpu().clone().contiguous() for name, tensor in tensors.items()}, metadata={"format": "pt"})
    write_atomic(path, lambda tmp: Path(tmp).write_bytes(data))


def _optimizer_state(optimizer: th.optim.Optimizer) -> tuple[dict[str, th.Tensor], list[dict[str, Any]]]:
    """The optimizer's per-parameter state as tensors named ``<parameter index>.<name>``, and its parameter groups."""
    state = optimizer.state_dict()
    tensors = {f"{index}.{name}": th.as_tensor(value) for index, entries in state["state"].items() for name, value in entries.items()}
    groups = [{k: list(v) if isinstance(v, tuple) else v for k, v in group.items()} for group in state["param_groups"]]
    return tensors, groups


def _name_of(table: Mapping[str, type], cls: Any, what: str) -> str:
    for name, known in table.items():
        if cls is known:
            return name
    raise ValueError(f"agent files name the {what} among {sorted(table)}, got {cls!r}")


def _class(table: Mapping[str, type], name: Any, where: str) -> type:
    if not isinstance(name, str) or name not in table:
        raise ValueError(f"{where} must be one of {sorted(table)}, got {name!r}")
    return table[name]



def _shape(values: list[Any], where: str) -> tuple[int, ...]:
    if not all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in values):
        raise ValueError(f"{where}.shape must be a list of integers >= 0, got {values}")
    return tuple(values)


def _numbers(array: np.ndarray) -> list[float | str]:
    """Flattened, as JSON numbers; the non-finite as the strings "inf", "-inf", "nan" (not JSON numbers)."""
    return [float(x) if math.isfinite(x) else str(float(x)) for x in np.ravel(array)]


def _array(values: list[Any], shape: tuple[int, ...], dtype: Any, where: str) -> np.ndarray:
    size = math.prod(shape)
    if len(values) != size or not all(isinstance(v, (int, float)) and not isinstance(v, bool) or v in ("inf", "-inf", "nan") for v in values):
        raise ValueError(f"{where} must hold {size} numbers (shape {list(shape)}), got {len(values)} values")
    return np.array([float(v) for v in values], dtype=dtype).reshape(shape)


def _number(value: float, where: str) -> float:
    if not math.isfinite(value):
        raise ValueError(f"{where} must be finite, got {value}")
    return float(value)


def _positive(value: float, where: str) -> float:
    """A clip or an epsilon: a finite number > 0 (a negative clip would clip every observation to its negative bound)."""
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{where} must be a finite number > 0, got {value}")
    return float(value)


def _fraction(value: float, where: str) -> float:
    if not 0 <= value <= 1:
        raise ValueError(f"{where} must be a number in [0, 1], got {value}")
    return float(value)


def _regular(path: Path) -> Path:
    """``path``, if it is a regular file (a FIFO would block the reader)."""
    if not path.is_file():
        raise ValueError(f"{path}: not a regular file")
    return path


def _first_line(error: BaseException) -> str:
    return str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
