"""The parts' wear (``ea_gym._kernels.wear``): a step's linear part and the mean trends' RUL, process by process."""

from __future__ import annotations

import numpy as np


def steady_wear(
    values: np.ndarray, systems: np.ndarray, columns: np.ndarray, running: np.ndarray, parts: np.ndarray, arrival: np.ndarray,
    velocity: np.ndarray, clock: np.ndarray, dt: float, linear: np.ndarray, active: np.ndarray,
) -> np.ndarray:
    """Seconds of wear in [clock, clock + dt] of each process's system after its ``arrival`` into ``active``
    (NaN kept); the mean velocity x active added to its part's column where its system runs and the part's
    wear is linear or the mean 0; the processes whose increment is random instead."""
    own_clock = clock[systems]
    active[:] = np.clip(own_clock + dt - np.maximum(arrival, own_clock), 0.0, dt)
    worn = np.flatnonzero(active > 0)
    mean = velocity[worn] * active[worn]
    random = ~linear[parts[worn]] & (mean != 0)
    steady = ~random & running[systems[worn]]
    rows = worn[steady]
    np.add.at(values, (systems[rows], columns[parts[rows]]), mean[steady])
    return worn[random].astype(np.intp)


def mean_trend_rul(
    values: np.ndarray, systems: np.ndarray, columns: np.ndarray, parts: np.ndarray, limits: np.ndarray, velocity: np.ndarray,
    arrival: np.ndarray, clock: np.ndarray, out: np.ndarray,
) -> None:
    """Seconds until each process's part, at ``velocity``, reaches the limit it heads for, 0 past it, inf
    before its arrival or without drift."""
    current = values[systems, columns[parts]]
    limit = np.where(velocity > 0, limits[parts, 1], limits[parts, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        rul = np.where(velocity != 0, (limit - current) / velocity, np.inf)
    out[:] = np.where(clock[systems] >= arrival, np.maximum(rul, 0.0), np.inf)
