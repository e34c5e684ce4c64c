"""The native batched maintenance environment: N machines stepped in array operations.

``gymnasium.make_vec("ea_gym/SpringMassDamper-v0", num_envs=N, vectorization_mode="vector_entry_point")``
returns it. The N systems share one ``MaintenanceCore`` (one simulation, one PHM chain, one call of the
isolation network per step for the whole batch); system i draws only from its own generator, seeded
like the i-th environment of a ``SyncVectorEnv`` (seed + i), so its episodes equal those of a single
environment reset with that seed.

It behaves as Gymnasium's ``SyncVectorEnv`` of single environments, step for step (tests/test_vector_env.py):

- ``autoreset_mode`` (``gymnasium.vector.AutoresetMode`` or its value as a string, declared in
  ``metadata["autoreset_mode"]``): ``NEXT_STEP`` (the default) returns an ended episode's last step as
  any other; the next ``step`` ignores that system's action and returns the first observation of its
  next episode, with reward 0, no termination or truncation and the reset's info. ``SAME_STEP``
  returns the next episode's first observation in the step that ended the episode; the last
  observation and info are in ``infos["final_obs"]`` (an object array of observations) and
  ``infos["final_info"]`` (a dict of batched arrays), masked by ``infos["_final_obs"]`` and
  ``infos["_final_info"]``. ``DISABLED`` never resets by itself: reset the ended systems with
  ``reset(options={"reset_mask": mask})`` before the next step.
- infos: Gymnasium's layout, each key's values in an array over the N systems beside its ``_key``
  mask, nested dicts likewise (``infos["cost"]["total"]``, ``infos["cost"]["_total"]``);
  ``info_layout="flat"`` gives the single environment's flat layout (``ea_gym.env.infos``).
- ``spec.max_episode_steps``: the horizon (``ea_gym.env.specs``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ea_gym.env.config import MAX_ENVS, check_reset_arguments
from ea_gym.env.core import MaintenanceCore
from ea_gym.env.infos import StepInfo, check_info_layout
from ea_gym.env.maintenance import build_core
from ea_gym.env.observations import Observation
from ea_gym.env.specs import HorizonSpec


class BondGraphMaintenanceVectorEnv(HorizonSpec, VectorEnv[Observation, np.ndarray, np.ndarray]):
    """N maintenance environments in one batch; see ``BondGraphMaintenanceEnv`` for the task.

    Args:
        num_envs: N.
        autoreset_mode: how ended episodes restart (see the module docstring).
        info_layout: ``"nested"`` or ``"flat"`` (numbers only, for TorchRL; ``ea_gym.env.infos``).
        **kwargs: the single environment's keyword arguments (system, config, classifier, and
            ``EnvConfig`` overrides: obs_mode, step_seconds, ...).

    ``step_info`` holds what the systems reported at the last reset, or at the last step before a
    ``SAME_STEP`` autoreset put the new episodes' reset info in the returned infos.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int = 1,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        info_layout: str = "nested",
        **kwargs: Any,
    ):
        if not (isinstance(num_envs, int) and not isinstance(num_envs, bool) and 0 < num_envs <= MAX_ENVS):
            raise ValueError(f"num_envs must be an int in [1, {MAX_ENVS}], got {num_envs!r}")
        if render_mode is not None:
            raise ValueError(f"the batched environment does not render; render_mode must be None, got {render_mode!r}")
        self.autoreset_mode = _autoreset_mode(autoreset_mode)
        self.info_layout = check_info_layout(info_layout)
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
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
        # a NEXT_STEP restart's system is stepped with the rest and then reset: it draws from its own
        # spare generator meanwhile, so that its own generator serves the reset alone, as in SyncVectorEnv
        self._spare_generators = [np.random.default_rng(i) for i in range(num_envs)]
        self._ended = np.zeros(num_envs, dtype=bool)  # at the last step: restart (NEXT_STEP) or await a reset (DISABLED)
        self._observation: Observation | None = None  # the last observation returned (a private copy)
        self.step_info: StepInfo = self.core.reset_info()

    def reset(
        self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Observation, dict[str, Any]]:
        """Reset every system, or those in ``options["reset_mask"]`` (a bool array (N,)).

        ``seed``: an int (system i gets seed + i), a list of N seeds (None keeps a system's generator
        going), or None. The infos hold the reset systems' info; the others keep their last observation.
        """
        seeds = self._seeds(seed)
        mask = _reset_mask(check_reset_arguments(None, options, known=("reset_mask",)).get("reset_mask"), self.num_envs)
        if mask is not None and self._observation is None:
            raise RuntimeError("reset(options={'reset_mask': ...}) needs a first reset of every system")
        systems = np.ones(self.num_envs, dtype=bool) if mask is None else mask
        for i in np.flatnonzero(systems).tolist():
            if seeds[i] is not None:
                self._generators[i] = seeding.np_random(seeds[i])[0]
        fresh = self.core.reset(self._generators, mask)
        self._ended &= ~systems
        self.step_info = self.core.reset_info()
        observation = fresh if mask is None or self._observation is None else _merge_rows(mask, fresh, self._observation)
        return self._returned(observation), self.step_info.batched(systems, self.info_layout)

    def step(self, actions: np.ndarray) -> tuple[Observation, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        actions = np.asarray(actions)
        n_actions = len(self.action_meanings)
        if (
            actions.shape != (self.num_envs,)
            or not np.issubdtype(actions.dtype, np.integer)
            or np.any((actions < 0) | (actions >= n_actions))
        ):
            raise ValueError(f"actions must be {self.num_envs} ints in [0, {n_actions - 1}] ({self.action_meanings}), got {actions!r}")
        if self._observation is None:
            raise RuntimeError("step() before reset(): reset the environment first")
        if self.autoreset_mode is AutoresetMode.DISABLED and self._ended.any():
            raise RuntimeError(
                f"systems {np.flatnonzero(self._ended).tolist()} ended their episodes; with autoreset_mode DISABLED, "
                "reset them with reset(options={'reset_mask': mask}) before the next step"
            )
        restart = self._ended if self.autoreset_mode is AutoresetMode.NEXT_STEP else np.zeros(self.num_envs, dtype=bool)
        rngs: Sequence[np.random.Generator] = self._generators
        if restart.any():
            rngs = [spare if again else own for again, own, spare in zip(restart.tolist(), self._generators, self._spare_generators)]
            actions = np.where(restart, 0, actions)
        result = self.core.step(actions, rngs)
        observation, info = result.observation, result.info
        rewards = result.reward.astype(np.float64)
        terminated, truncated = result.terminated, result.truncated
        if restart.any():
            observation = _merge_rows(restart, self.core.reset(self._generators, restart), observation)
            info = info.where(restart, self.core.reset_info())
            rewards = np.where(restart, 0.0, rewards)
            terminated, truncated = terminated & ~restart, truncated & ~restart
        self.step_info = info
        ended = terminated | truncated
        infos: dict[str, Any] = {}
        if self.autoreset_mode is AutoresetMode.SAME_STEP and ended.any():
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in np.flatnonzero(ended).tolist():
                final_obs[i] = {key: value[i] for key, value in observation.items()}
            infos.update(final_obs=final_obs, _final_obs=ended.copy(), final_info=info.batched(ended, self.info_layout), _final_info=ended.copy())
            observation = _merge_rows(ended, self.core.reset(self._generators, ended), observation)
            info = info.where(ended, self.core.reset_info())
        self._ended = ended
        infos.update(info.batched(np.ones(self.num_envs, dtype=bool), self.info_layout))
        return self._returned(observation), rewards, terminated, truncated, infos

    def _seeds(self, seed: int | Sequence[int | None] | None) -> list[int | None]:
        if seed is None:
            return [None] * self.num_envs
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            return [int(seed) + i for i in range(self.num_envs)]
        if isinstance(seed, (str, bytes)) or not isinstance(seed, Sequence):
            raise TypeError(f"seed must be an int, None or a list of {self.num_envs} ints or None, got {seed!r}")
        seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise ValueError(f"seed must be an int, None or a list of {self.num_envs} seeds, got {len(seeds)} seeds")
        for s in seeds:
            if s is not None and (isinstance(s, bool) or not isinstance(s, (int, np.integer))):
                raise TypeError(f"seed must be an int, None or a list of {self.num_envs} ints or None, got {s!r} in the list")
        return [None if s is None else int(s) for s in seeds]

    def _returned(self, observation: Observation) -> Observation:
        """Keep a private copy of what is returned: a later partial reset shows it for the other systems."""
        self._observation = {key: value.copy() for key, value in observation.items()}
        return observation


class SpringMassDamperVectorEnv(BondGraphMaintenanceVectorEnv):
    """N spring-mass-damper maintenance environments in one batch."""

    def __init__(self, num_envs: int = 1, **kwargs: Any):
        if "system" in kwargs:
            raise TypeError("SpringMassDamper is the spring-mass-damper; use BondGraphMaintenance (same version) for another system")
        super().__init__(num_envs, system="spring_mass_damper", **kwargs)


def _autoreset_mode(mode: AutoresetMode | str) -> AutoresetMode:
    if isinstance(mode, AutoresetMode):
        return mode
    values = [m.value for m in AutoresetMode]
    if isinstance(mode, str) and mode in values:
        return AutoresetMode(mode)
    raise ValueError(f"autoreset_mode must be a gymnasium.vector.AutoresetMode or one of {values}, got {mode!r}")


def _reset_mask(mask: Any, n: int) -> np.ndarray | None:
    """``options["reset_mask"]`` checked as ``SyncVectorEnv`` checks it: None, or a bool array (n,) with a True."""
    if mask is None:
        return None
    if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_ or mask.shape != (n,):
        raise ValueError(f"options['reset_mask'] must be a numpy bool array of shape ({n},), got {mask!r}")
    if not mask.any():
        raise ValueError(f"options['reset_mask'] must hold at least one True value, got {mask!r}")
    return mask.copy()


def _merge_rows(rows: np.ndarray, chosen: Observation, others: Observation) -> Observation:
    """New observation arrays: ``chosen``'s rows where ``rows`` (N,) is True, ``others``' elsewhere."""
    return {key: np.where(rows.reshape((-1,) + (1,) * (value.ndim - 1)), chosen[key], others[key]) for key, value in chosen.items()}
