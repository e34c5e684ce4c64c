"""Sequential causality assignment procedure (SCAP).

Causality says, for every bond, which end sets its effort (the other end then sets its flow).
Sources are fixed first, storage elements are then given integral causality one at a time, R
elements last, and after each choice the junction, TF and GY constraints are propagated. What comes
out is inspectable: for every element, whether its input S(t) of the paper's eq 6 is its effort or
its flow.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from ea_gym.bondgraph.elements import Kind
from ea_gym.bondgraph.graph import BondGraph, BondGraphError

Signal = Literal["effort", "flow"]


@dataclass(frozen=True)
class Causality:
    """The result of the SCAP.

    Attributes:
        effort_setter: for each bond (in the graph's order), the name of the element that sets its effort.
        inputs: for each one-port element, which of its power variables is its input S(t) (eq 6).
        algebraic_loop: R elements whose causality was an arbitrary choice: they sit on an algebraic
            loop, which the equation generator solves as a linear system.
    """

    effort_setter: tuple[str, ...]
    inputs: dict[str, Signal]
    algebraic_loop: tuple[str, ...]

    def is_integral(self, element: str, kind: Kind) -> bool:
        """Integral causality: an I element driven by effort, a C element driven by flow."""
        return self.inputs[element] == ("effort" if kind is Kind.I else "flow")


class _Assigner:
    """Holds the partial assignment and propagates the junction, TF and GY rules."""

    def __init__(self, graph: BondGraph) -> None:
        self.graph = graph
        self.elements = graph.elements
        self.bonds = graph.bonds
        self.setter: list[str | None] = [None] * len(self.bonds)

    def fix(self, bond: int, who: str, why: str) -> None:
        current = self.setter[bond]
        if current is None:
            self.setter[bond] = who
        elif current != who:
            b = self.bonds[bond]
            raise BondGraphError(f"causal conflict on bond {bond} ({b.tail}->{b.head}) at {why}")

    def propagate(self) -> None:
        changed = True
        while changed:
            before = list(self.setter)
            for name, element in self.elements.items():
                if element.kind.is_junction:
                    self._junction(name, element.kind)
                elif element.kind.is_two_port:
                    self._two_port(name, element.kind)
            changed = before != self.setter

    def _junction(self, name: str, kind: Kind) -> None:
        ports = self.graph.bonds_of(name)
        free = [i for i in ports if self.setter[i] is None]
        # A 0-junction takes its effort from exactly one bond; a 1-junction its flow from exactly one,
        # i.e. it sets the effort of exactly one bond.
        if kind is Kind.ZERO:
            strong = [i for i in ports if self.setter[i] not in (None, name)]
        else:
            strong = [i for i in ports if self.setter[i] == name]
        if len(strong) > 1:
            culprits = sorted({self.bonds[i].other(name) for i in strong})
            rule = "effort" if kind is Kind.ZERO else "flow"
            raise BondGraphError(
                f"causal conflict at {kind.value}-junction {name!r}: its {rule} is imposed by "
                f"more than one of {culprits}"
            )
        if not strong and not free:
            rule = "effort" if kind is Kind.ZERO else "flow"
            raise BondGraphError(
                f"{kind.value}-junction {name!r} has no bond that imposes its {rule}: the graph is under-determined"
            )
        if len(strong) == 1:
            for i in free:
                self.fix(i, name if kind is Kind.ZERO else self.bonds[i].other(name), f"junction {name!r}")
        elif len(free) == 1:
            i = free[0]
            self.fix(i, self.bonds[i].other(name) if kind is Kind.ZERO else name, f"junction {name!r}")

    def _two_port(self, name: str, kind: Kind) -> None:
        a, b = self.graph.two_port_bonds(name)
        for known, unknown in ((a, b), (b, a)):
            if self.setter[known] is None:
                continue
            sets_known = self.setter[known] == name
            # TF passes effort through (sets exactly one side); GY turns flow into effort (both or none).
            sets_unknown = sets_known if kind is Kind.GY else not sets_known
            self.fix(unknown, name if sets_unknown else self.bonds[unknown].other(name), f"{kind.value} {name!r}")


def assign_causality(graph: BondGraph) -> Causality:
    """Run the SCAP on ``graph``.

    Raises:
        BondGraphError: on a causal conflict between sources, or when storage elements end in
            derivative causality (the error names them: they are not independent energy stores and
            the model would need index reduction, which this engine does not do).
    """
    graph.validate()
    state = _Assigner(graph)
    elements = graph.elements

    def one_port_bond(name: str) -> int:
        return graph.bonds_of(name)[0]

    for name in graph.names([Kind.SE, Kind.SF]):
        bond = one_port_bond(name)
        state.fix(bond, name if elements[name].kind is Kind.SE else graph.bonds[bond].other(name), f"source {name!r}")
        state.propagate()

    derivative: list[str] = []
    for name in graph.names([Kind.I, Kind.C]):
        bond = one_port_bond(name)
        integral_setter = name if elements[name].kind is Kind.C else graph.bonds[bond].other(name)
        if state.setter[bond] is None:
            state.fix(bond, integral_setter, f"storage {name!r}")
            state.propagate()
        elif state.setter[bond] != integral_setter:
            derivative.append(name)
    if derivative:
        raise BondGraphError(
            f"storage elements {derivative} are in derivative causality: their energy variables depend on "
            "other states or sources; merge them with the storage elements they depend on"
        )

    loop: list[str] = []
    for name in graph.names([Kind.R]):
        bond = one_port_bond(name)
        if state.setter[bond] is None:
            loop.append(name)
            state.fix(bond, name, f"resistor {name!r}")
            state.propagate()

    for i, setter in enumerate(state.setter):
        if setter is None:  # a junction-only loop: any consistent choice will do
            state.fix(i, graph.bonds[i].tail, f"bond {i}")
            state.propagate()

    setters = tuple(s for s in state.setter if s is not None)
    inputs: dict[str, Signal] = {}
    for name, element in elements.items():
        if element.kind.is_junction or element.kind.is_two_port:
            continue
        inputs[name] = "flow" if setters[one_port_bond(name)] == name else "effort"
    return Causality(effort_setter=setters, inputs=inputs, algebraic_loop=tuple(loop))
