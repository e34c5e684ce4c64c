"""Power balance at the junctions and two-ports of a bond graph, for the engine's tests."""

import numpy as np

from ea_gym.bondgraph.graph import BondGraph


def power_residuals(graph: BondGraph, z: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """For every junction, TF and GY: (net power into it, largest |bond power| at it).

    z holds efforts then flows of every bond, (..., 2 n). A bond's power e*f flows from its tail to
    its head, so it counts + at a junction it points into and - at one it leaves.
    """
    bonds = graph.bonds
    n = len(bonds)
    e, f = z[..., :n], z[..., n:]
    out = {}
    for name, element in graph.elements.items():
        if element.kind.is_junction:
            ports = graph.bonds_of(name)
        elif element.kind.is_two_port:
            ports = list(graph.two_port_bonds(name))
        else:
            continue
        signs = np.array([1.0 if bonds[i].head == name else -1.0 for i in ports])
        powers = e[..., ports] * f[..., ports]
        out[name] = ((powers * signs).sum(axis=-1), np.abs(powers).max(axis=-1))
    return out
