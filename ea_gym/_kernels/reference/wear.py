"""The plant's wear (``ea_gym._kernels.wear``): a step's linear part and the mean trend's RUL."""

from __future__ import annotations

import numpy as np


def steady_wear(
    values: np.ndarray, columns: np.ndarray, running: np.ndarray, faulty: np.ndarray, arrival: np.ndarray, velocity: np.ndarray,
    clock: np.ndarray, dt: float, linear: np.ndarray, active: np.ndarray,
) -> np.ndarray:
    """Seconds of wear in [clock, clock + dt] after the fault's ``arrival`` into ``active`` (NaN kept); the
    mean velocity x active added to the faulty component's column where running and the wear is linear
    or the mean 0; the systems whose increment is random instead."""
    active[:] = np.clip(clock + dt - np.maximum(arrival, clock), 0.0, dt)
    worn = np.flatnonzero(active > 0)
    mean = velocity[worn] * active[worn]
    random = ~linear[faulty[worn]] & (mean != 0)
    steady = ~random & running[worn]
    values[worn[steady], columns[faulty[worn[steady]]]] += mean[steady]
    return worn[random].astype(np.intp)


def mean_trend_rul(
    values: np.ndarray, columns: np.ndarray, faulty: np.ndarray, limits: np.ndarray, velocity: np.ndarray, arrival: np.ndarray,
    clock: np.ndarray, out: np.ndarray,
) -> None:
    """Seconds until each faulty component's mean trend reaches the limit it heads for, 0 past it, inf
    before its fault arrives or without drift."""
    current = values[np.arange(len(faulty)), columns[faulty]]
    limit = np.where(velocity > 0, limits[faulty, 1], limits[faulty, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        rul = np.where(velocity != 0, (limit - current) / velocity, np.inf)
    out[:] = np.where(clock >= arrival, np.maximum(rul, 0.0), np.inf)
