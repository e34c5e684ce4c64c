"""The Gymnasium ``info`` of the maintenance environments, built in one place for the single, the
native vector and the stable-baselines3 environments.

Keys: ``true_parameters`` (parameter name -> value), ``true_rul`` (s: a float with one fault per system;
where every part ages, an array (n,) of each maintainable component's), ``cost`` (cost item -> the
step's cost: each action kind's item, failure, lost production and the total), ``failed`` (a
parameter left its safe limits this step), ``events`` (the step's events' texts, see ``ea_gym.env.events``).

Layouts (``INFO_LAYOUTS``, the environments' ``info_layout``): ``"nested"`` (the default) as above;
``"flat"`` for libraries that make a tensor of every info (TorchRL's ``GymEnv``), which can batch neither
lists of texts nor nested dicts with their masks: one level of numbers, ``true_rul`` (per part:
``true_rul_<component>``), ``failed``, ``cost_<item>`` and ``true_parameters_<name>``, and no ``events``.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ea_gym.env.events import ActionKind, Event


def cost_items(kinds: Iterable[ActionKind]) -> tuple[str, ...]:
    """The cost items of an environment whose actions are of ``kinds``: each kind's item, in their order,
    then failure and lost production (which no order buys), then the total."""
    items = [kind.cost_item for kind in kinds if kind.cost_item is not None]
    return (*dict.fromkeys(items), "failure", "lost_production", "total")


INFO_LAYOUTS = ("nested", "flat")


def check_info_layout(layout: object) -> str:
    """``layout`` if it is one of ``INFO_LAYOUTS``; a ValueError naming them otherwise."""
    if not isinstance(layout, str) or layout not in INFO_LAYOUTS:
        raise ValueError(f"info_layout must be one of {INFO_LAYOUTS}, got {layout!r}")
    return layout


#: the cost items of the environments' default action kinds (carry on, corrective action, replacement)
COST_ITEMS = cost_items((ActionKind.CARRY_ON, ActionKind.CORRECTIVE, ActionKind.REPLACE))


@dataclass(frozen=True)
class StepInfo:
    """What N systems report after a step (or a reset): the ground truth, costs and events.

    Attributes:
        parameter_names: the model's parameters (P), in the columns' order.
        true_parameters: (N, P).
        true_rul: (N,) s; where every part ages, (N, n), a column per component of ``rul_columns``.
        costs: per cost item (``cost_items``), (N,).
        failed: (N,) bool.
        events: N lists of events.
        rul_columns: the components of ``true_rul``'s columns; () for one RUL per system.
    """

    parameter_names: tuple[str, ...]
    true_parameters: np.ndarray
    true_rul: np.ndarray
    costs: dict[str, np.ndarray]
    failed: np.ndarray
    events: Sequence[Sequence[Event]]
    rul_columns: tuple[str, ...] = ()

    @classmethod
    def at_reset(
        cls, parameter_names: tuple[str, ...], true_parameters: np.ndarray, true_rul: np.ndarray, items: Sequence[str],
        rul_columns: tuple[str, ...] = (),
    ) -> StepInfo:
        """After a reset: the true state, no cost in any of the cost ``items``, no failure, no event."""
        n = len(true_rul)
        return cls(
            parameter_names, true_parameters, true_rul, {key: np.zeros(n) for key in items}, np.zeros(n, dtype=bool),
            [[] for _ in range(n)], rul_columns,
        )

    def _rul_numbers(self) -> dict[str, np.ndarray]:
        """The true RUL's columns (N,) by their flat key: ``true_rul``, or ``true_rul_<component>`` per part."""
        if not self.rul_columns:
            return {"true_rul": self.true_rul}
        return {f"true_rul_{name}": self.true_rul[:, d] for d, name in enumerate(self.rul_columns)}

    def system(self, i: int, layout: str = "nested") -> dict[str, Any]:
        """The ``info`` of system i, in ``layout`` (one of ``INFO_LAYOUTS``)."""
        if layout == "flat":
            return {**{key: value.item(i) for key, value in self._rul_numbers().items()}, "failed": self.failed.item(i),
                    **{f"cost_{key}": value.item(i) for key, value in self.costs.items()},
                    **{f"true_parameters_{name}": value for name, value in zip(self.parameter_names, self.true_parameters[i].tolist())}}
        return {
            "true_parameters": dict(zip(self.parameter_names, self.true_parameters[i].tolist())),
            # item: the Python float (bool) at once, no numpy scalar between; per part an array of its own
            "true_rul": self.true_rul[i].copy() if self.rul_columns else self.true_rul.item(i),
            "cost": {key: value.item(i) for key, value in self.costs.items()},
            "failed": self.failed.item(i),
            "events": [str(event) for event in self.events[i]],
        }

    def where(self, mask: np.ndarray, other: StepInfo) -> StepInfo:
        """This info with the rows of the systems in the boolean ``mask`` (N,) taken from ``other``."""
        rows = np.asarray(mask, dtype=bool)
        column = rows[:, None]
        return StepInfo(
            self.parameter_names,
            np.where(column, other.true_parameters, self.true_parameters),
            np.where(column if self.rul_columns else rows, other.true_rul, self.true_rul),
            {key: np.where(rows, other.costs[key], value) for key, value in self.costs.items()},
            np.where(rows, other.failed, self.failed),
            [theirs if chosen else ours for chosen, ours, theirs in zip(rows.tolist(), self.events, other.events)],
            self.rul_columns,
        )

    def batched(self, mask: np.ndarray, layout: str = "nested") -> dict[str, Any]:
        """The vector environment's ``info`` for the systems in the boolean ``mask`` (N,), laid out as
        Gymnasium's ``VectorEnv._add_info`` lays out the single environments' infos: every key's values
        in an array over the N systems (zero, False or None where the mask is False), nested dicts
        likewise, each key beside its ``_key`` mask. Empty when no system is in the mask. ``layout``: one of
        ``INFO_LAYOUTS``, as the single environments' ``system`` lays them out."""
        rows = np.asarray(mask, dtype=bool)
        if not rows.any():
            return {}
        if layout == "flat":
            columns = {**self._rul_numbers(), **{f"cost_{key}": value for key, value in self.costs.items()},
                       **{f"true_parameters_{name}": self.true_parameters[:, j] for j, name in enumerate(self.parameter_names)}}
            return _with_masks({"failed": self.failed & rows, **{key: np.where(rows, value, 0.0) for key, value in columns.items()}}, rows)
        events = np.full(len(rows), None, dtype=object)
        for i in np.flatnonzero(rows).tolist():
            events[i] = [str(event) for event in self.events[i]]
        values: dict[str, Any] = {
            "true_parameters": _masked({name: self.true_parameters[:, j] for j, name in enumerate(self.parameter_names)}, rows),
            "true_rul": np.where(rows[:, None] if self.rul_columns else rows, self.true_rul, 0.0),
            "cost": _masked(self.costs, rows),
            "failed": self.failed & rows,
            "events": events,
        }
        return _with_masks(values, rows)


def _masked(columns: dict[str, np.ndarray], rows: np.ndarray) -> dict[str, Any]:
    """Float columns (N,) as ``_add_info`` batches them: zero outside ``rows``, each with its mask."""
    return _with_masks({key: np.where(rows, value, 0.0) for key, value in columns.items()}, rows)


def _with_masks(values: dict[str, Any], rows: np.ndarray) -> dict[str, Any]:
    infos: dict[str, Any] = {}
    for key, value in values.items():
        infos[key] = value
        infos[f"_{key}"] = rows.copy()  # one mask per key, as Gymnasium's (a caller may write into one)
    return infos
