"""The observation of N systems (``ea_gym.env.observations.Observer.observe``) in one compiled loop: the
arithmetic of its numpy form, element by element, so to the bit (``np.clip``: NaN kept, the bound where
the value is not strictly inside), cast to float32 as ``astype`` casts.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.observation``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ea_gym._kernels.numpy_forms import numpy_maximum, numpy_minimum


@numba.njit(cache=True, inline="always")
def numpy_clip(x: float, low: float, high: float) -> float:
    """``np.clip(x, low, high)`` of a float: NaN kept, else the larger of x and low (low where equal), then the smaller of that and high."""
    if math.isnan(x):
        return x
    x = x if x > low else low
    return x if x < high else high


@numba.njit(cache=True)
def observation_rows(
    ea: np.ndarray, ea_reference: np.ndarray, eai: np.ndarray, since_maintenance: np.ndarray, down: np.ndarray, diagnosis: np.ndarray,
    values: np.ndarray, low: np.ndarray, span: np.ndarray, rul: np.ndarray, rul_max: float, longest_run: float, residual_floor: float,
    position_low: float, position_high: float, bound: float, out: np.ndarray,
) -> None:
    """Each system's observation, its keys side by side in ``out`` (N, W) float32, every value clipped to +-``bound``:
    ea (E), eai (C), residual (E) = (ea - ea_reference) / max(ea_reference, residual_floor), time since maintenance
    (1, at most ``longest_run``), maintenance in progress (1, ``down`` as 0/1), then, where ``diagnosis``,
    ``values`` and ``rul`` have columns, the diagnosis (K), each value's position (values - low) / span in
    [position_low, position_high] (n), and the RUL (3; NaN read as ``rul_max``, clipped to [0, rul_max])."""
    for i in range(out.shape[0]):
        c = 0
        for j in range(ea.shape[1]):
            out[i, c] = numpy_clip(ea[i, j], -bound, bound)
            c += 1
        for j in range(eai.shape[1]):
            out[i, c] = numpy_clip(eai[i, j], -bound, bound)
            c += 1
        for j in range(ea.shape[1]):
            residual = (ea[i, j] - ea_reference[i, j]) / numpy_maximum(ea_reference[i, j], residual_floor)
            out[i, c] = numpy_clip(residual, -bound, bound)
            c += 1
        out[i, c] = numpy_clip(numpy_minimum(since_maintenance[i], longest_run), -bound, bound)
        out[i, c + 1] = 1.0 if down[i] else 0.0
        c += 2
        for j in range(diagnosis.shape[1]):
            out[i, c] = numpy_clip(diagnosis[i, j], -bound, bound)
            c += 1
        for j in range(values.shape[1]):
            position = numpy_clip((values[i, j] - low[j]) / span[j], position_low, position_high)
            out[i, c] = numpy_clip(position, -bound, bound)
            c += 1
        for j in range(rul.shape[1]):
            r = rul_max if math.isnan(rul[i, j]) else rul[i, j]
            out[i, c] = numpy_clip(numpy_clip(r, 0.0, rul_max), -bound, bound)
            c += 1
