"""Bond graphs as data: elements and bonds (``elements``), the graph (``graph``), causality by SCAP
(``causality``), the linear state-space model (``equations``) and its exact simulation (``simulation``).

    from ea_gym.bondgraph import BondGraph, StateSpaceModel
"""

from ea_gym.bondgraph.causality import Causality, assign_causality
from ea_gym.bondgraph.elements import Bond, CForm, Element, Kind
from ea_gym.bondgraph.equations import LinearMatrices, StateSpaceModel
from ea_gym.bondgraph.graph import BondGraph, BondGraphError
from ea_gym.bondgraph.simulation import (
    HOLD_ORDER,
    Discretization,
    ModelMatrices,
    discretize,
    expm,
    hermite_coefficients,
    matrices_along,
    propagate,
    simulate_batch,
    simulate_linear,
    simulate_measured,
    unique_rows,
)

__all__ = [
    "HOLD_ORDER",
    "Bond",
    "BondGraph",
    "BondGraphError",
    "CForm",
    "Causality",
    "Discretization",
    "Element",
    "Kind",
    "LinearMatrices",
    "ModelMatrices",
    "StateSpaceModel",
    "assign_causality",
    "discretize",
    "expm",
    "hermite_coefficients",
    "matrices_along",
    "propagate",
    "simulate_batch",
    "simulate_linear",
    "simulate_measured",
    "unique_rows",
]
