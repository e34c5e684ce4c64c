"""The maintenance step's bookkeeping over N systems (``ea_gym.env.core.MaintenanceCore``) in compiled
loops: the orders, the failure check and the step's close, each in one pass where their numpy forms take a dozen small
array operations, with the same comparisons and additions in the same order, so to the bit.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.ledger``.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def take_orders(actions: np.ndarray, n_actions: int, down: np.ndarray, orders: np.ndarray) -> bool:
    """The step's orders of N systems into ``orders`` (N,): ``np.where(down > 0, 0, actions)`` (a machine that
    is down takes none); False, ``orders`` unfinished, where an action is outside [0, n_actions)."""
    for i in range(actions.shape[0]):
        if actions[i] < 0 or actions[i] >= n_actions:
            return False
        orders[i] = 0 if down[i] > 0 else actions[i]
    return True


@numba.njit(cache=True)
def outside_limits(theta: np.ndarray, columns: np.ndarray, low: np.ndarray, high: np.ndarray, running: np.ndarray, failed: np.ndarray) -> bool:
    """``failed`` (N,) = ``running & ((theta[:, columns] < low) | (theta[:, columns] > high)).any(axis=1)``
    (NaN is inside); returns whether any system failed."""
    any_failed = False
    for i in range(theta.shape[0]):
        outside = False
        if running[i]:
            for k in range(columns.shape[0]):
                value = theta[i, columns[k]]
                if value < low[k] or value > high[k]:
                    outside = True
        failed[i] = outside
        any_failed = any_failed or outside
    return any_failed


@numba.njit(cache=True)
def close_step(
    costs: np.ndarray, lost_production_row: int, lost_production: float, down: np.ndarray, since_maintenance: np.ndarray, steps: np.ndarray,
    maintained: np.ndarray, failed: np.ndarray, step_seconds: float, horizon: int, stop_at_failure: bool, terminated: np.ndarray,
    truncated: np.ndarray,
) -> None:
    """The end of a step for N systems, in place, as its numpy form:
    ``costs[lost_production_row] += np.where(down > 0, lost_production, 0.0)``; ``down = np.maximum(down - 1, 0)``;
    ``since_maintenance = np.where(maintained | failed, 0.0, since_maintenance + step_seconds)``; ``steps += 1``;
    ``terminated = failed & stop_at_failure``; ``truncated = (steps >= horizon) & ~terminated``; and the
    total in the last row of ``costs`` (items + 1, N): ``costs[:-1].sum(axis=0)``, item after item."""
    for i in range(costs.shape[1]):
        if down[i] > 0:
            costs[lost_production_row, i] += lost_production
        down[i] = max(down[i] - 1, 0)
        since_maintenance[i] = 0.0 if maintained[i] or failed[i] else since_maintenance[i] + step_seconds
        steps[i] += 1
        terminated[i] = failed[i] and stop_at_failure
        truncated[i] = steps[i] >= horizon and not terminated[i]
        total = costs[0, i]
        for item in range(1, costs.shape[0] - 1):
            total += costs[item, i]
        costs[costs.shape[0] - 1, i] = total
