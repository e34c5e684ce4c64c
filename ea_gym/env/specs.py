"""The environments' ``spec``, with the episode length they keep themselves.

An environment here truncates its episodes at its own ``horizon`` (an ``EnvConfig`` field that ``gymnasium.make``
may override), so no TimeLimit is registered: one registered at the default horizon would add nothing to
a shorter episode and cut a longer one short. ``make`` then gives the environment a spec whose
``max_episode_steps`` is None; this mixin fills in the horizon, so ``env.spec.max_episode_steps`` is the
episode's length for any horizon, and ``gymnasium.make(env.spec)`` wraps a TimeLimit that truncates at the
same step as the environment. A ``max_episode_steps`` given to ``make`` wraps its TimeLimit as usual, and
the spec then reports that.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from gymnasium.envs.registration import EnvSpec

if TYPE_CHECKING:
    from ea_gym.env.core import MaintenanceCore


class HorizonSpec:
    """Mixin of the single and vector environments: ``spec.max_episode_steps`` from ``core.config.horizon``."""

    core: MaintenanceCore
    _spec: EnvSpec | None = None

    @property
    def spec(self) -> EnvSpec | None:
        """The spec ``make`` gave, its ``max_episode_steps`` the horizon where ``make`` left it None."""
        return self._spec

    @spec.setter
    def spec(self, value: EnvSpec | None) -> None:
        if value is not None and value.max_episode_steps is None:
            value = dataclasses.replace(value, max_episode_steps=self.core.config.horizon)
        self._spec = value
