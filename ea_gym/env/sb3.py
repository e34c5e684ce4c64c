"""A stable-baselines3 ``VecEnv`` over the batched maintenance core (no subprocesses, no per-env loop)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn

from ea_gym.env.vector import BondGraphMaintenanceVectorEnv


class MaintenanceVecEnv(VecEnv):
    """N maintenance environments for stable-baselines3, stepped as one batch.

    Same episodes as N ``BondGraphMaintenanceEnv`` in a ``DummyVecEnv`` seeded alike (``seed(s)`` gives
    system i the seed s + i), with SB3's conventions: finished episodes restart at once, the last
    observation is in ``info["terminal_observation"]`` and truncation in ``info["TimeLimit.truncated"]``.
    Wrap it in SB3's ``VecMonitor``, as any ``VecEnv``, for the episodes' returns and lengths in
    ``info["episode"]`` (SB3's logs and ``evaluate_policy`` read them there).

    Args:
        num_envs: N.
        **kwargs: the environments' keyword arguments (system, obs_mode, ...); v0's world unless they say otherwise:
            ``MaintenanceVecEnv(N, **ea_gym.env.V1_SETTINGS)`` is v1's, where every part ages.
    """

    def __init__(self, num_envs: int, **kwargs: Any):
        self.venv = BondGraphMaintenanceVectorEnv(num_envs, autoreset_mode=AutoresetMode.SAME_STEP, **kwargs)
        super().__init__(num_envs, self.venv.single_observation_space, self.venv.single_action_space)
        self._actions: np.ndarray | None = None

    def reset(self) -> VecEnvObs:
        seeds = None if all(s is None for s in self._seeds) else self._seeds
        observation, _ = self.venv.reset(seed=seeds)
        self.reset_infos = [self.venv.step_info.system(i, self.venv.info_layout) for i in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        return observation

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions).reshape(self.num_envs)

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait() needs the actions of step_async()")
        observation, rewards, terminated, truncated, infos = self.venv.step(self._actions)
        dones = terminated | truncated
        per_env = []
        for i in range(self.num_envs):
            info = self.venv.step_info.system(i, self.venv.info_layout)  # the step's info; an ended episode's last one
            if dones[i]:
                info["terminal_observation"] = infos["final_obs"][i]
                self.reset_infos[i] = self.venv.core.reset_info().system(i, self.venv.info_layout)
            info["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            per_env.append(info)
        return observation, rewards.astype(np.float32), dones, per_env

    def close(self) -> None:
        self.venv.close()

    def _indices(self, indices: VecEnvIndices) -> Sequence[int]:
        if indices is None:
            return range(self.num_envs)
        return [indices] if isinstance(indices, int) else list(indices)

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """Attributes are shared by the batch (model, spaces, action meanings...)."""
        return [getattr(self.venv, attr_name) for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        raise AttributeError(f"the batched environments share their attributes; cannot set {attr_name!r} per environment")

    def env_method(self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs) -> list[Any]:
        raise AttributeError(f"the batched environments have no per-environment methods; cannot call {method_name!r}")

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._indices(indices)]
