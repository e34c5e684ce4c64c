"""The native batched maintenance environment: N machines stepped in array operations.

``gymnasium.make_vec("ea_gym/SpringMassDamper-v0", num_envs=N, vectorization_mode="vector_entry_point")``
returns it. The N systems share one ``MaintenanceCore`` (one simulation, one PHM chain, one call of the
isolation network per step for the whole batch); system i draws only from its own generator, seeded
like the i-th environment of a ``SyncVectorEnv`` (seed + i), so its episodes equal those of a single
environment reset with that seed.

Autoreset: Gymnasium's ``AutoresetMode.SAME_STEP``. When a system's episode ends, the same ``step``
returns the first observation of its next episode; the last observation and info of the ended
episode are in ``infos["final_obs"]`` and ``infos["final_info"]`` (masked by ``infos["_final_obs"]``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ea_gym.env.core import MaintenanceCore
from ea_gym.env.infos import StepInfo
from ea_gym.env.maintenance import build_core
from ea_gym.env.observations import Observation


class BondGraphMaintenanceVectorEnv(VectorEnv[Observation, np.ndarray, np.ndarray]):
    """N maintenance environments in one batch; see ``BondGraphMaintenanceEnv`` for the task.

    Args:
        num_envs: N.
        **kwargs: the single environment's keyword arguments (system, config, classifier, and
            ``EnvConfig`` overrides: obs_mode, step_seconds, ...).

    ``step_info`` holds what the systems reported at the last step or reset (the infos' source).
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(self, num_envs: int = 1, render_mode: str | None = None, **kwargs: Any):
        if not (isinstance(num_envs, int) and num_envs > 0):
            raise ValueError(f"num_envs must be a positive int, got {num_envs!r}")
        if render_mode is not None:
            raise ValueError(f"the batched environment does not render; render_mode must be None, got {render_mode!r}")
        self.core: MaintenanceCore = build_core(num_envs, **kwargs)
        self.num_envs = num_envs
        self.render_mode = None
        self.actions = self.core.actions
        self.action_meanings = self.core.action_meanings
        self.diagnosis_classes = self.core.classes
        self.maintainable_components = self.core.components
        self.elements = self.core.elements
        self.nominal_parameters = self.core.nominal_parameters
        self.safe_limits = self.core.safe_limits
        self.single_action_space = spaces.Discrete(len(self.action_meanings))
        self.action_space = spaces.MultiDiscrete(np.full(num_envs, len(self.action_meanings)))
        self.single_observation_space = self.core.observer.space()
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self._generators = [seeding.np_random(None)[0] for _ in range(num_envs)]
        self.step_info: StepInfo = self.core.reset_info()

    def reset(
        self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Observation, dict[str, Any]]:
        """Reset every system; ``seed`` is an int (system i gets seed + i), a list of N seeds, or None."""
        seeds: list[int | None]
        if seed is None:
            seeds = [None] * self.num_envs
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"seed must be an int, None or a list of {self.num_envs} seeds, got {len(seeds)} seeds")
        self._generators = [seeding.np_random(s)[0] for s in seeds]
        observation = self.core.reset(self._generators)
        self.step_info = self.core.reset_info()
        return observation, self.step_info.batched(np.ones(self.num_envs, dtype=bool))

    def step(self, actions: np.ndarray) -> tuple[Observation, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        actions = np.asarray(actions)
        n_actions = len(self.action_meanings)
        if (
            actions.shape != (self.num_envs,)
            or not np.issubdtype(actions.dtype, np.integer)
            or np.any((actions < 0) | (actions >= n_actions))
        ):
            raise ValueError(f"actions must be {self.num_envs} ints in [0, {n_actions - 1}] ({self.action_meanings}), got {actions!r}")
        result = self.core.step(actions, self._generators)
        self.step_info = result.info
        done = result.terminated | result.truncated
        infos = result.info.batched(np.ones(self.num_envs, dtype=bool))
        observation = result.observation
        if np.any(done):
            final_obs = np.empty(self.num_envs, dtype=object)
            final_info = np.empty(self.num_envs, dtype=object)
            for i in np.flatnonzero(done):
                final_obs[i] = {key: value[i] for key, value in observation.items()}
                final_info[i] = result.info.system(int(i))
            fresh = self.core.reset(self._generators, done)
            observation = {key: np.where(_rows(done, value), fresh[key], value) for key, value in observation.items()}
            infos.update(final_obs=final_obs, _final_obs=done, final_info=final_info, _final_info=done)
        return observation, result.reward.astype(np.float64), result.terminated, result.truncated, infos


class SpringMassDamperVectorEnv(BondGraphMaintenanceVectorEnv):
    """N spring-mass-damper maintenance environments in one batch."""

    def __init__(self, num_envs: int = 1, **kwargs: Any):
        if "system" in kwargs:
            raise TypeError("SpringMassDamper-v0 is the spring-mass-damper; use BondGraphMaintenance-v0 for another system")
        super().__init__(num_envs, system="spring_mass_damper", **kwargs)


def _rows(mask: np.ndarray, like: np.ndarray) -> np.ndarray:
    return mask.reshape((-1,) + (1,) * (like.ndim - 1))
