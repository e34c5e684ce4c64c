"""The code's shape: sizes, layering and privacy, checked on the source itself.

- No function over 80 lines and no module over 600 lines in ``ea_gym/`` and ``agents/``, unless it
  carries a ``# long: <reason>`` line.
- ``ea_gym`` imports nothing from ``agents`` (the library never imports its client).
- No module uses another module's underscore names: no ``from m import _x``, no ``obj._x`` on
  anything but ``self`` or ``cls``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("ea_gym", "agents")
MAX_FUNCTION_LINES = 80
MAX_MODULE_LINES = 600


def _sources() -> list[Path]:
    return sorted(p for package in PACKAGES for p in (ROOT / package).rglob("*.py"))


def _long_ok(lines: list[str], start: int, end: int) -> bool:
    return any(line.strip().startswith("# long:") for line in lines[start - 1 : end])


@pytest.mark.parametrize("path", _sources(), ids=lambda p: str(p.relative_to(ROOT)))
def test_sizes(path: Path) -> None:
    text = path.read_text()
    lines = text.splitlines()
    assert len(lines) <= MAX_MODULE_LINES or _long_ok(lines, 1, len(lines)), f"{path.name}: {len(lines)} lines"
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            span = node.end_lineno - node.lineno + 1
            assert span <= MAX_FUNCTION_LINES or _long_ok(lines, node.lineno, node.end_lineno), f"{path.name}: {node.name} is {span} lines"


def _imported_modules(tree: ast.AST) -> list[str]:
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.append(node.module)
    return names


@pytest.mark.parametrize("path", sorted((ROOT / "ea_gym").rglob("*.py")), ids=lambda p: str(p.relative_to(ROOT)))
def test_library_does_not_import_agents(path: Path) -> None:
    imported = _imported_modules(ast.parse(path.read_text()))
    assert not [m for m in imported if m == "agents" or m.startswith("agents.")]


def _private_uses(tree: ast.AST) -> list[str]:
    uses = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            uses += [f"from {node.module} import {a.name}" for a in node.names if a.name.startswith("_") and not a.name.startswith("__")]
        elif isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__"):
            owner = node.value
            if not (isinstance(owner, ast.Name) and owner.id in ("self", "cls")):
                uses.append(f"{ast.unparse(node)} (line {node.lineno})")
    return uses


# numpy's ctypes interface and a few library attributes are public API despite the underscore
_FOREIGN_PUBLIC = {"_fields", "_asdict", "_replace", "_getvalue", "_value_", "_name_"}


@pytest.mark.parametrize("path", _sources(), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_other_modules_private_names(path: Path) -> None:
    uses = [u for u in _private_uses(ast.parse(path.read_text())) if u.split(" ")[0].rsplit(".", 1)[-1] not in _FOREIGN_PUBLIC]
    assert not uses, f"{path.name} uses private names: {uses}"
