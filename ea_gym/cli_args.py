"""What every ``ea-gym`` subcommand shares: argument types that refuse bad values, and the seam through
which packages add subcommands (the ``ea_gym.commands`` entry-point group)."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

__all__ = [
    "COMMAND_GROUP", "Subcommands", "env_option", "positive_int", "non_negative_int", "positive_float", "non_negative_float",
    "fraction_below_one", "system_option", "column_mapping", "columns_given", "column_names", "sample_rate_option",
    "seconds_within",
]

#: entry-point group of subcommands from other packages: each entry is ``add(commands: Subcommands) -> None``,
#: which adds its parser with ``commands.add_parser`` and sets ``run`` (``args -> exit code``) as its default
COMMAND_GROUP = "ea_gym.commands"


class Subcommands(Protocol):
    """``ArgumentParser.add_subparsers()``' result, as far as a subcommand needs it."""

    def add_parser(self, name: str, **kwargs: Any) -> argparse.ArgumentParser: ...


def positive_int(text: str) -> int:
    """An integer > 0 (argparse type)."""
    value = int(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text}")
    return value


def non_negative_int(text: str) -> int:
    """An integer >= 0 (argparse type)."""
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text}")
    return value


def positive_float(text: str) -> float:
    """A number of seconds > 0 (argparse type)."""
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text}")
    return value


def non_negative_float(text: str) -> float:
    """A finite number >= 0 (argparse type)."""
    value = float(text)
    if not 0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text}")
    return value


def fraction_below_one(expected: str) -> Callable[[str], float]:
    """An argparse type for a number in [0, 1); a refusal says ``expected ...`` with ``expected`` (what the value
    means, e.g. "a wear in [0, 1)") and the text given (NaN and words refused)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = -1.0
        if not 0 <= value < 1:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
        return value

    return parse


def env_option(text: str) -> tuple[str, Any]:
    """``KEY=VALUE``, an environment keyword and its value read as JSON (a bare word is text) (argparse type)."""
    key, sep, value = text.partition("=")
    if not sep or not key.isidentifier():
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE with KEY an environment keyword, got {text!r}")
    try:
        return key, json.loads(value)
    except json.JSONDecodeError:
        return key, value


def system_option(text: str) -> str:
    """``--system``'s value checked: a built-in's name as is, a model file's path made absolute (the
    environments of other processes and a resumed run find it); raises ParameterError naming the culprit."""
    from ea_gym.model_files import is_model_file, load_system

    load_system(text)
    return str(Path(text).resolve()) if is_model_file(text) else text


def column_mapping(text: str) -> tuple[str, str]:
    """``NAME=COLUMN``: the model's column NAME read from the file's column COLUMN (argparse type)."""
    name, sep, column = (part.strip() for part in text.partition("="))
    if not (sep and name and column):
        raise argparse.ArgumentTypeError(f"expected NAME=COLUMN (the model's column, the file's), got {text!r}")
    return name, column


def columns_given(pairs: list[tuple[str, str]]) -> dict[str, str]:
    """``--columns``' NAME=COLUMN pairs (:func:`column_mapping`, repeated) as a mapping; a NAME given twice is refused."""
    mapping: dict[str, str] = {}
    for name, column in pairs:
        if mapping.setdefault(name, column) != column:
            raise ValueError(f"--columns: {name!r} is mapped twice ({mapping[name]!r} and {column!r}); expected one COLUMN per NAME")
    return mapping


def seconds_within(option: str, seconds: float, least: float, most: float, what: str) -> None:
    """``option``'s ``seconds`` (s) in [least, most], ``most`` the duration of ``what`` (a record); else a one-line refusal."""
    if not least <= seconds <= most:
        raise ValueError(f"{option}: {seconds:g} s; expected at least {least:g} s and at most the duration of {what} ({most:g} s)")


def column_names(text: str) -> list[str]:
    """``A,B``: the file's columns, comma-separated (argparse type)."""
    names = [name.strip() for name in text.split(",")]
    if not all(names):
        raise argparse.ArgumentTypeError(f"expected column names separated by commas, got {text!r}")
    return names


def sample_rate_option(text: str) -> float:
    """A finite number of Hz > 0 (argparse type)."""
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a sample rate in Hz > 0, got {text!r}")
    return value
