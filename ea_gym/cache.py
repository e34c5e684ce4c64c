"""The on-disk cache of what is slow to compute and depends only on its inputs: isolation networks, detection thresholds.

Entries live in the user's cache directory (``platformdirs.user_cache_dir("ea-gym")``, e.g.
``~/.cache/ea-gym`` on Linux), or in the directory named by the environment variable
``EA_GYM_CACHE_DIR``. Each entry is named by a SHA-256 of a canonical JSON of everything it depends
on (:func:`cache_key`): the model's definition, the settings that matter, the seed, the entry kind's
format version and the package's version. Files are written atomically and read without unpickling;
an entry that cannot be read, or whose recorded key is not its name's, is reported with a warning and
treated as missing, so that it is rebuilt.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import json
import math
import os
import warnings
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ea_gym.files import write_atomic, write_json

if TYPE_CHECKING:
    from ea_gym.models import SystemModel

__all__ = [
    "CACHE_DIR_VARIABLE",
    "PACKAGE_VERSION",
    "cache_dir",
    "cache_key",
    "canonical",
    "entry_path",
    "model_definition",
    "read_arrays_entry",
    "read_json_entry",
    "warn_rebuilt",
    "write_arrays_entry",
    "write_json_entry",
]

#: the environment variable that moves the cache
CACHE_DIR_VARIABLE = "EA_GYM_CACHE_DIR"
#: part of every key: a new release computes its own entries
PACKAGE_VERSION = "0.1.0"
#: SystemModel fields that change no computation (labels for people)
_LABELS = ("name", "description", "units")


def cache_dir() -> Path:
    """The cache directory: ``$EA_GYM_CACHE_DIR`` if set and not empty, else the user's cache directory for ea-gym."""
    override = os.environ.get(CACHE_DIR_VARIABLE)
    if override:
        return Path(override).expanduser()
    import platformdirs

    return Path(platformdirs.user_cache_dir("ea-gym"))


def canonical(value: Any) -> Any:
    """``value`` as plain JSON data, the same for equal inputs: dataclasses as dicts of their fields, mappings with
    sorted string keys, sequences and arrays as lists, enums as their values; floats kept exactly (JSON writes repr)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: canonical(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, enum.Enum):
        return canonical(value.value)
    if isinstance(value, Mapping):
        return {str(k): canonical(value[k]) for k in sorted(value, key=str)}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [canonical(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    if value is None or isinstance(value, str):
        return value
    raise TypeError(f"cannot put a {type(value).__name__} in a cache key")


def model_definition(model: SystemModel) -> dict[str, Any]:
    """What a model computes with, as canonical JSON data: its bond graph (elements in their order, their kinds and C
    forms, the bonds in order) and every field of the model but its labels (name, description, units). The elements'
    order is kept (canonical sorts mapping keys): it sets the order of the parameters, states and features, so two
    files listing the same elements in another order train different networks and calibrate thresholds in another order."""
    graph = model.graph
    definition: dict[str, Any] = {
        "elements": [[name, canonical(element)] for name, element in graph.elements.items()],
        "bonds": [[bond.tail, bond.head] for bond in graph.bonds],
    }
    for field in dataclasses.fields(model):
        # an optional field left None (a load without its own scale) is left out: the keys of the models without it stay
        if field.name not in (*_LABELS, "graph") and getattr(model, field.name) is not None:
            definition[field.name] = canonical(getattr(model, field.name))
    return definition


def cache_key(kind: str, format_version: int, **parts: Any) -> str:
    """SHA-256 (hex) of the canonical JSON of ``parts`` with the entry's kind, its format version and the package's version."""
    document = canonical({"kind": kind, "format": format_version, "package": PACKAGE_VERSION, **parts})
    text = json.dumps(document, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def entry_path(kind: str, key: str, suffix: str) -> Path:
    """Where the entry of ``kind`` with ``key`` lives: ``cache_dir()/kind/key.suffix``."""
    return cache_dir() / kind / f"{key}{suffix}"


def warn_rebuilt(path: Path, why: str) -> None:
    """Say that the entry at ``path`` is ignored (and will be rebuilt), and why."""
    warnings.warn(f"ignoring the cache entry {path} ({why}); rebuilding it", RuntimeWarning, stacklevel=3)


def read_json_entry(kind: str, key: str) -> dict[str, Any] | None:
    """The JSON entry of ``kind`` with ``key``, or None if there is none or it is unreadable or not this key's (warned)."""
    path = entry_path(kind, key, ".json")
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        warn_rebuilt(path, f"unreadable: {error}")
        return None
    if not isinstance(data, dict) or data.get("key") != key:
        warn_rebuilt(path, "its recorded key is not its name's")
        return None
    return data


def write_json_entry(kind: str, key: str, data: Mapping[str, Any]) -> Path:
    """Write the JSON entry of ``kind`` with ``key`` atomically; the key is recorded inside it too."""
    return write_json(entry_path(kind, key, ".json"), {"key": key, **data})


def read_arrays_entry(kind: str, key: str) -> dict[str, np.ndarray] | None:
    """The arrays entry (``.npz``, read with ``allow_pickle=False``) of ``kind`` with ``key``, or None if there is none
    or it is unreadable or not this key's (warned)."""
    path = entry_path(kind, key, ".npz")
    if not path.is_file():
        return None
    try:
        _check_members(path)
        with np.load(path, allow_pickle=False) as archive:
            arrays = {name: archive[name] for name in archive.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as error:
        warn_rebuilt(path, f"unreadable: {error}")
        return None
    if str(arrays.pop("key", "")) != key:
        warn_rebuilt(path, "its recorded key is not its name's")
        return None
    return arrays


#: most bytes an arrays entry's members may declare, together (the thresholds and networks cached are kilobytes)
MAX_ENTRY_BYTES = 1 << 28


def _check_members(path: Path) -> None:
    """Every member's shape and dtype read from its header, before any array is allocated: each member's data as large
    as its header declares (a header declaring shape (1e11,) would allocate 800 GB) and all of them within MAX_ENTRY_BYTES.

    Raises:
        ValueError: naming the member.
    """
    total = 0
    with zipfile.ZipFile(path) as archive:
        for info in archive.infolist():
            with archive.open(info) as member:
                version = np.lib.format.read_magic(member)
                read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
                shape, _, dtype = read_header(member, max_header_size=10_000)
                declared = math.prod(shape) * dtype.itemsize
                if dtype.hasobject or declared != info.file_size - member.tell():
                    raise ValueError(f"member {info.filename} declares {shape} {dtype}, {declared} bytes; it holds {info.file_size - member.tell()}")
            total += declared
            if total > MAX_ENTRY_BYTES:
                raise ValueError(f"its members declare more than {MAX_ENTRY_BYTES} bytes")


def write_arrays_entry(kind: str, key: str, arrays: Mapping[str, np.ndarray]) -> Path:
    """Write the arrays entry of ``kind`` with ``key`` atomically; the key is recorded inside it too."""

    payload: dict[str, Any] = {"key": np.array(key), **arrays}

    def write(tmp: str) -> None:
        with open(tmp, "wb") as file:
            np.savez(file, **payload)

    return write_atomic(entry_path(kind, key, ".npz"), write)
