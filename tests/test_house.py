"""The code's shape: sizes, layering and privacy, checked on the source itself.

- No function over 80 lines and no module over 600 lines in ``ea_gym/`` and ``agents/``, unless it
  carries a ``# long: <reason>`` line.
- ``ea_gym`` imports nothing from ``agents`` (the library never imports its client).
- No module uses another module's underscore names: no ``from m import _x``, no ``obj._x`` on
  anything but ``self`` or ``cls``.
- The package is built in floors, and no module imports from a floor above its own (imports inside
  functions and under ``if TYPE_CHECKING:`` count too; a module may import from its own floor):

  0. foundation: ``numerics``, ``threads``, ``interrupts``, ``files``, ``pyplot``, ``documents``, ``metrics``, ``_kernels``
  1. the model and what it produces: ``bondgraph``, ``models``, ``model_files``, ``energy``, ``sensors``,
     ``loads``, ``degradation``, ``scenario``, ``measurements``, ``plant``, ``cache``
  2. ``diagnosis`` (the EA monitor, features, the isolation network and its training)
  3. ``phm`` (the chain's stages and the chain)
  4. its users: ``env``, ``reporting``, ``plots``, ``reproduce``
  5. the front doors: ``cli``, ``cli_args`` and the package's ``__init__``

  Every top-level module or subpackage of ``ea_gym`` has a floor here: a new one must be placed.
- No cycle among the ``ea_gym.phm`` modules (the package's ``__init__`` included), type-checking-time
  imports counted: the settings and the estimator registry sit below the stages that use them.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
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


FLOORS: dict[str, int] = {
    **dict.fromkeys(("numerics", "threads", "interrupts", "files", "pyplot", "documents", "metrics", "_kernels"), 0),
    **dict.fromkeys(("bondgraph", "models", "model_files", "energy", "sensors", "loads", "degradation", "scenario", "measurements",
                     "plant", "cache"), 1),
    "diagnosis": 2,
    "phm": 3,
    **dict.fromkeys(("env", "reporting", "plots", "reproduce"), 4),
    **dict.fromkeys(("cli", "cli_args", "__init__"), 5),
}
LIBRARY = {".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__"): p for p in (ROOT / "ea_gym").rglob("*.py")}


def library_imports(module: str) -> Iterator[tuple[str, int]]:
    """The ``ea_gym`` modules that ``module`` imports anywhere in its source (a name imported from a package that is
    one of its modules counts as that module), with the line of each import."""
    path = LIBRARY[module]
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            yield from ((alias.name, node.lineno) for alias in node.names if alias.name.split(".")[0] == "ea_gym")
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            if base.split(".")[0] == "ea_gym":
                yield from ((f"{base}.{a.name}" if f"{base}.{a.name}" in LIBRARY else base, node.lineno) for a in node.names)


def floor_of(module: str) -> int:
    """The floor of an ``ea_gym`` module: that of its top-level module or subpackage (the package itself: the top)."""
    return FLOORS[module.split(".")[1] if "." in module else "__init__"]


def test_every_top_level_module_has_a_floor() -> None:
    tops = {module.split(".")[1] for module in LIBRARY if "." in module}
    assert tops <= set(FLOORS), f"place {sorted(tops - set(FLOORS))} on a floor (FLOORS, and this module's docstring)"


@pytest.mark.parametrize("module", sorted(LIBRARY))
def test_no_import_from_a_floor_above(module: str) -> None:
    upward = [f"{imported} (floor {floor_of(imported)}, line {line})" for imported, line in library_imports(module)
              if floor_of(imported) > floor_of(module)]
    assert not upward, f"{module} (floor {floor_of(module)}) imports from above: {upward}"


def test_the_phm_modules_import_one_another_without_a_cycle() -> None:
    phm = sorted(m for m in LIBRARY if m == "ea_gym.phm" or m.startswith("ea_gym.phm."))
    graph = {m: sorted({imported for imported, _ in library_imports(m) if imported in phm and imported != m}) for m in phm}
    done: set[str] = set()

    def cycle_from(module: str, path: list[str]) -> list[str] | None:
        """A cycle through the modules on ``path`` reached from ``module``, depth first; None if there is none."""
        if module in path:
            return path[path.index(module):] + [module]
        if module in done:
            return None
        for imported in graph[module]:
            found = cycle_from(imported, path + [module])
            if found:
                return found
        done.add(module)
        return None

    cycles = [c for c in (cycle_from(m, []) for m in phm) if c]
    assert not cycles, f"import cycle: {' -> '.join(cycles[0])}"
