"""The environment's observation rows (``ea_gym._kernels.observation``), as numpy's clip, to the bit."""

from __future__ import annotations

import numpy as np


def observation_rows(
    ea: np.ndarray, ea_reference: np.ndarray, eai: np.ndarray, since_maintenance: np.ndarray, down: np.ndarray, diagnosis: np.ndarray,
    values: np.ndarray, low: np.ndarray, span: np.ndarray, rul: np.ndarray, rul_max: float, longest_run: float, residual_floor: float,
    position_low: float, position_high: float, bound: float, out: np.ndarray,
) -> None:
    """Each system's observation side by side in ``out`` (N, W) float32, every value clipped to +-``bound``:
    ea, eai, the EA residual over max(ea_reference, residual_floor), the time since maintenance (at most
    ``longest_run``), maintenance in progress (0/1), the diagnosis, each value's position (values - low) /
    span in [position_low, position_high], and the RUL (NaN read as ``rul_max``, in [0, rul_max])."""
    residual = (ea - ea_reference) / np.maximum(ea_reference, residual_floor)
    position = np.clip((values - low) / span, position_low, position_high)
    remaining = np.clip(np.where(np.isnan(rul), rul_max, rul), 0.0, rul_max)
    columns = [ea, eai, residual, np.minimum(since_maintenance, longest_run)[:, None], np.where(down, 1.0, 0.0)[:, None], diagnosis, position]
    out[:] = np.concatenate([np.clip(c, -bound, bound) for c in [*columns, remaining]], axis=1)
