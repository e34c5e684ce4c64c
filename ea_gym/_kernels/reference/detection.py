"""Fault detection's statistic and alarm (``ea_gym._kernels.detection``), to the bit."""

from __future__ import annotations

import numpy as np


def detect(
    start: int, stop: int, ea: np.ndarray, ea_reference: np.ndarray, window: int, balance: np.ndarray, dissipated: np.ndarray,
    steps: np.ndarray, step_samples: int, span_samples: np.ndarray, thresholds: np.ndarray, persistence: int, time: np.ndarray, tiny: float,
    above: np.ndarray, alarm: np.ndarray, detection_time: np.ndarray, statistic: np.ndarray,
) -> None:
    """Systems [start, stop)'s statistic (N, E + 1): each element's relative EA residual over the last
    ``window`` sub-windows, then the balance residual over the dissipators' EA (denominators at least
    ``tiny``), 0 before the system has seen ``span_samples``; the alarm after ``persistence`` steps in a row
    with a statistic above its threshold, ``detection_time`` its ``time``."""
    part = slice(start, stop)
    real, reference = ea[part, :, -window:].sum(-1), ea_reference[part, :, -window:].sum(-1)
    values = np.column_stack(
        [(real - reference) / np.maximum(reference, tiny), balance[part].sum(-1) / np.maximum(dissipated[part].sum(-1), tiny)]
    )
    statistic[part] = np.where((steps[part] * step_samples)[:, None] >= span_samples, values, 0.0)
    exceeded = (np.abs(statistic[part]) > thresholds).any(axis=1)
    above[part] = np.where(exceeded, above[part] + 1, 0)
    raised = ~alarm[part] & (above[part] >= persistence)
    detection_time[part] = np.where(raised, time[part], detection_time[part])
    alarm[part] |= raised
