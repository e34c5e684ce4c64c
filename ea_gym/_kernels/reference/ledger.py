"""The environment's step ledger (``ea_gym._kernels.ledger``): orders, failures and the step's close."""

from __future__ import annotations

import numpy as np


def take_orders(actions: np.ndarray, n_actions: int, down: np.ndarray, orders: np.ndarray) -> bool:
    """``orders[:] = np.where(down > 0, 0, actions)``; False, ``orders`` unfinished, where an action is
    outside [0, n_actions) (the kernel writes the orders before the first such action)."""
    bad = (actions < 0) | (actions >= n_actions)
    valid = int(np.argmax(bad)) if bad.any() else len(actions)
    orders[:valid] = np.where(down[:valid] > 0, 0, actions[:valid])
    return not bad.any()


def outside_limits(theta: np.ndarray, columns: np.ndarray, low: np.ndarray, high: np.ndarray, running: np.ndarray, failed: np.ndarray) -> bool:
    """``failed = running & ((theta[:, columns] < low) | (theta[:, columns] > high)).any(axis=1)`` (NaN is
    inside); whether any system failed."""
    values = theta[:, columns]
    failed[:] = running & ((values < low) | (values > high)).any(axis=1)
    return bool(failed.any())


def close_step(
    costs: np.ndarray, lost_production_row: int, lost_production: float, down: np.ndarray, since_maintenance: np.ndarray, steps: np.ndarray,
    maintained: np.ndarray, failed: np.ndarray, step_seconds: float, horizon: int, stop_at_failure: bool, terminated: np.ndarray,
    truncated: np.ndarray,
) -> None:
    """The end of a step for N systems, in place: lost production where down, one step less down, the
    time since maintenance, the step count, termination and truncation, and each system's total cost in
    the last row of ``costs`` (items + 1, N), item after item."""
    costs[lost_production_row] += np.where(down > 0, lost_production, 0.0)
    down[:] = np.maximum(down - 1, 0)
    since_maintenance[:] = np.where(maintained | failed, 0.0, since_maintenance + step_seconds)
    steps += 1
    terminated[:] = failed & stop_at_failure
    truncated[:] = (steps >= horizon) & ~terminated
    total = costs[0].copy()
    for item in range(1, costs.shape[0] - 1):
        total += costs[item]
    costs[-1] = total
