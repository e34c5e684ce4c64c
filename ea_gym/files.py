"""Results files that appear whole or not at all: written to a temporary sibling, then renamed; a command's
output directory staged beside it and moved into place together."""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any, SupportsFloat

import numpy as np

from ea_gym.interrupts import interruptions_held


def write_atomic(path: str | os.PathLike[str], write: Callable[[str], object]) -> Path:
    """Call ``write(temporary_path)`` and move the result onto ``path`` in one rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = None
    try:
        with interruptions_held():  # the temporary file known to the cleanup below before an interruption raises
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
            os.close(fd)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; results are for everyone to read
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _umask() -> int:
    """The process's umask (reading it means setting it: set back at once)."""
    umask = os.umask(0)
    os.umask(umask)
    return umask


class OutputError(ValueError):
    """An output directory that cannot be written; the message names it and says why."""


def check_output_directory(out: str | os.PathLike[str]) -> None:
    """Refuse, before any work, an output directory that cannot be written: an existing file, a path under a file, or
    a directory whose nearest existing ancestor is not writable; raises OutputError naming it."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"{out} is an existing file; expected a directory (existing or to create)")
    # "." and "/" have no parents (and exist)
    existing = next((path for path in out.parents if path.exists() or path == Path(path.anchor)), out)
    if not existing.is_dir():
        raise OutputError(f"cannot write {out}: {existing} is a file, not a directory")
    for directory in (existing, out) if out.exists() else (existing,):  # the staging directory goes beside out
        if not os.access(directory, os.W_OK | os.X_OK):
            raise OutputError(f"cannot write {out}: {directory} is not writable")


def refuse_links(directory: str | os.PathLike[str], purpose: str) -> None:
    """Refuse a directory holding a symbolic link at any depth (ValueError naming the first found): a run that reads
    or rewrites the directory's files ``purpose`` must find them inside it, not write through a link or drop what it
    points to."""
    for root, directories, files in os.walk(directory):
        for name in sorted(directories + files):
            if os.path.islink(os.path.join(root, name)):
                raise ValueError(f"{os.path.join(root, name)} is a symbolic link; expected {directory} to hold its own files "
                                  f"{purpose}, no links")


def _missing_parents(directory: Path) -> list[Path]:
    """The ancestors of ``directory`` (itself included) that do not exist yet, outermost first."""
    missing = []
    for path in (directory, *directory.parents):
        if path.exists():
            break
        missing.append(path)
    return missing[::-1]


@contextlib.contextmanager
def staged_output(out: str | os.PathLike[str], last: str | None = None, carry_existing: bool = False) -> Iterator[Path]:
    """A temporary directory beside ``out`` for a command to write its outputs in; when the block succeeds they move
    into ``out`` together (a rename of the whole directory when ``out`` does not exist yet), when it fails nothing
    is left: neither the staging directory nor the parent directories it created.

    ``last``: a file (e.g. ``results.json``) removed from an existing ``out`` first and moved in last, so that
    its presence means the directory is complete.

    ``carry_existing``: the staging directory starts as a copy of an existing ``out``, for a run that adds to it
    (a resumed training's new checkpoints beside the earlier ones); on success the result replaces ``out``, on
    failure ``out`` is left as it was.

    Raises:
        OutputError: ``out`` is an existing file, lies under a file, or its parent cannot be written.
        ValueError: with ``carry_existing``, ``out`` holds a symbolic link (``refuse_links``).
    """
    out = Path(out)
    check_output_directory(out)
    if carry_existing and out.is_dir():
        refuse_links(out, "to continue it")
    beside = Path(os.path.abspath(out))  # "." and "a/.." name a directory, not a parent to write beside it in
    created = _missing_parents(beside.parent)
    staging = None
    try:
        with interruptions_held():  # the staging directory known to the cleanup below before an interruption raises
            staging = _staging_beside(beside, out)
        if carry_existing and out.is_dir():
            shutil.copytree(out, staging, symlinks=True, dirs_exist_ok=True)
        yield staging
        with interruptions_held():  # the outputs move in together, or (an error) not at all
            _move_in(staging, out, last)
    except BaseException:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)
        _remove_created(created)
        raise


def _staging_beside(beside: Path, out: Path) -> Path:
    """A new, empty staging directory beside ``beside`` (the absolute ``out``); OutputError when it cannot be made."""
    try:
        beside.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{beside.name}.", dir=beside.parent))
        staging.chmod(0o777 & ~_umask())  # mkdtemp creates 0700; a new out is renamed from it, for everyone to read
    except OSError as error:
        raise OutputError(f"cannot write {out}: {error.strerror or error}") from None
    return staging


def _move_in(staging: Path, out: Path, last: str | None) -> None:
    if not out.exists():
        os.replace(staging, out)
        return
    if last is not None:
        (out / last).unlink(missing_ok=True)
    entries = sorted(staging.iterdir(), key=lambda path: path.name == last)
    for path in entries:
        target = out / path.name
        if target.is_symlink():  # the output replaces the link; what it points to is not written
            target.unlink()
        elif target.is_dir() and path.is_dir():
            shutil.rmtree(target)
        os.replace(path, target)
    staging.rmdir()


def _remove_created(created: list[Path]) -> None:
    for path in reversed(created):
        with contextlib.suppress(OSError):
            path.rmdir()


def write_json(path: str | os.PathLike[str], data: Any) -> Path:
    """Write ``data`` as indented JSON, atomically; NaN and inf are refused (they are not JSON)."""
    text = json.dumps(data, indent=2, allow_nan=False)
    return write_atomic(path, lambda tmp: Path(tmp).write_text(text + "\n"))


def write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write a text file atomically."""
    return write_atomic(path, lambda tmp: Path(tmp).write_text(text))


def save_figure(figure: Any, path: str | os.PathLike[str], dpi: int = 110) -> Path:
    """Save a matplotlib figure as PNG atomically and close it."""
    from ea_gym.pyplot import plt

    try:
        return write_atomic(path, lambda tmp: figure.savefig(tmp, dpi=dpi, format="png"))
    finally:
        plt.close(figure)


def finite_or_none(value: SupportsFloat) -> float | None:
    """``value`` as a float, or None (JSON null) where it is NaN or infinite."""
    number = float(value)
    return number if math.isfinite(number) else None


def json_ready(value: Any) -> Any:
    """Plain Python containers and numbers, recursively: mappings as dicts with string keys, sequences and
    arrays as lists, numpy scalars as Python numbers, NaN and inf as None."""
    if isinstance(value, Mapping):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [json_ready(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return finite_or_none(value)
    return value
