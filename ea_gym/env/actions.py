"""What each kind of action does to the machines: one handler per ``ActionKind``.

``MaintenanceCore`` groups a step's orders by kind and hands each group to its kind's handler (the
systems that carry on, the common step, cost nothing). The handlers in use are the environment's
``action_kinds`` (``DEFAULT_ACTION_KINDS``: carry on, corrective action, replacement); their kinds, in
that order, make the action table (``ea_gym.env.events.action_table``), so the order fixes what each
index of the ``Discrete`` action space means. Carrying on comes first: it is the order a machine takes
while it is down.

A kind's cost comes with the kind: its price per order (counted under its ``cost_item`` in
``info["cost"]``; the built-in kinds read theirs from ``CostModel``) and its downtime (steps). The
handler does the rest: made once per environment with the ``Machines`` it acts on, it keeps what it
needs from step to step (the corrective action's heading) and ``apply`` carries out each step's
``Orders`` of its kind. Adding a kind takes its ``ActionKind``, the event it records (an
``ea_gym.env.events.Event``, whose ``str`` and ``parse`` a ``ComponentEvent`` has for a prefix and a
component) and its handler, and nothing else::

    import gymnasium as gym
    from ea_gym.env.actions import DEFAULT_ACTION_KINDS, ActionHandler, Orders
    from ea_gym.env.events import ActionKind, ComponentEvent

    INSPECT = ActionKind("inspect", cost_item="inspection", price=lambda costs: 2.0, maintains=False)

    class Inspection(ComponentEvent):
        prefix = "inspection of"

    class Inspect(ActionHandler):
        kind = INSPECT

        def apply(self, orders: Orders, rngs, events) -> None:
            for system, component in zip(orders.systems.tolist(), orders.components.tolist()):
                events[system].append(Inspection(self.machines.components[component]))

    env = gym.make("ea_gym/SpringMassDamper-v0", action_kinds=(*DEFAULT_ACTION_KINDS, Inspect))

The new actions follow the others ("inspect <c>" for each component, at the end of the table), so
the existing indices keep their meaning.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import ClassVar, Protocol

import numpy as np

from ea_gym.env.config import EnvConfig
from ea_gym.env.events import ActionKind, CorrectiveStep, Event


class Machines(Protocol):
    """What a handler reads and changes of the N machines (``ea_gym.env.core.MaintenanceCore`` is one)."""

    n: int
    components: tuple[str, ...]
    limits: np.ndarray
    config: EnvConfig

    def deviation(self, systems: np.ndarray, components: np.ndarray) -> np.ndarray:
        """Nominal minus the true value of ``components[k]``'s parameter in ``systems[k]`` (SI)."""
        ...

    def adjust(self, systems: np.ndarray, components: np.ndarray, change: np.ndarray) -> None:
        """Move ``components[k]``'s parameter in ``systems[k]`` by ``change[k]`` (SI), logged for the chain."""
        ...

    def replace(
        self, systems: np.ndarray, components: np.ndarray, downtime: int, rngs: Sequence[np.random.Generator], events: list[list[Event]]
    ) -> None:
        """Put a new ``components[k]`` in ``systems[k]``, the machine down for ``downtime`` steps."""
        ...


@dataclass(frozen=True)
class Orders:
    """A step's orders of one kind.

    Attributes:
        systems: (M,) the systems given them, distinct, ascending.
        components: (M,) each one's component, an index into ``Machines.components`` (-1 for a kind
            that acts on the machine).
        continued: (M,) the system was given the same order the step before, in the same episode.
    """

    systems: np.ndarray
    components: np.ndarray
    continued: np.ndarray


class ActionHandler(ABC):
    """Does what the actions of ``kind`` do; made by the core with the machines it acts on.

    A handler's price is counted by the core (``kind.price`` under ``kind.cost_item``); ``apply``
    changes the machines and records the events.
    """

    kind: ClassVar[ActionKind]

    def __init__(self, machines: Machines):
        self.machines = machines

    @abstractmethod
    def apply(self, orders: Orders, rngs: Sequence[np.random.Generator], events: list[list[Event]]) -> None:
        """Carry out ``orders`` (system i draws only from ``rngs[i]``; its events go to ``events[i]``)."""


#: what makes a handler for the machines: a handler class, or any callable taking the machines
HandlerFactory = Callable[[Machines], ActionHandler]


class CarryOn(ActionHandler):
    """The machine runs on: nothing to do, nothing to pay."""

    kind = ActionKind.CARRY_ON

    def apply(self, orders: Orders, rngs: Sequence[np.random.Generator], events: list[list[Event]]) -> None:
        """Nothing: wear and operation go on as for every running machine."""


class Corrective(ActionHandler):
    """One step of corrective action: the parameter moves toward nominal (and past it, if continued)
    at ``config.corrective_rate`` x its safe range per second (SI units per second)."""

    kind = ActionKind.CORRECTIVE

    def __init__(self, machines: Machines):
        super().__init__(machines)
        limits = machines.limits
        self.speed = machines.config.corrective_rate * (limits[:, 1] - limits[:, 0])  # per component, SI/s
        self.heading = np.zeros(machines.n)  # +1 or -1: where each system's corrective action under way goes

    def apply(self, orders: Orders, rngs: Sequence[np.random.Generator], events: list[list[Event]]) -> None:
        """A new corrective action heads for nominal (up where the parameter is at it); a continued one keeps its heading."""
        rows, d = orders.systems, orders.components
        new = ~orders.continued
        heading = np.sign(self.machines.deviation(rows[new], d[new]))
        self.heading[rows[new]] = np.where(heading == 0, 1.0, heading)
        change = self.heading[rows] * self.speed[d] * self.machines.config.step_seconds
        self.machines.adjust(rows, d, change)
        for i, component in zip(rows, d):
            events[i].append(CorrectiveStep(self.machines.components[component]))


class Replace(ActionHandler):
    """A new component: back to nominal, the machine down for ``kind.downtime`` steps."""

    kind = ActionKind.REPLACE

    def apply(self, orders: Orders, rngs: Sequence[np.random.Generator], events: list[list[Event]]) -> None:
        """Replace, the machine stopped and restarted (a new fault where the replaced component was the faulty one)."""
        downtime = self.kind.downtime(self.machines.config.costs)
        self.machines.replace(orders.systems, orders.components, downtime, rngs, events)


#: the environments' action kinds: index 0 carry on, 1..n corrective actions, n+1..2n replacements
DEFAULT_ACTION_KINDS: tuple[HandlerFactory, ...] = (CarryOn, Corrective, Replace)
