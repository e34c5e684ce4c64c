"""The linear-drift End of Life and its interval (``ea_gym._kernels.prognosis``), as numpy expressions
over whole arrays, to the bit."""

from __future__ import annotations

import numpy as np


def drift_ends(
    value: np.ndarray, drift: np.ndarray, v_tt: np.ndarray, v_td: np.ndarray, v_dd: np.ndarray, lower: np.ndarray,
    upper: np.ndarray, t: np.ndarray, diffusion: np.ndarray, z2: float, out: np.ndarray,
) -> None:
    """End of Life, its low and high end (s) into ``out`` (M, 3): when theta + drift tau reaches the limit it
    heads for, and the roots of (margin - rate tau)^2 = z2 Var(margin - rate tau), theta's random walk
    ``diffusion`` adding to the covariance."""
    upward = drift >= 0
    limit = np.where(upward, upper, lower)
    sign = np.where(upward, 1.0, -1.0)
    margin = sign * (limit - value)
    rate = sign * drift
    cross = v_td + 0.5 * diffusion
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = np.where(margin <= 0, 0.0, np.where(rate > 0, margin / rate, np.inf))
        a = rate * rate - z2 * v_dd
        b = -2.0 * rate * margin - 2.0 * z2 * cross
        c = margin * margin - z2 * v_tt
        root = np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))
        linear = -c / b
        r1, r2 = (-b - root) / (2.0 * a), (-b + root) / (2.0 * a)
        small, large = np.minimum(r1, r2), np.maximum(r1, r2)
        low = np.where(a > 0, small, np.where(a < 0, large, linear))
        low = np.where(c <= 0, 0.0, np.maximum(low, 0.0))
        high = np.where(a > 0, np.maximum(large, 0.0), np.inf)
        high = np.where((margin < 0) & (c > 0), 0.0, high)
    out[:] = np.stack([t + tau, t + low, t + high], axis=1)


def drift_prognosis(
    value: np.ndarray, drift: np.ndarray, variance: np.ndarray, covariance: np.ndarray, drift_variance: np.ndarray, stamps: np.ndarray,
    isolated: np.ndarray, confident: np.ndarray, lower: np.ndarray, upper: np.ndarray, diffusion: np.ndarray, t: np.ndarray, z2: float,
    horizon: float, out: np.ndarray,
) -> None:
    """For every ``confident`` system its suspect d = isolated - 1's ``drift_ends``, an end more than
    ``horizon`` s after ``t`` inf; into out (7, N): the suspect's estimate, the three ends, its drift and
    drift variance (NaN, the ends inf, where not confident), then ``t``."""
    rows = np.flatnonzero(confident)
    d = isolated[rows] - 1
    ends = np.empty((len(rows), 3))
    drift_ends(
        value[rows, d], drift[rows, d], variance[rows, d], covariance[rows, d], drift_variance[rows, d], lower[d], upper[d], stamps[rows, d],
        diffusion[d], z2, ends,
    )
    out[:6] = np.nan
    out[1:4] = np.inf
    out[1:4, rows] = np.where(ends - t[rows, None] > horizon, np.inf, ends).T
    out[0, rows], out[4, rows], out[5, rows] = value[rows, d], drift[rows, d], drift_variance[rows, d]
    out[6] = t
