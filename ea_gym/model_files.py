"""Model files: a system's bond graph, component values, safe limits and load written in YAML or JSON.

A model file (the README's "Model files" section has a whole one)::

    name: two_mass_chain                  # required; a letter or _, then letters, digits, _
    description: two masses in a chain    # optional
    elements:                             # required: name -> element
      F:  {kind: Se, unit: N}             # sources Se, Sf; a source other than the load source needs `value`
      v1: {kind: "1"}                     # junctions "0", "1"
      m1: {kind: I, value: 10.0, unit: kg, limits: [9.0, 11.0]}
      k1: {kind: C, form: stiffness, value: 100.0, unit: N/m, limits: [85.0, 105.0]}
      b1: {kind: R, value: 0.5, unit: N s/m}
    bonds: [[F, v1], [v1, m1], [v1, k1], [v1, b1]]   # [tail, head]: positive power from tail to head
    load: {source: F, nominal: 10.0, bandwidth: 2.0}

R, C, I, TF and GY carry ``value`` (> 0, SI) and an optional ``unit``; a C element states its ``form``
(required, no default): ``stiffness`` (effort = value x q, value in N/m) or ``compliance`` (effort =
q / value, value in m/N or F); TF and GY follow :class:`ea_gym.bondgraph.Element`'s laws, their incoming
bond first. ``limits: [lower, upper]`` (around the value) make a parameter degradable and maintainable.

``load`` names the source a scenario's load drives (an effort source Se, e.g. a force, or a flow source
Sf, e.g. a road's vertical velocity), its ``nominal`` value (the operating level in the source's unit;
any finite number, 0 for a zero-mean load), the ``bandwidth`` (Hz) of the random loads that excite the
dynamics and their ``scale`` (the source's unit; optional where the nominal is not 0, which it then
defaults to; required where it is 0): random loads vary by 20 to 40 % of the scale around the nominal::

    load: {source: zr, nominal: 0.0, scale: 0.1, bandwidth: 5.0}   # a zero-mean road velocity (m/s)

:func:`load_model_file` checks all of it and builds a :class:`~ea_gym.models.SystemModel`; a
:class:`ModelFileError` names, on one line, every element, bond or field that is wrong and what was
expected. :func:`load_system` takes a built-in name or a model file's path wherever a system is named.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeGuard

from ea_gym.bondgraph.elements import CForm, Kind
from ea_gym.bondgraph.graph import BondGraph, BondGraphError
from ea_gym.documents import DocumentError, read_document
from ea_gym.models import MODELS, ParameterError, SystemModel, get_model

__all__ = [
    "MAX_BONDS", "MAX_ELEMENTS", "MAX_STATES", "MODEL_FILE_SUFFIXES", "ModelFileError", "is_model_file", "load_model_file", "load_system",
    "model_from_data", "printable",
]

MODEL_FILE_SUFFIXES = (".yaml", ".yml", ".json")
NAME_PATTERN = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,63}")
#: an element's value and limits (SI): the product or quotient of any ten stays a normal float (m = k = 1e308 gave a state
#: matrix whose eigenvalues came out 0, the model "resolved" at any rate); physical parts lie well inside (1 pF, 1e12 N/m)
VALUE_RANGE = (1e-30, 1e30)
#: what one model file may ask for, checked on the raw document before any element is built: a graph's structure and
#: causality checks grow with elements x bonds, its eigenvalues with states cubed (14,000 C elements ran past 120 s)
MAX_ELEMENTS = 500
MAX_BONDS = 1000
MAX_STATES = 100
#: problems an error message lists before it counts the rest (15,000 of them made a 1.6 GB line)
LISTED_PROBLEMS = 8
#: names taken by the measurement files' own columns
RESERVED_NAMES = ("t",)
_FIELDS = ("name", "description", "elements", "bonds", "load")
_C_FORMS = {"stiffness": CForm.STIFFNESS, "compliance": CForm.CAPACITANCE}
_KINDS = tuple(kind.value for kind in Kind)


class ModelFileError(ParameterError):
    """An invalid model file; the one-line message names the file and every culprit with what was expected."""


def is_model_file(system: str | os.PathLike[str]) -> bool:
    """Whether ``system`` names a model file (by its suffix) rather than a built-in system."""
    return Path(system).suffix.lower() in MODEL_FILE_SUFFIXES


def load_system(system: str | os.PathLike[str] | SystemModel, base: str | os.PathLike[str] | None = None) -> SystemModel:
    """The system a user names: a SystemModel as is, a built-in's name, or a model file's path.

    Args:
        base: the directory a relative model-file path is relative to (default: the working directory).

    Raises:
        ParameterError: an unknown name (the message lists the built-ins), or a ModelFileError.
    """
    if isinstance(system, SystemModel):
        return system
    if not isinstance(system, (str, os.PathLike)):
        raise ParameterError(f"system: expected a built-in name or a model file's path, got {type(system).__name__}")
    if isinstance(system, str) and system in MODELS:
        return get_model(system)
    if not is_model_file(system):
        raise ParameterError(
            f"unknown system {os.fspath(system)!r}; valid systems are {sorted(MODELS)} "
            f"or a model file ({', '.join(MODEL_FILE_SUFFIXES)})"
        )
    path = Path(system)
    return load_model_file(path if base is None or path.is_absolute() else Path(base) / path)


def load_model_file(path: str | os.PathLike[str]) -> SystemModel:
    """Read, check and build the model file at ``path`` (YAML for .yaml/.yml, else JSON); raises ModelFileError."""
    source = os.fspath(path)
    try:
        data = read_document(source)
    except DocumentError as exc:
        raise ModelFileError(f"model file {source}: {exc}") from None
    return model_from_data(data, source)


def model_from_data(data: Any, source: str = "dict") -> SystemModel:
    """Check the plain data of a model file and build its SystemModel; raises ModelFileError naming ``source``."""
    problems = _Problems()
    model = _build(data, problems) if _within_bounds(data, problems) else None
    if problems or model is None:
        raise ModelFileError(f"model file {source}: {problems.summary()}")
    return model


def _within_bounds(data: Any, problems: _Problems) -> bool:
    """The counts of elements, bonds and states (I and C elements) at most MAX_ELEMENTS, MAX_BONDS and MAX_STATES."""
    if not isinstance(data, dict):
        return True  # _build says what the top level must be
    elements, bonds = data.get("elements"), data.get("bonds")
    if isinstance(elements, dict) and len(elements) > MAX_ELEMENTS:
        problems.add("elements", f"{len(elements)} elements; a model file holds at most {MAX_ELEMENTS}")
    if isinstance(bonds, list) and len(bonds) > MAX_BONDS:
        problems.add("bonds", f"{len(bonds)} bonds; a model file holds at most {MAX_BONDS}")
    if isinstance(elements, dict) and not problems:
        states = sum(isinstance(spec, dict) and spec.get("kind") in ("I", "C") for spec in elements.values())
        if states > MAX_STATES:
            problems.add("elements", f"{states} storage elements (I, C), each a state; a model holds at most {MAX_STATES} states")
    return not problems


class _Problems(list[str]):
    """The problems found so far, one ``<where>: <what was expected>`` each."""

    def add(self, where: str, expected: str) -> None:
        self.append(f"{where}: {expected}")

    def summary(self) -> str:
        """The first LISTED_PROBLEMS problems, then how many in all."""
        shown = "; ".join(_cut(problem, 300) for problem in self[:LISTED_PROBLEMS])
        return shown + (f"; ... ({len(self)} problems in all)" if len(self) > LISTED_PROBLEMS else "")


def _cut(text: str, length: int) -> str:
    """``text`` cut to ``length`` characters (a value quoted whole can be as long as the file)."""
    return text if len(text) <= length else text[: length - 3] + "..."


def _listed(names: list[str]) -> str:
    """Names for a message: the first LISTED_PROBLEMS, then how many in all."""
    shown = ", ".join(map(str, names[:LISTED_PROBLEMS]))
    return shown + (f", ... ({len(names)} in all)" if len(names) > LISTED_PROBLEMS else "")


def printable(text: str) -> str:
    """``text`` with its control characters (a terminal's escape sequences) written as escapes, for printing."""
    return "".join(c if c.isprintable() or c == " " else c.encode("unicode_escape").decode("ascii") for c in text)


def _number(value: Any) -> TypeGuard[float]:
    """A finite int or float (not a bool; an int beyond the float range is not finite either)."""
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def _describe(value: Any) -> str:
    """A value as a message shows it: a scalar's repr (cut at 40 characters), else its type."""
    if isinstance(value, (str, int, float, bool)) or value is None:
        text = repr(value)
        return text if len(text) <= 40 else text[:37] + "..."
    return f"a {type(value).__name__}"


def _name(value: Any, where: str, problems: _Problems) -> bool:
    if isinstance(value, str) and value in RESERVED_NAMES:
        problems.add(where, f"the name {value!r} is reserved (the time column of measurement files); choose another")
        return False
    if isinstance(value, str) and NAME_PATTERN.fullmatch(value):
        return True
    problems.add(where, f"expected a name of letters, digits and _ that starts with a letter or _ (at most 64), got {_describe(value)}")
    return False


def _build(data: Any, problems: _Problems) -> SystemModel | None:
    if not isinstance(data, dict):
        problems.add("top level", f"expected a mapping with the fields {', '.join(_FIELDS)}, got {_describe(data)}")
        return None
    name, description = _header(data, problems)
    elements = _elements(data.get("elements"), problems) if "elements" in data else {}
    declared = list(data["elements"]) if isinstance(data.get("elements"), dict) else []
    bonds = _bonds(data.get("bonds"), declared, problems) if "bonds" in data else []
    load = _load(data.get("load"), elements, problems) if "load" in data else None
    if elements:
        _ports(elements, bonds, problems)
        _source_values(elements, _load_source(data.get("load"), elements), problems)
    if not problems:
        _connected(elements, bonds, problems)
    if problems or load is None:
        return None
    graph = BondGraph()
    for element, spec in elements.items():
        graph.add(element, spec.kind, c_form=spec.form)
    for tail, head in bonds:
        graph.connect(tail, head)
    values = {e: spec.value for e, spec in elements.items() if spec.value is not None}
    try:
        return SystemModel(
            name=name,
            graph=graph,
            nominal={e: v for e, v in values.items() if elements[e].kind.has_parameter},
            safe_limits={e: spec.limits for e, spec in elements.items() if spec.limits is not None},
            units={e: spec.unit for e, spec in elements.items() if spec.unit is not None},
            load_source=load.source,
            nominal_load=load.nominal,
            load_scale=load.scale,
            excitation_bandwidth=load.bandwidth,
            description=description,
            source_values={e: v for e, v in values.items() if elements[e].kind.is_source},
        )
    except BondGraphError as exc:  # the structure's checks and the causality (derivative causality named)
        problems.add("bonds", str(exc))
    except ParameterError as exc:
        problems.append(str(exc))
    return None


def _header(data: dict[str, Any], problems: _Problems) -> tuple[str, str]:
    """The unknown and missing top-level fields; the name and description."""
    for key in data:
        if key not in _FIELDS:
            problems.add(str(key), f"unknown field; expected {', '.join(_FIELDS)}")
    for key in ("name", "elements", "bonds", "load"):
        if key not in data:
            problems.add(key, "missing (required)")
    name = data.get("name")
    if name is not None and _name(name, "name", problems) and name in MODELS:
        problems.add("name", f"{name!r} is a built-in system's name; choose another (built-ins: {sorted(MODELS)})")
    description = data.get("description", "")
    if not isinstance(description, str):
        problems.add("description", f"expected text, got {_describe(description)}")
    return str(name), str(description)


@dataclass
class _Element:
    """An element's checked fields (value in SI; limits only where given)."""

    kind: Kind
    value: float | None = None
    unit: str | None = None
    form: CForm = CForm.CAPACITANCE  # read only for a C element, which states it
    limits: tuple[float, float] | None = None


def _elements(raw: Any, problems: _Problems) -> dict[str, _Element]:
    """name -> checked fields of the valid elements."""
    if not isinstance(raw, dict) or not raw:
        problems.add("elements", f"expected a non-empty mapping of element name -> element, got {_describe(raw)}")
        return {}
    elements = {}
    for name, spec in raw.items():
        where = f"elements.{name}"
        if not _name(name, where, problems):
            continue
        if not isinstance(spec, dict):
            problems.add(where, f"expected a mapping with kind (one of {', '.join(_KINDS)}), got {_describe(spec)}")
            continue
        checked = _element(where, spec, problems)
        if checked is not None:
            elements[name] = checked
    return elements


def _element(where: str, spec: dict[str, Any], problems: _Problems) -> _Element | None:
    kind_text = spec.get("kind")
    if isinstance(kind_text, int) and not isinstance(kind_text, bool) and kind_text in (0, 1):
        kind_text = str(kind_text)  # YAML reads an unquoted 0 or 1 as a number
    if kind_text not in _KINDS:
        got = _describe(kind_text) if "kind" in spec else "nothing"
        problems.add(f"{where}.kind", f"expected one of {', '.join(_KINDS)}, got {got}")
        return None
    kind = Kind(kind_text)
    allowed = {"kind"} | ({"value", "unit"} if kind.is_source else set())
    if kind.has_parameter:
        allowed |= {"value", "unit", "limits"} | ({"form"} if kind is Kind.C else set())
    for key in spec:
        if key not in allowed:
            problems.add(f"{where}.{key}", f"not a field of a {kind.value} element; expected {', '.join(sorted(allowed))}")
    checked = _Element(kind)
    if "unit" in spec:
        if isinstance(spec["unit"], str) and printable(spec["unit"]) == spec["unit"]:
            checked.unit = spec["unit"]
        else:
            problems.add(f"{where}.unit", f"expected text such as N/m (no control characters), got {_describe(spec['unit'])}")
    if kind.is_source and "value" in spec:
        if _number(spec["value"]):
            checked.value = float(spec["value"])
        else:
            problems.add(f"{where}.value", f"expected a finite number (the source's constant value), got {_describe(spec['value'])}")
    return _parameter(where, spec, checked, problems) if kind.has_parameter else checked


def _parameter(where: str, spec: dict[str, Any], checked: _Element, problems: _Problems) -> _Element | None:
    """An R, C, I, TF or GY element's value, C form and limits."""
    value = spec.get("value")
    if "value" not in spec:
        problems.add(f"{where}.value", f"missing: a {checked.kind.value} element needs a value > 0 (SI)")
        return None
    low, high = VALUE_RANGE
    if not (_number(value) and value > 0):
        problems.add(f"{where}.value", f"expected a finite number > 0 (SI), got {_describe(value)}")
        return None
    if not low <= value <= high:
        problems.add(f"{where}.value", f"{value:g} is outside [{low:g}, {high:g}], the values a model's arithmetic holds (SI)")
        return None
    checked.value = float(value)
    if checked.kind is Kind.C:
        form = spec.get("form")
        if isinstance(form, str) and form in _C_FORMS:
            checked.form = _C_FORMS[form]
        else:
            given = _describe(form) if "form" in spec else "nothing (a C element states its form)"
            problems.add(f"{where}.form", f"expected stiffness (effort = value x q) or compliance (effort = q / value), got {given}")
    if "limits" in spec:
        limits = spec["limits"]
        if not (isinstance(limits, list) and len(limits) == 2 and all(_number(v) and v > 0 for v in limits)):
            got = _cut(repr(limits), 60) if isinstance(limits, list) else _describe(limits)
            problems.add(f"{where}.limits", f"expected [lower, upper], two finite numbers > 0, got {got}")
        elif not limits[0] <= value <= limits[1] or not limits[0] < limits[1]:
            problems.add(f"{where}.limits", f"{limits} must satisfy lower < upper and contain the value {value}")
        elif not (low <= limits[0] and limits[1] <= high):
            problems.add(f"{where}.limits", f"{limits} must lie inside [{low:g}, {high:g}], the values a model's arithmetic holds (SI)")
        else:
            checked.limits = (float(limits[0]), float(limits[1]))
    return checked


def _source_values(elements: Mapping[str, _Element], load_source: str | None, problems: _Problems) -> None:
    """A constant value for every source but the load source, none for it."""
    for name, spec in elements.items():
        if not spec.kind.is_source:
            continue
        if name == load_source:
            if spec.value is not None:
                problems.add(f"elements.{name}.value", "the load source takes its value from the scenario's load; give load.nominal instead")
        elif spec.value is None:
            problems.add(f"elements.{name}.value", "missing: a source other than the load source needs a constant value")


def _bonds(raw: Any, elements: list[str], problems: _Problems) -> list[tuple[str, str]]:
    if not isinstance(raw, list) or not raw:
        problems.add("bonds", f"expected a non-empty list of [tail, head] pairs, got {_describe(raw)}")
        return []
    bonds = []
    for i, bond in enumerate(raw):
        where = f"bonds[{i}]"
        if not (isinstance(bond, list) and len(bond) == 2 and all(isinstance(end, str) for end in bond)):
            got = _cut(repr(bond), 60) if isinstance(bond, list) else _describe(bond)
            problems.add(where, f"expected [tail, head], two element names, got {got}")
            continue
        tail, head = bond
        unknown = [end for end in bond if end not in elements]
        if unknown:
            problems.add(where, f"[{tail}, {head}]: unknown element {unknown[0]!r}; expected one of {_listed(elements)}")
        elif tail == head:
            problems.add(where, f"[{tail}, {head}] joins an element to itself; expected two different elements")
        else:
            bonds.append((tail, head))
    return bonds


def _ports(elements: Mapping[str, _Element], bonds: list[tuple[str, str]], problems: _Problems) -> None:
    """Every element's number of bonds (and a TF or GY's directions)."""
    for name, spec in elements.items():
        kind = spec.kind
        ins = sum(head == name for _, head in bonds)
        outs = sum(tail == name for tail, _ in bonds)
        where = f"elements.{name}"
        if kind.is_junction and ins + outs < 2:
            problems.add(where, f"a {kind.value}-junction needs at least 2 bonds, has {ins + outs}")
        elif kind.is_two_port and (ins, outs) != (1, 1):
            expected = f"exactly one bond in ([x, {name}]) and one out ([{name}, y])"
            problems.add(where, f"a {kind.value} element needs {expected}, has {ins} in and {outs} out")
        elif not (kind.is_junction or kind.is_two_port) and ins + outs != 1:
            problems.add(where, f"a {kind.value} element needs exactly 1 bond, has {ins + outs}")


def _connected(elements: Mapping[str, _Element], bonds: list[tuple[str, str]], problems: _Problems) -> None:
    """Every element bonded, through the graph, to a source: a part no source reaches keeps an EA of 0."""
    neighbours: dict[str, list[str]] = {name: [] for name in elements}
    for tail, head in bonds:
        neighbours[tail].append(head)
        neighbours[head].append(tail)
    reached = {name for name, spec in elements.items() if spec.kind.is_source}
    stack = list(reached)
    while stack:
        for other in neighbours[stack.pop()]:
            if other not in reached:
                reached.add(other)
                stack.append(other)
    cut_off = [name for name in elements if name not in reached]
    if cut_off:
        problems.add("bonds", f"{_listed(cut_off)} not connected to any source (their EA would stay 0); bond them to the system or remove them")


@dataclass(frozen=True)
class _Load:
    """The load's checked fields (the source's unit; Hz)."""

    source: str
    nominal: float
    scale: float | None
    bandwidth: float


_LOAD_FIELDS = ("source", "nominal", "scale", "bandwidth")


def _load_source(raw: Any, elements: Mapping[str, _Element]) -> str | None:
    """The load's source where it names one of the sources, whatever the load's other fields hold."""
    source = raw.get("source") if isinstance(raw, dict) else None
    return source if isinstance(source, str) and source in elements and elements[source].kind.is_source else None


def _load(raw: Any, elements: Mapping[str, _Element], problems: _Problems) -> _Load | None:
    if not isinstance(raw, dict):
        problems.add("load", f"expected a mapping with {', '.join(_LOAD_FIELDS)} (scale optional), got {_describe(raw)}")
        return None
    count = len(problems)
    for key in raw:
        if key not in _LOAD_FIELDS:
            problems.add(f"load.{key}", f"unknown field; expected {', '.join(_LOAD_FIELDS)}")
    for key in ("source", "nominal", "bandwidth"):
        if key not in raw:
            problems.add(f"load.{key}", "missing (required)")
    source = _load_source(raw, elements)
    if "source" in raw and source is None:
        sources = [n for n, s in elements.items() if s.kind.is_source]
        problems.add("load.source", f"expected one of the sources {sources}, got {_describe(raw['source'])}")
    nominal, scale, bandwidth = raw.get("nominal"), raw.get("scale"), raw.get("bandwidth")
    if "nominal" in raw and not _number(nominal):
        expected = "a finite number (the load's operating level, the source's unit; 0 for a zero-mean load)"
        problems.add("load.nominal", f"expected {expected}, got {_describe(nominal)}")
    if "scale" in raw and not (_number(scale) and scale > 0):
        expected = "a finite number > 0 (the size of the random loads' variation, the source's unit)"
        problems.add("load.scale", f"expected {expected}, got {_describe(scale)}")
    elif "scale" not in raw and nominal == 0:
        problems.add("load.scale", "missing: a zero-mean load (nominal 0) needs the size of its variation, a finite number > 0 in the source's unit")
    if "bandwidth" in raw and not (_number(bandwidth) and bandwidth > 0):
        problems.add("load.bandwidth", f"expected a finite number of Hz > 0, got {_describe(bandwidth)}")
    if len(problems) > count or source is None or not (_number(nominal) and _number(bandwidth)):
        return None
    return _Load(source, float(nominal), None if scale is None else float(scale), float(bandwidth))
