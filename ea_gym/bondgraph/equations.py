"""From a bond graph to its linear state-space model, for many parameter sets at once.

The unknowns are the effort and flow of every bond, z = [e_0 .. e_{n-1}, f_0 .. f_{n-1}]. Every bond
end contributes one equation (constitutive law, junction or two-port relation), so the 2n equations
M(phi) z = N(phi) x + P u determine z from the energy variables x (p of each I, q of each C) and the
source values u. Solving them, batched over parameter sets, gives the output map z = Cy x + Dy u and
the state equation dx/dt = A x + B u (dp/dt = e of each I bond, dq/dt = f of each C bond). Algebraic
loops are solved exactly by the same linear solve.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ea_gym.bondgraph.causality import Causality, assign_causality
from ea_gym.bondgraph.elements import CForm, Kind
from ea_gym.bondgraph.graph import BondGraph, BondGraphError


@dataclass(frozen=True)
class LinearMatrices:
    """State-space matrices, each with the leading batch shape of the parameters they came from.

    A: (..., nx, nx) in 1/s; B: (..., nx, nu); Cy: (..., 2 n_bonds, nx) and Dy: (..., 2 n_bonds, nu)
    map (x, u) to the efforts (first n_bonds rows) and flows (last n_bonds rows) of every bond.
    """

    A: np.ndarray
    B: np.ndarray
    Cy: np.ndarray
    Dy: np.ndarray


@dataclass(frozen=True)
class _Entry:
    """One parameter-dependent coefficient: ``matrix[row, col] += scale * (value or 1 / value)``."""

    parameter: int
    matrix: str  # "M" or "N"
    row: int
    col: int
    scale: float
    reciprocal: bool


@dataclass
class _Equations:
    """The 2n bond-end equations M(phi) z = N(phi) x + P u as they are assembled, one row per bond end:
    M0 the constant part of M, P the input map, ``entries`` the parameter-dependent coefficients."""

    M0: np.ndarray
    P: np.ndarray
    entries: list[_Entry] = field(default_factory=list)
    row: int = 0


class StateSpaceModel:
    """The linear model of a bond graph.

    Attributes:
        graph: the bond graph.
        causality: the SCAP result (inspectable inputs S(t) of every element).
        parameter_names: one per R, C, I, TF, GY element, named after it, in the graph's order.
        state_names: one per storage element (its energy variable: p for I, q for C).
        input_names: one per source, in the graph's order.
    """

    def __init__(self, graph: BondGraph) -> None:
        self.graph = graph
        self.causality: Causality = assign_causality(graph)
        self.n_bonds = n = len(graph.bonds)
        self.parameter_names = tuple(graph.names(k for k in Kind if k.has_parameter))
        self.state_names = tuple(graph.names([Kind.I, Kind.C]))
        self.input_names = tuple(graph.names([Kind.SE, Kind.SF]))
        self.bond_of: dict[str, int] = {}
        # +1 where the bond points into the element: then f is the flow into it
        self.flow_sign: dict[str, float] = {}
        equations = _Equations(M0=np.zeros((2 * n, 2 * n)), P=np.zeros((2 * n, len(self.input_names))))
        for name, element in graph.elements.items():
            if element.kind.is_junction:
                self._junction_equations(name, equations)
            elif element.kind.is_two_port:
                self._two_port_equations(name, equations)
            else:
                self._one_port_equation(name, equations)
        assert equations.row == 2 * n, "every bond end contributes exactly one equation"
        self._M0 = equations.M0
        self._P = equations.P
        self._rhs0 = np.concatenate([np.zeros((2 * n, len(self.state_names))), self._P], axis=1)  # [N | P] before the entries
        self._entries = tuple(equations.entries)
        self._S = self._state_derivative_map()

    def _junction_equations(self, name: str, equations: _Equations) -> None:
        """A 0 junction's common effort and summed flows (a 1 junction's: flow and efforts), one row per bond."""
        n, ports = self.n_bonds, self.graph.bonds_of(name)
        common, summed = (0, n) if self.graph.elements[name].kind is Kind.ZERO else (n, 0)
        for i in ports[1:]:
            equations.M0[equations.row, common + ports[0]], equations.M0[equations.row, common + i] = 1.0, -1.0
            equations.row += 1
        for i in ports:
            equations.M0[equations.row, summed + i] = 1.0 if self.graph.bonds[i].head == name else -1.0
        equations.row += 1

    def _two_port_equations(self, name: str, equations: _Equations) -> None:
        """TF: e_a = n e_b, f_b = n f_a.  GY: e_a = r f_b, e_b = r f_a (a: incoming bond, b: outgoing)."""
        n = self.n_bonds
        a, b = self.graph.two_port_bonds(name)
        j = self.parameter_names.index(name)
        tf = self.graph.elements[name].kind is Kind.TF
        pairs = [(a, b), (n + b, n + a)] if tf else [(a, n + b), (b, n + a)]
        for lhs, rhs in pairs:
            equations.M0[equations.row, lhs] = 1.0
            equations.entries.append(_Entry(j, "M", equations.row, rhs, -1.0, False))
            equations.row += 1

    def _one_port_equation(self, name: str, equations: _Equations) -> None:
        """The constitutive law of a source, R, C or I element on its one bond."""
        element = self.graph.elements[name]
        kind, row = element.kind, equations.row
        i = self.graph.bonds_of(name)[0]
        sign = 1.0 if self.graph.bonds[i].head == name else -1.0
        self.bond_of[name] = i
        self.flow_sign[name] = sign
        effort, flow = i, self.n_bonds + i
        if kind is Kind.SE:
            equations.M0[row, effort] = 1.0
            equations.P[row, self.input_names.index(name)] = 1.0
        elif kind is Kind.SF:
            # the source's value is the flow it delivers, i.e. out of it
            equations.M0[row, flow] = 1.0
            equations.P[row, self.input_names.index(name)] = -sign
        elif kind is Kind.R:
            equations.M0[row, effort] = 1.0
            equations.entries.append(_Entry(self.parameter_names.index(name), "M", row, flow, -sign, False))
        elif kind is Kind.C:
            equations.M0[row, effort] = 1.0
            capacitance = element.c_form is CForm.CAPACITANCE
            equations.entries.append(_Entry(self.parameter_names.index(name), "N", row, self.state_names.index(name), 1.0, capacitance))
        else:  # I: flow into the element = p / I
            equations.M0[row, flow] = sign
            equations.entries.append(_Entry(self.parameter_names.index(name), "N", row, self.state_names.index(name), 1.0, True))
        equations.row += 1

    def _state_derivative_map(self) -> np.ndarray:
        """S of dx/dt = S z: dp/dt = effort of an I bond, dq/dt = flow into a C element, (nx, 2 n_bonds)."""
        S = np.zeros((len(self.state_names), 2 * self.n_bonds))
        for k, name in enumerate(self.state_names):
            i = self.bond_of[name]
            if self.graph.elements[name].kind is Kind.I:
                S[k, i] = 1.0
            else:
                S[k, self.n_bonds + i] = self.flow_sign[name]
        return S

    @property
    def n_states(self) -> int:
        return len(self.state_names)

    @property
    def n_inputs(self) -> int:
        return len(self.input_names)

    def matrices(self, parameters: np.ndarray) -> LinearMatrices:
        """State-space and output matrices for parameter vectors of shape (..., n_parameters).

        Raises:
            BondGraphError: when the junction equations are singular for some parameter set (an
                ill-posed algebraic loop), naming the parameter values.
        """
        theta = np.asarray(parameters, dtype=float)
        if theta.shape[-1:] != (len(self.parameter_names),):
            raise ValueError(
                f"parameters must have a last axis of length {len(self.parameter_names)} "
                f"({list(self.parameter_names)}), got shape {theta.shape}"
            )
        batch = theta.shape[:-1]
        nx = len(self.state_names)
        M = np.empty(batch + self._M0.shape)
        M[...] = self._M0
        rhs = np.empty(batch + self._rhs0.shape)  # [N | P]
        rhs[...] = self._rhs0
        N = rhs[..., :nx]
        for entry in self._entries:
            value = theta[..., entry.parameter]
            coefficient = entry.scale / value if entry.reciprocal else entry.scale * value
            target = M if entry.matrix == "M" else N
            target[..., entry.row, entry.col] += coefficient
        try:
            X = np.linalg.solve(M, rhs)
        except np.linalg.LinAlgError:
            raise BondGraphError(
                "the bond-graph equations are singular for these parameters (an ill-posed algebraic loop "
                f"through {list(self.causality.algebraic_loop)})"
            ) from None
        # one product for both: S selects (entries 0 and +-1, one nonzero per row), so each entry is exact in any order
        AB = self._S @ X
        return LinearMatrices(A=AB[..., :nx], B=AB[..., nx:], Cy=X[..., :nx], Dy=X[..., nx:])

    def element_bonds(self) -> tuple[tuple[str, ...], np.ndarray, np.ndarray, np.ndarray]:
        """Where every non-junction element's effort and flow sit among the bond values (..., 2 n_bonds).

        Returns:
            the element names in the graph's order; the index of each one's effort and of its flow in
            the bond values; the sign that turns that bond's flow into the element's (see ``element_signals``).
        """
        if not hasattr(self, "_element_bonds"):
            names, efforts, flows, signs = [], [], [], []
            for name, element in self.graph.elements.items():
                if element.kind.is_junction:
                    continue
                if element.kind.is_two_port:
                    i, sign = self.graph.two_port_bonds(name)[0], 1.0
                else:
                    i, sign = self.bond_of[name], self.flow_sign[name]
                    if element.kind.is_source:
                        sign = -sign
                names.append(name)
                efforts.append(i)
                flows.append(self.n_bonds + i)
                signs.append(sign)
            self._element_bonds = (tuple(names), np.array(efforts, dtype=np.intp), np.array(flows, dtype=np.intp), np.array(signs))
        return self._element_bonds

    def element_signals(self, bond_values: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """Split bond efforts and flows (..., 2 n_bonds) into per-element effort and flow.

        The flow of R, C and I elements is the flow into them (power e*f > 0 is absorbed); the flow of
        a source is the flow it delivers; a TF or GY reports its incoming bond.
        """
        effort: dict[str, np.ndarray] = {}
        flow: dict[str, np.ndarray] = {}
        for name, e, f, sign in zip(*self.element_bonds()):
            effort[name] = bond_values[..., e]
            flow[name] = float(sign) * bond_values[..., f]
        return effort, flow
