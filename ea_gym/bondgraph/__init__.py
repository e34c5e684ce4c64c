"""Bond graphs as data: elements and bonds (``elements``), the graph (``graph``), causality by SCAP
(``causality``), the linear state-space model (``equations``) and its exact simulation (``simulation``).

    from ea_gym.bondgraph import BondGraph, StateSpaceModel
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ea_gym.bondgraph.causality import Causality, assign_causality
from ea_gym.bondgraph.elements import Bond, CForm, Element, Kind
from ea_gym.bondgraph.equations import LinearMatrices, StateSpaceModel
from ea_gym.bondgraph.graph import BondGraph, BondGraphError

if TYPE_CHECKING:
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

# the simulation (numba kernels) is imported on first use: a model is read and checked without it
_SIMULATION = (
    "HOLD_ORDER", "Discretization", "ModelMatrices",
    "discretize", "expm", "hermite_coefficients", "matrices_along",
    "propagate", "simulate_batch", "simulate_linear", "simulate_measured", "unique_rows",
)


def __getattr__(name: str) -> Any:
    if name not in _SIMULATION:
        raise AttributeError(f"module 'ea_gym.bondgraph' has no attribute {name!r}")
    return getattr(importlib.import_module("ea_gym.bondgraph.simulation"), name)


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
