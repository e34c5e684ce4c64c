"""The Gymnasium ``info`` of the maintenance environments, built in one place for the single, the
native vector and the stable-baselines3 environments.

Keys: ``true_parameters`` (parameter name -> value), ``true_rul`` (s), ``cost`` (cost item -> the
step's cost), ``failed`` (a parameter left its safe limits this step), ``events`` (the step's events'
texts, see ``ea_gym.env.events``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ea_gym.env.events import Event

COST_ITEMS = ("corrective", "replacement", "failure", "lost_production", "total")


@dataclass(frozen=True)
class StepInfo:
    """What N systems report after a step (or a reset): the ground truth, costs and events.

    Attributes:
        parameter_names: the model's parameters (P), in the columns' order.
        true_parameters: (N, P).
        true_rul: (N,), s.
        costs: per cost item of ``COST_ITEMS``, (N,).
        failed: (N,) bool.
        events: N lists of events.
    """

    parameter_names: tuple[str, ...]
    true_parameters: np.ndarray
    true_rul: np.ndarray
    costs: dict[str, np.ndarray]
    failed: np.ndarray
    events: Sequence[Sequence[Event]]

    @classmethod
    def at_reset(cls, parameter_names: tuple[str, ...], true_parameters: np.ndarray, true_rul: np.ndarray) -> StepInfo:
        """After a reset: the true state, no cost, no failure, no event."""
        n = len(true_rul)
        return cls(
            parameter_names, true_parameters, true_rul, {key: np.zeros(n) for key in COST_ITEMS}, np.zeros(n, dtype=bool),
            [[] for _ in range(n)],
        )

    def system(self, i: int) -> dict[str, Any]:
        """The ``info`` of system i."""
        return {
            "true_parameters": dict(zip(self.parameter_names, map(float, self.true_parameters[i]))),
            "true_rul": float(self.true_rul[i]),
            "cost": {key: float(value[i]) for key, value in self.costs.items()},
            "failed": bool(self.failed[i]),
            "events": [str(event) for event in self.events[i]],
        }

    def batched(self, mask: np.ndarray) -> dict[str, Any]:
        """The vector environment's ``info``: each key's values of all systems, with Gymnasium's
        ``_key`` mask of the systems the values stand for."""
        events = np.empty(len(self.events), dtype=object)
        events[:] = [[str(event) for event in happened] for happened in self.events]
        return {
            "true_parameters": {name: self.true_parameters[:, j] for j, name in enumerate(self.parameter_names)},
            "_true_parameters": mask,
            "true_rul": self.true_rul,
            "_true_rul": mask,
            "cost": dict(self.costs),
            "_cost": mask,
            "failed": self.failed,
            "_failed": mask,
            "events": events,
            "_events": mask,
        }
