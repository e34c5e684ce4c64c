"""Energy Activity, the time integral of |P|, by the trapezoid rule (``ea_gym._kernels.activity``)."""

from __future__ import annotations

import numpy as np


def trapezoid_activity(power: np.ndarray, start: int, stop: int, h: float) -> float:
    """EA (J) of ``power`` (T,) in W over the sample intervals [start, stop): the trapezoid of |P| (the
    kernel adds the intervals in time order, numpy pairwise: equal to ~1e-13)."""
    return float(np.trapezoid(np.abs(power[start : stop + 1]), dx=h))


def interval_activities(power: np.ndarray, h: float) -> np.ndarray:
    """EA (J) of every sample interval of every row of ``power`` (M, T): (M, T - 1), to the bit."""
    magnitude = np.abs(power)
    return 0.5 * (magnitude[:, :-1] + magnitude[:, 1:]) * h


def component_shares(ea: np.ndarray, columns: np.ndarray, out: np.ndarray) -> int:
    """EAI of every row of ``ea`` (rows, E) over its components' ``columns`` into ``out`` (rows, C): each one's
    EA over their sum, 1 / C each where the sum is 0; -1, or (nothing written) the first component whose
    EA is not finite and >= 0 in some row. One row's sum is numpy's; several rows' add in order."""
    values = ea[:, columns]
    bad = ~(np.isfinite(values) & (values >= 0.0)).all(axis=0)
    if bad.any():
        return int(np.argmax(bad))
    total = np.array([values[0].sum()]) if len(values) == 1 else np.array([sum(row.tolist(), 0.0) for row in values])
    with np.errstate(invalid="ignore", divide="ignore"):
        out[:] = np.where(total[:, None] > 0.0, values / total[:, None], 1.0 / len(columns))
    return -1


def summed_shares(sub_ea: np.ndarray, sub_ea_reference: np.ndarray, columns: np.ndarray, ea: np.ndarray, out: np.ndarray) -> int:
    """Every element's EA over a step into ``ea`` (2N, E): ``sub_ea`` then ``sub_ea_reference`` (N, E, S)
    summed over their sub-windows; then ``component_shares`` of its rows into ``out``."""
    n = len(sub_ea)
    ea[:n], ea[n:] = sub_ea.sum(axis=-1), sub_ea_reference.sum(axis=-1)
    return component_shares(ea, columns, out)
