"""Bond-graph elements and bonds.

Every one-port element (Se, Sf, R, C, I) has exactly one bond; TF and GY have two (the first bond
carries power in, the second out); junctions have any number. Each parametrised element carries
one component value, the paper's phi: resistance, stiffness or capacitance, inertance, modulus.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass


class Kind(str, enum.Enum):
    """Element kinds of a linear bond graph."""

    SE = "Se"
    SF = "Sf"
    R = "R"
    C = "C"
    I = "I"  # noqa: E741 - the bond-graph name of the inertia element
    TF = "TF"
    GY = "GY"
    ZERO = "0"
    ONE = "1"

    @property
    def is_source(self) -> bool:
        return self in (Kind.SE, Kind.SF)

    @property
    def is_storage(self) -> bool:
        return self in (Kind.C, Kind.I)

    @property
    def is_junction(self) -> bool:
        return self in (Kind.ZERO, Kind.ONE)

    @property
    def is_two_port(self) -> bool:
        return self in (Kind.TF, Kind.GY)

    @property
    def has_parameter(self) -> bool:
        return not (self.is_source or self.is_junction)


class CForm(str, enum.Enum):
    """How a C element's component value enters its law: e = k q (stiffness) or e = q / C (capacitance)."""

    STIFFNESS = "stiffness"
    CAPACITANCE = "capacitance"


@dataclass(frozen=True)
class Element:
    """One node of a bond graph.

    Attributes:
        name: unique name; for parametrised elements it is also the parameter's name.
        kind: the element kind.
        c_form: for C elements only, whether the value is a stiffness (e = k q, N/m) or a
            capacitance / compliance (e = q / C, F or m/N).

    Laws (e effort, f flow into the element, q = integral of f, p = integral of e):
        R: e = R f.  C: e = k q or e = q / C.  I: f = p / I.
        TF (modulus n): e_in = n e_out, f_out = n f_in.  GY (modulus r): e_in = r f_out, e_out = r f_in.
    """

    name: str
    kind: Kind
    c_form: CForm = CForm.CAPACITANCE

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"element name {self.name!r} must be a Python identifier")


@dataclass(frozen=True)
class Bond:
    """A bond carrying power from ``tail`` to ``head`` (the half arrow points at ``head``)."""

    tail: str
    head: str

    def other(self, name: str) -> str:
        return self.head if name == self.tail else self.tail
