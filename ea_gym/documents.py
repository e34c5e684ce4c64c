"""Bounded reading of JSON and YAML documents into plain data.

Only regular files are read (a FIFO or a device would block or never end), at most ``MAX_BYTES`` of
them; the data may nest at most ``MAX_DEPTH`` levels and hold at most ``MAX_VALUES`` values (YAML
aliases count every time they are used); a mapping with the same key twice is refused rather than
silently keeping the last. YAML goes through ``yaml.safe_load``'s loader: no object is ever constructed
from a tag.
"""

from __future__ import annotations

import json
import os
import re
import stat
from pathlib import Path
from typing import Any

import yaml

__all__ = [
    "MAX_BYTES", "MAX_DEPTH", "MAX_VALUES", "DocumentError", "FileTooLargeError", "NotRegularFileError", "is_yaml", "read_document",
    "read_regular_file",
]

MAX_BYTES = 1 << 20
MAX_DEPTH = 32
MAX_VALUES = 100_000


class DocumentError(ValueError):
    """A file that cannot be read as a JSON or YAML document within the limits; the message says why."""


class NotRegularFileError(ValueError):
    """A path that is not a regular file (a FIFO or a device, whose reading would block or never end)."""


class FileTooLargeError(ValueError):
    """A file of more bytes than its reader takes; ``size``: its size as stat saw it, None when it grew while read."""

    def __init__(self, size: int | None) -> None:
        super().__init__(f"{size} bytes" if size is not None else "it grew while read")
        self.size = size


def read_regular_file(path: Path, max_bytes: int) -> bytes:
    """The bytes of ``path``, a regular file of at most ``max_bytes``: its size checked before reading and the
    read itself bounded (the file may grow in between). The callers word the errors for their files.

    Raises:
        OSError: the file cannot be read. NotRegularFileError, FileTooLargeError.
    """
    info = path.stat()
    if not stat.S_ISREG(info.st_mode):
        raise NotRegularFileError(str(path))
    if info.st_size > max_bytes:
        raise FileTooLargeError(info.st_size)
    with path.open("rb") as stream:
        raw = stream.read(max_bytes + 1)
    if len(raw) > max_bytes:
        raise FileTooLargeError(None)
    return raw


def is_yaml(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` names a YAML file (.yaml or .yml); anything else is read as JSON."""
    return Path(path).suffix.lower() in (".yaml", ".yml")


class _UniqueKeyLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses a mapping with a repeated key."""


def _construct_unique_mapping(loader: _UniqueKeyLoader, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
    seen: set[Any] = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        if not isinstance(key, (str, int, float)):
            continue  # an unhashable key: construct_mapping reports it
        if key in seen:
            raise DocumentError(f"the key {key!r} appears twice in one mapping (line {key_node.start_mark.line + 1})")
        seen.add(key)
    return loader.construct_mapping(node, deep=deep)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_unique_mapping)
# YAML 1.1 reads a float only with a dot: 5e-1 and 1E3 would be strings where every reader means numbers (as JSON does)
_UniqueKeyLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?[0-9][0-9_]*[eE][-+]?[0-9]+$"), list("-+0123456789")
)
#: Python's limit on the digits of an integer read from text (sys.get_int_max_str_digits)
MAX_DIGITS = 4300


def _unique_pairs(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    result: dict[str, Any] = {}
    for key, value in pairs:
        if key in result:
            raise DocumentError(f"the key {key!r} appears twice in one object")
        result[key] = value
    return result


def _check_shape(data: Any) -> None:
    """Refuse data nested deeper than MAX_DEPTH or holding more than MAX_VALUES values (walked without recursion)."""
    stack = [(data, 1)]
    count = 0
    while stack:
        value, depth = stack.pop()
        count += 1
        if count > MAX_VALUES:
            raise DocumentError(f"the document holds more than {MAX_VALUES} values")
        if isinstance(value, (dict, list)):
            if depth > MAX_DEPTH:
                raise DocumentError(f"the document nests deeper than {MAX_DEPTH} levels")
            children = value.values() if isinstance(value, dict) else value
            stack.extend((child, depth + 1) for child in children)


def _long_number(text: str) -> str:
    """Where ``text`` writes an integer of more than MAX_DIGITS digits: its line and its field."""
    match = re.search(rf"([\"']?([A-Za-z_][\w.-]*)[\"']?\s*:\s*)?[-+]?[0-9]{{{MAX_DIGITS + 1},}}", text)
    if match is None:
        return f"a number has more than {MAX_DIGITS} digits; expected a number of at most {MAX_DIGITS} digits"
    line = text.count("\n", 0, match.start()) + 1
    field = f", field {match[2]!r}" if match[2] else ""
    digits = len(match[0]) - len(match[1] or "")
    return f"line {line}{field}: a number of {digits} digits; expected a number of at most {MAX_DIGITS} digits"


def read_document(path: str | os.PathLike[str]) -> Any:
    """The plain data (dicts, lists, strings, numbers, booleans, None) of a JSON or YAML file.

    Raises:
        DocumentError: not a regular file, unreadable, larger than MAX_BYTES, not valid JSON/YAML
            (the parser's message), a repeated key, or deeper or larger than the limits.
    """
    path = Path(path)
    try:
        raw = read_regular_file(path, MAX_BYTES)
    except OSError as exc:
        raise DocumentError(f"cannot read the file: {exc.strerror or exc}") from None
    except NotRegularFileError:
        raise DocumentError("not a regular file") from None
    except FileTooLargeError as exc:
        read = f"more than {MAX_BYTES} bytes" if exc.size is None else f"{exc.size} bytes; at most {MAX_BYTES} are read"
        raise DocumentError(f"the file has {read}") from None
    syntax = "YAML" if is_yaml(path) else "JSON"
    try:
        text = raw.decode("utf-8")
        data = yaml.load(text, Loader=_UniqueKeyLoader) if syntax == "YAML" else json.loads(text, object_pairs_hook=_unique_pairs)
    except UnicodeDecodeError:
        raise DocumentError("the file is not UTF-8 text") from None
    except RecursionError:
        raise DocumentError(f"the document nests deeper than {MAX_DEPTH} levels") from None
    except (json.JSONDecodeError, yaml.YAMLError) as exc:
        reason = " ".join(str(exc).split())
        raise DocumentError(f"the file is not valid {syntax}: {reason}") from None
    except DocumentError:
        raise
    except ValueError:  # an integer past Python's limit on digits read from text
        raise DocumentError(_long_number(text)) from None
    _check_shape(data)
    return data
