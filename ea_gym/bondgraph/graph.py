"""The bond-graph container: elements, bonds and their structural checks."""

from __future__ import annotations

from collections.abc import Iterable

from ea_gym.bondgraph.elements import Bond, CForm, Element, Kind


class BondGraphError(ValueError):
    """A bond graph that is malformed or cannot be turned into a state-space model."""


class BondGraph:
    """A linear bond graph built element by element.

    Example (the spring-mass-damper of the paper's Fig 7)::

        g = BondGraph()
        g.add("F", "Se"); g.add("j", "1")
        g.add("m", "I"); g.add("k", "C", c_form="stiffness"); g.add("b", "R")
        g.connect("F", "j"); g.connect("j", "m"); g.connect("j", "k"); g.connect("j", "b")
    """

    def __init__(self) -> None:
        self._elements: dict[str, Element] = {}
        self._bonds: list[Bond] = []

    def add(self, name: str, kind: Kind | str, *, c_form: CForm | str = CForm.CAPACITANCE) -> BondGraph:
        """Add an element; ``kind`` is one of Se, Sf, R, C, I, TF, GY, 0, 1."""
        try:
            kind = Kind(kind)
        except ValueError:
            raise BondGraphError(
                f"element {name!r}: unknown kind {kind!r}; expected one of {[k.value for k in Kind]}"
            ) from None
        if name in self._elements:
            raise BondGraphError(f"element {name!r} is defined twice")
        self._elements[name] = Element(name, kind, CForm(c_form))
        return self

    def connect(self, tail: str, head: str) -> BondGraph:
        """Add a bond whose positive power flows from ``tail`` to ``head``."""
        for end in (tail, head):
            if end not in self._elements:
                raise BondGraphError(f"bond {tail}->{head}: no element named {end!r}")
        if tail == head:
            raise BondGraphError(f"bond {tail}->{head} connects an element to itself")
        self._bonds.append(Bond(tail, head))
        return self

    @property
    def elements(self) -> dict[str, Element]:
        return dict(self._elements)

    @property
    def bonds(self) -> tuple[Bond, ...]:
        return tuple(self._bonds)

    def bonds_of(self, name: str) -> list[int]:
        """Indices of the bonds attached to element ``name``, in the order they were connected."""
        return [i for i, b in enumerate(self._bonds) if name in (b.tail, b.head)]

    def names(self, kinds: Iterable[Kind]) -> list[str]:
        """Element names of the given kinds, in insertion order."""
        kinds = set(kinds)
        return [n for n, e in self._elements.items() if e.kind in kinds]

    def validate(self) -> None:
        """Check the port count of every element; raise ``BondGraphError`` naming the culprits."""
        if not self._elements:
            raise BondGraphError("the bond graph has no elements")
        for name, element in self._elements.items():
            ports = self.bonds_of(name)
            kind = element.kind
            if kind.is_junction:
                if len(ports) < 2:
                    raise BondGraphError(f"junction {name!r} needs at least 2 bonds, has {len(ports)}")
            elif kind.is_two_port:
                ins = [i for i in ports if self._bonds[i].head == name]
                outs = [i for i in ports if self._bonds[i].tail == name]
                if len(ins) != 1 or len(outs) != 1:
                    raise BondGraphError(
                        f"{kind.value} element {name!r} needs exactly one bond in and one bond out, "
                        f"has {len(ins)} in and {len(outs)} out"
                    )
            elif len(ports) != 1:
                raise BondGraphError(f"{kind.value} element {name!r} needs exactly 1 bond, has {len(ports)}")
        for i, bond in enumerate(self._bonds):
            a, b = self._elements[bond.tail], self._elements[bond.head]
            if not (a.kind.is_junction or a.kind.is_two_port or b.kind.is_junction or b.kind.is_two_port):
                raise BondGraphError(
                    f"bond {i} ({bond.tail}->{bond.head}) joins two one-port elements; put a junction between them"
                )

    def two_port_bonds(self, name: str) -> tuple[int, int]:
        """(incoming bond, outgoing bond) of a TF or GY element."""
        ports = self.bonds_of(name)
        bond_in = next(i for i in ports if self._bonds[i].head == name)
        bond_out = next(i for i in ports if self._bonds[i].tail == name)
        return bond_in, bond_out
