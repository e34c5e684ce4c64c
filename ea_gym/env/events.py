"""Actions and events as typed values.

An action is a kind (carry on, corrective action, replacement) and, but for carrying on, a component;
its ``str`` is its meaning in ``env.unwrapped.action_meanings``. An event (a corrective step taken, a
replacement, a failure) is a small frozen dataclass whose ``str`` is the text in ``info["events"]``.
Infos and logs keep the text (plain strings: JSON, pickling and comparisons as before);
``parse_action`` and ``parse_event`` turn a text back into its value, the one place that reads it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from enum import Enum


class ActionKind(Enum):
    """What an action does; the value is its meaning's text before the component."""

    CARRY_ON = "carry on"
    CORRECTIVE = "corrective action on"
    REPLACE = "replace"


@dataclass(frozen=True)
class Action:
    """One entry of the action space: ``kind`` on ``component`` (None for carrying on)."""

    kind: ActionKind
    component: str | None = None

    def __post_init__(self) -> None:
        if (self.component is None) != (self.kind is ActionKind.CARRY_ON):
            raise ValueError(f"action {self.kind.value!r}: a component is needed exactly for corrective actions and replacements")

    def __str__(self) -> str:
        return self.kind.value if self.component is None else f"{self.kind.value} {self.component}"


def action_table(components: tuple[str, ...]) -> tuple[Action, ...]:
    """The action space's actions in index order: carry on, a corrective action on each component, the
    replacement of each component."""
    return (
        Action(ActionKind.CARRY_ON),
        *(Action(ActionKind.CORRECTIVE, c) for c in components),
        *(Action(ActionKind.REPLACE, c) for c in components),
    )


def parse_action(meaning: str) -> Action:
    """The action whose ``str`` is ``meaning``."""
    if meaning == ActionKind.CARRY_ON.value:
        return Action(ActionKind.CARRY_ON)
    for kind in (ActionKind.CORRECTIVE, ActionKind.REPLACE):
        prefix = kind.value + " "
        if meaning.startswith(prefix) and len(meaning) > len(prefix):
            return Action(kind, meaning[len(prefix) :])
    raise ValueError(f"not an action meaning: {meaning!r}")


@dataclass(frozen=True)
class CorrectiveStep:
    """A step of corrective action on ``component``."""

    component: str

    def __str__(self) -> str:
        return f"corrective action on {self.component}"


@dataclass(frozen=True)
class Replacement:
    """A new ``component``, the machine down for ``downtime`` steps."""

    component: str
    downtime: int

    def __str__(self) -> str:
        return f"replacement of {self.component} ({self.downtime} steps down)"


@dataclass(frozen=True)
class Failure:
    """``component``'s parameter at ``value`` left its safe ``limits`` (low, high)."""

    component: str
    value: float
    limits: tuple[float, float]

    def __str__(self) -> str:
        return f"failure: {self.component} = {self.value:.4g} outside {self.limits}"


Event = CorrectiveStep | Replacement | Failure

_REPLACEMENT = re.compile(r"replacement of (?P<component>\S+) \((?P<downtime>\d+) steps down\)")
_FAILURE = re.compile(r"failure: (?P<component>\S+) = (?P<value>\S+) outside \((?P<low>.+), (?P<high>.+)\)")
_NUMBER = re.compile(r"(?:np\.float64\()?(?P<number>[^()]+)\)?")


def parse_event(text: str) -> Event:
    """The event whose ``str`` is ``text`` (a failure's value and limits as printed: to 4 digits)."""
    if text.startswith("corrective action on ") and " " not in text[len("corrective action on ") :]:
        return CorrectiveStep(text[len("corrective action on ") :])
    if match := _REPLACEMENT.fullmatch(text):
        return Replacement(match["component"], int(match["downtime"]))
    if match := _FAILURE.fullmatch(text):
        low, high = (_number(match[key]) for key in ("low", "high"))
        return Failure(match["component"], float(match["value"]), (low, high))
    raise ValueError(f"not an event: {text!r}")


def _number(text: str) -> float:
    match = _NUMBER.fullmatch(text)
    if match is None:
        raise ValueError(f"not a number: {text!r}")
    return float(match["number"])
