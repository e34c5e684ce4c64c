"""Prognosis: the trend of the suspect's recent estimates, its End of Life, RUL and interval (paper 3.3).

The End of Life is where a polynomial fitted to the recent estimates (degree 1 by default) reaches a
safe limit; the interval comes from the fit's covariance (the times where the confidence band of the
trend reaches the limit). Only a suspect the isolation is confident of gets one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import norm

from ea_gym.models import SystemModel
from ea_gym.numerics import TINY
from ea_gym.phm.estimation import ParameterEstimates
from ea_gym.phm.history import push_window, rows_of


@dataclass(frozen=True)
class TrendFit:
    """The polynomial trend behind an End-of-Life prediction.

    Attributes:
        t: prediction time (s).
        times: the fitted estimates' time stamps (s), (M,); values: the estimates (parameter unit), (M,).
        coefficients: the polynomial in (time - t), highest power first.
        covariance: the coefficients' covariance, scaled by the residual variance and ``correlated``.
    """

    t: float
    times: np.ndarray
    values: np.ndarray
    coefficients: np.ndarray
    covariance: np.ndarray


@dataclass(frozen=True)
class EndOfLife:
    """One End-of-Life prediction.

    Attributes:
        t: prediction time (s).
        eol: predicted End of Life (s); inf when the trend never reaches a limit.
        eol_low, eol_high: its interval (s).
        limit: "lower", "upper" or None.
        fit: the trend it extrapolates.
    """

    t: float
    eol: float
    eol_low: float
    eol_high: float
    limit: str | None
    fit: TrendFit

    @property
    def rul(self) -> float:
        """Remaining useful life (s, eq 2)."""
        return self.eol - self.t


@dataclass(frozen=True)
class ExtrapolationConfig:
    """Settings of the trend extrapolation.

    Attributes:
        degree: polynomial degree (the paper uses 1).
        span: the fit uses the estimates of the last ``span`` seconds.
        min_points: fewer estimates than this give no prediction.
        confidence: two-sided confidence of the interval (normal quantile of the trend's uncertainty).
        horizon: predictions further than this ahead are reported as inf (s).
        correlated: how many consecutive estimates share data (overlapping windows, a running median):
            their errors are correlated, the fit has that many times fewer independent points, and its
            covariance is scaled up by as much.
    """

    degree: int = 1
    span: float = 30.0
    min_points: int = 5
    confidence: float = 0.95
    horizon: float = 2000.0
    correlated: int = 1


def _first_crossing(times: np.ndarray, curve: np.ndarray, level: float, below: bool) -> float:
    """First time at which ``curve`` reaches ``level`` from its side, linearly interpolated; inf if never."""
    beyond = curve <= level if below else curve >= level
    hits = np.flatnonzero(beyond)
    if len(hits) == 0:
        return math.inf
    i = hits[0]
    if i == 0:
        return float(times[0])
    t0, t1, c0, c1 = times[i - 1], times[i], curve[i - 1], curve[i]
    return float(t0 + (level - c0) * (t1 - t0) / (c1 - c0))


def fit_trend(times: np.ndarray, estimates: np.ndarray, t_now: float, config: ExtrapolationConfig = ExtrapolationConfig()) -> TrendFit | None:
    """The polynomial trend of the ``estimates`` (parameter unit) at ``times`` (s) of the last ``config.span``
    seconds; None when fewer than ``config.min_points`` fall in it."""
    recent = times >= t_now - config.span
    t, y = times[recent], estimates[recent]
    if len(t) < max(config.min_points, config.degree + 2):
        return None
    coefficients, covariance = np.polyfit(t - t_now, y, config.degree, cov="unscaled")
    residual = y - np.polyval(coefficients, t - t_now)
    dof = max(len(t) - config.degree - 1, 1)
    covariance = covariance * max(float(residual @ residual) / dof, TINY) * config.correlated
    return TrendFit(t=t_now, times=t, values=y, coefficients=coefficients, covariance=covariance)


def predict_end_of_life(
    times: np.ndarray,
    estimates: np.ndarray,
    limits: tuple[float, float],
    t_now: float,
    config: ExtrapolationConfig = ExtrapolationConfig(),
) -> EndOfLife | None:
    """Extrapolate the trend of ``estimates`` (parameter unit) at ``times`` (s) to the safe ``limits``.

    Returns None when fewer than ``config.min_points`` estimates fall in the fit span.
    """
    fit = fit_trend(times, estimates, t_now, config)
    return None if fit is None else extrapolate(fit, limits, config)


def extrapolate(fit: TrendFit, limits: tuple[float, float], config: ExtrapolationConfig = ExtrapolationConfig()) -> EndOfLife:
    """Where the trend and its confidence band reach the safe ``limits``: now if the newest estimate is past one."""
    t_now, coefficients, covariance = fit.t, fit.coefficients, fit.covariance
    lower, upper = limits
    if fit.values[-1] <= lower or fit.values[-1] >= upper:
        return EndOfLife(t_now, t_now, t_now, t_now, "lower" if fit.values[-1] <= lower else "upper", fit)
    z = norm.ppf(0.5 + config.confidence / 2)
    slope = np.polyval(np.polyder(coefficients), 0.0)
    limit: str | None
    limit, level, below = ("lower", lower, True) if slope < 0 else ("upper", upper, False)

    def crossing(side: float) -> float:
        """First time ahead (s) at which the trend + side x its band reaches the limit; inf if never."""
        def curve(ahead: np.ndarray) -> np.ndarray:
            powers = np.vander(ahead, config.degree + 1)
            return powers @ coefficients + side * z * np.sqrt(np.einsum("ti,ij,tj->t", powers, covariance, powers))

        # a coarse grid over the horizon, then a fine one over the interval where the curve first gets there
        coarse = np.linspace(0.0, config.horizon, 201)
        first = _first_crossing(coarse, curve(coarse), level, below)
        if math.isinf(first) or first == 0.0:
            return first
        i = int(np.searchsorted(coarse, first))
        fine = np.linspace(coarse[i - 1], coarse[i], 41)
        return _first_crossing(fine, curve(fine), level, below)

    eol = crossing(0.0)
    earliest, latest = crossing(-1.0 if below else 1.0), crossing(1.0 if below else -1.0)
    if math.isinf(eol):
        limit = None
    return EndOfLife(t_now, t_now + eol, t_now + earliest, t_now + latest, limit, fit)


@dataclass
class PrognosisState:
    """Per system (N) and degradable parameter (D): the estimates of the last ``history_length`` steps
    the estimator ran, NaN where it did not update that parameter, (N, D, H), and the times they describe (s)."""

    history: np.ndarray
    history_t: np.ndarray

    @classmethod
    def new(cls, n: int, parameters: int, length: int) -> PrognosisState:
        state = cls(history=np.empty((n, parameters, length)), history_t=np.empty((n, parameters, length)))
        state.reset()
        return state

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Start over for all systems, or for those where the boolean mask (N,) is true."""
        rows = rows_of(systems)
        self.history[rows] = np.nan
        self.history_t[rows] = np.nan


@dataclass(frozen=True)
class Prognosis:
    """One step's prognosis, N systems.

    Attributes:
        estimate: the confident suspect's estimate, NaN where none, (N,).
        eol, eol_low, eol_high: End of Life and interval (s), inf while no trend reaches a limit, (N,).
        end_of_life: each system's prediction with the fit it made, None where none.
    """

    estimate: np.ndarray
    eol: np.ndarray
    eol_low: np.ndarray
    eol_high: np.ndarray
    end_of_life: tuple[EndOfLife | None, ...]


class Prognostics:
    """The prognosis stage of N systems: each confident suspect's recent estimates extrapolated to its safe limits.

    Args:
        model: the monitored system (safe limits).
        degradable: the degradable parameters, in the estimator's order.
        config: extrapolation settings.
        history_length: estimates kept per parameter (steps).
        n_systems: N.
    """

    def __init__(self, model: SystemModel, degradable: tuple[str, ...], config: ExtrapolationConfig, history_length: int, n_systems: int):
        self.limits = [model.safe_limits[p] for p in degradable]
        self.config = config
        self.n = n_systems
        self.state = PrognosisState.new(n_systems, len(degradable), history_length)

    def record_adjustment(self, systems: np.ndarray, parameters: np.ndarray, changes: np.ndarray) -> None:
        """Shift the history of parameter ``parameters[k]`` of system ``systems[k]`` by ``changes[k]``, as if
        the change had always been there: the trend stays the wear's, now from the adjusted value."""
        self.state.history[systems, parameters] += np.asarray(changes, dtype=float)[:, None]

    def update(self, estimates: ParameterEstimates, isolated: np.ndarray, confident: np.ndarray, t: np.ndarray) -> Prognosis:
        """Record the step's estimates and predict the End of Life of every confident suspect (class index ``isolated``) at ``t`` (s)."""
        s = self.state
        if np.any(estimates.estimated):
            s.history = push_window(s.history, np.where(estimates.estimated, estimates.value, np.nan)[..., None])
            s.history_t = push_window(s.history_t, estimates.time[..., None])
        estimate = np.full(self.n, np.nan)
        eol = np.full((self.n, 3), math.inf)
        predictions: list[EndOfLife | None] = [None] * self.n
        rows = np.flatnonzero(confident)  # no End of Life for a suspect the isolation is unsure of
        estimate[rows] = estimates.value[rows, isolated[rows] - 1]
        for i in rows:
            d = isolated[i] - 1
            history = s.history[i, d]
            valid = np.isfinite(history)
            prediction = predict_end_of_life(s.history_t[i, d, valid], history[valid], self.limits[d], float(t[i]), self.config)
            if prediction is not None:
                eol[i] = (prediction.eol, prediction.eol_low, prediction.eol_high)
            predictions[i] = prediction
        return Prognosis(estimate=estimate, eol=eol[:, 0], eol_low=eol[:, 1], eol_high=eol[:, 2], end_of_life=tuple(predictions))
