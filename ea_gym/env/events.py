"""Actions and events as typed values.

An action is a kind (carry on, corrective action, replacement, or one a user adds) and, for a kind
that acts on a component, a component; its ``str`` is its meaning in ``env.unwrapped.action_meanings``.
An event (a corrective step taken, a replacement, a failure) is a small frozen dataclass whose ``str``
is the text in ``info["events"]``. Infos and logs keep the text (plain strings: JSON, pickling and
comparisons as before); ``parse_action`` and ``parse_event`` turn a text back into its value, the one
place that reads it.

Kinds and event types register themselves: every ``ActionKind`` made is known to ``parse_action`` by
its text, and every subclass of ``Event`` to ``parse_event``, so that one defined outside the library
reads back as the built-in ones do. What a kind does to the machines is its handler's
(``ea_gym.env.actions``).
"""

from __future__ import annotations

import operator
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import ClassVar

from ea_gym.env.costs import CostModel


def no_cost(costs: CostModel) -> float:
    """The price of an action that costs nothing of its own."""
    return 0.0


def no_downtime(costs: CostModel) -> int:
    """The downtime of an action that does not stop the machine (steps)."""
    return 0


#: every kind made, by its text: what ``parse_action`` reads meanings with
_KINDS: dict[str, ActionKind] = {}


@dataclass(frozen=True)
class ActionKind:
    """What an action does, named and priced; its handler (``ea_gym.env.actions``) does it.

    Two kinds are the same kind when their ``text`` and ``on_component`` are; a kind made registers
    itself under its text (a text taken by another kind is refused).

    Attributes:
        text: its meaning's text before the component ("replace").
        on_component: it acts on one component (one action per maintainable component) or on the
            machine (one action).
        cost_item: the ``info["cost"]`` key its price is counted under; None for an action without one.
        price: its price per order given, from the environment's cost model (monetary unit).
        downtime: steps without production it costs, from the cost model.
        maintains: an order of it is maintenance: it restarts ``time_since_maintenance``.
    """

    text: str
    on_component: bool = True
    cost_item: str | None = field(default=None, compare=False)
    price: Callable[[CostModel], float] = field(default=no_cost, compare=False)
    downtime: Callable[[CostModel], int] = field(default=no_downtime, compare=False)
    maintains: bool = field(default=True, compare=False)

    CARRY_ON: ClassVar[ActionKind]
    CORRECTIVE: ClassVar[ActionKind]
    REPLACE: ClassVar[ActionKind]

    def __post_init__(self) -> None:
        if not self.text or self.text != self.text.strip():
            raise ValueError(f"an action kind's text must be non-empty without outer spaces, got {self.text!r}")
        known = _KINDS.get(self.text)
        if known is not None and known != self:
            raise ValueError(f"action kind {self.text!r} exists already (on_component={known.on_component})")
        _KINDS[self.text] = self

    def immediate_cost(self, costs: CostModel) -> float:
        """Its cost on the step it is given: its price and its downtime's lost production."""
        return self.price(costs) + self.downtime(costs) * costs.lost_production


ActionKind.CARRY_ON = ActionKind("carry on", on_component=False, maintains=False)
ActionKind.CORRECTIVE = ActionKind("corrective action on", cost_item="corrective", price=operator.attrgetter("corrective"))
ActionKind.REPLACE = ActionKind(
    "replace", cost_item="replacement", price=operator.attrgetter("replacement"), downtime=operator.attrgetter("replace_downtime")
)


@dataclass(frozen=True)
class Action:
    """One entry of the action space: ``kind`` on ``component`` (None for a kind that acts on the machine)."""

    kind: ActionKind
    component: str | None = None

    def __post_init__(self) -> None:
        if (self.component is not None) != self.kind.on_component:
            raise ValueError(f"action {self.kind.text!r}: a component is needed exactly for the kinds that act on one")

    def __str__(self) -> str:
        return self.kind.text if self.component is None else f"{self.kind.text} {self.component}"


def action_table(components: tuple[str, ...], kinds: Iterable[ActionKind]) -> tuple[Action, ...]:
    """The action space's actions in index order: each kind in turn, on each component for a kind that
    acts on one (today's kinds: carry on, a corrective action on each component, the replacement of each)."""
    return tuple(action for kind in kinds for action in (
        [Action(kind, c) for c in components] if kind.on_component else [Action(kind)]
    ))


def parse_action(meaning: str) -> Action:
    """The action whose ``str`` is ``meaning``, of any kind made (the longest kind's text that fits)."""
    kind = _KINDS.get(meaning)
    if kind is not None and not kind.on_component:
        return Action(kind)
    for text, kind in sorted(_KINDS.items(), key=lambda item: -len(item[0])):
        prefix = text + " "
        if kind.on_component and meaning.startswith(prefix) and len(meaning) > len(prefix):
            return Action(kind, meaning[len(prefix) :])
    raise ValueError(f"not an action meaning: {meaning!r}")


class Event:
    """What happened to a machine in a step; ``str`` is its text in ``info["events"]``.

    A subclass registers itself with ``parse_event``: its ``parse`` reads its own text back.
    """

    #: every event type defined, in the order defined: the ones ``parse_event`` tries
    types: ClassVar[list[type[Event]]] = []

    def __init_subclass__(cls, **kwargs: object) -> None:
        super().__init_subclass__(**kwargs)
        Event.types.append(cls)

    @classmethod
    def parse(cls, text: str) -> Event | None:
        """The event of this type whose ``str`` is ``text``; None if ``text`` is not one."""
        raise NotImplementedError(f"{cls.__name__} must define parse")


@dataclass(frozen=True)
class ComponentEvent(Event):
    """An event on one ``component`` whose text is its ``prefix`` and the component's name; a subclass
    names its ``prefix`` and is done."""

    component: str
    prefix: ClassVar[str | None] = None

    def __str__(self) -> str:
        return f"{self.prefix} {self.component}"

    @classmethod
    def parse(cls, text: str) -> ComponentEvent | None:
        if cls.prefix is None or not text.startswith(cls.prefix + " "):
            return None
        component = text[len(cls.prefix) + 1 :]
        return None if " " in component else cls(component)


class CorrectiveStep(ComponentEvent):
    """A step of corrective action on ``component``."""

    prefix = "corrective action on"


@dataclass(frozen=True)
class Replacement(Event):
    """A new ``component``, the machine down for ``downtime`` steps."""

    component: str
    downtime: int

    def __str__(self) -> str:
        return f"replacement of {self.component} ({self.downtime} steps down)"

    @classmethod
    def parse(cls, text: str) -> Replacement | None:
        match = _REPLACEMENT.fullmatch(text)
        return None if match is None else cls(match["component"], int(match["downtime"]))


@dataclass(frozen=True)
class Failure(Event):
    """``component``'s parameter at ``value`` left its safe ``limits`` (low, high)."""

    component: str
    value: float
    limits: tuple[float, float]

    def __str__(self) -> str:
        return f"failure: {self.component} = {self.value:.4g} outside {self.limits}"

    @classmethod
    def parse(cls, text: str) -> Failure | None:
        """A failure's value and limits as printed: to 4 digits."""
        match = _FAILURE.fullmatch(text)
        if match is None:
            return None
        low, high = (_number(match[key]) for key in ("low", "high"))
        return cls(match["component"], float(match["value"]), (low, high))


_REPLACEMENT = re.compile(r"replacement of (?P<component>\S+) \((?P<downtime>\d+) steps down\)")
_FAILURE = re.compile(r"failure: (?P<component>\S+) = (?P<value>\S+) outside \((?P<low>.+), (?P<high>.+)\)")
_NUMBER = re.compile(r"(?:np\.float64\()?(?P<number>[^()]+)\)?")


def parse_event(text: str) -> Event:
    """The event whose ``str`` is ``text``, of any event type defined."""
    for event_type in Event.types:
        event = event_type.parse(text)
        if event is not None:
            return event
    raise ValueError(f"not an event: {text!r}")


def _number(text: str) -> float:
    match = _NUMBER.fullmatch(text)
    if match is None:
        raise ValueError(f"not a number: {text!r}")
    return float(match["number"])
