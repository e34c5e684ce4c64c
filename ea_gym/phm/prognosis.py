"""Prognosis: the suspect's End of Life, RUL and interval, from its estimates (paper 3.3).

Two stages behind one seam (:class:`PrognosisStage`), chosen with the estimator:

* :class:`TrendPrognosis` (the paper's, for estimators without a drift: the EA inversion): the End of
  Life is where a polynomial fitted to the recent estimates (degree 1 by default) reaches a safe
  limit; the interval comes from the fit's covariance (the times where the confidence band of the
  trend reaches the limit).
* :class:`DriftPrognosis` (for estimators that track the parameter's drift with its covariance: the
  tracking filter): the parameter and its drift carried to the safe limit (:func:`drift_end_of_life`).

Only a suspect the isolation is confident of gets one.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache, cached_property
from typing import Protocol, overload

import numpy as np

from ea_gym._kernels.prognosis import drift_ends, drift_prognosis
from ea_gym.models import SystemModel
from ea_gym.numerics import TINY
from ea_gym.phm.config import ExtrapolationConfig
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
    """One End-of-Life prediction, from a polynomial trend or from a tracked drift.

    Attributes:
        t: prediction time (s).
        eol: predicted End of Life (s); inf when the parameter is not heading for a limit.
        eol_low, eol_high: its interval (s).
        limit: "lower", "upper" or None.
        value: the parameter at ``t`` it starts from (its unit): the trend's value there, or the filter's estimate.
        drift: its rate of change at ``t`` (unit/s); drift_std: that rate's standard deviation.
        fit: the polynomial trend it extrapolates; None when it carries a tracked drift.
    """

    t: float
    eol: float
    eol_low: float
    eol_high: float
    limit: str | None
    value: float
    drift: float
    drift_std: float
    fit: TrendFit | None

    def path(self, times: np.ndarray) -> np.ndarray:
        """The parameter it predicts at ``times`` (s): the trend, or the straight line of the drift."""
        ahead = np.asarray(times, dtype=float) - self.t
        if self.fit is not None:
            return np.polyval(self.fit.coefficients, ahead)
        return self.value + self.drift * ahead

    @property
    def rul(self) -> float:
        """Remaining useful life (s, eq 2)."""
        return self.eol - self.t


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
    slope = float(np.polyval(np.polyder(coefficients), 0.0))
    # the slope at t_now is the coefficient of the linear term: its variance is that coefficient's
    slope_std = math.sqrt(covariance[-2, -2]) if len(coefficients) > 1 else 0.0
    value = float(coefficients[-1])
    if fit.values[-1] <= lower or fit.values[-1] >= upper:
        past = "lower" if fit.values[-1] <= lower else "upper"
        return EndOfLife(t_now, t_now, t_now, t_now, past, value, slope, slope_std, fit)
    from scipy.special import ndtri  # imported when first needed: scipy.special takes a few tenths of a second

    z = ndtri(0.5 + config.confidence / 2)
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
    return EndOfLife(t_now, t_now + eol, t_now + earliest, t_now + latest, limit, value, slope, slope_std, fit)


def drift_end_of_life(
    value: np.ndarray, drift: np.ndarray, covariance: np.ndarray, limits: np.ndarray, t: np.ndarray, confidence: float = 0.95,
    diffusion: np.ndarray | float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """End of Life where theta + drift (s - t) reaches the safe limit it heads for, with its interval.

    theta and drift are jointly Gaussian (``covariance``) and theta goes on diffusing (a random walk of
    ``diffusion`` unit^2/s), so at a horizon tau the parameter is N(theta + drift tau, var_theta +
    tau (2 cov + diffusion) + tau^2 var_drift), and P(limit crossed by tau) is a normal CDF. The
    interval's ends are the horizons where that probability is (1 -+ confidence) / 2: the roots of a
    quadratic in tau, bounded above only when the drift is resolved (|drift| / its std
    above the confidence's z, about 2).

    Args:
        value, drift: (...,) the parameter (its unit) and its drift (unit/s).
        covariance: (..., 2, 2) of (theta, drift).
        limits: (..., 2) the (lower, upper) safe limits.
        t: (...,) the time the values describe (s).
        diffusion: (...,) or a number: variance per second of theta's random walk from now on (unit^2/s).

    Returns:
        eol, eol_low, eol_high (s), each (...,); inf where the limit is not approached (or not surely).
    """
    covariance = np.asarray(covariance, dtype=float)
    limits = np.asarray(limits, dtype=float)
    inputs = np.broadcast_arrays(
        value, drift, covariance[..., 0, 0], covariance[..., 0, 1], covariance[..., 1, 1], limits[..., 0], limits[..., 1], t, diffusion
    )
    shape = inputs[0].shape
    # copies: numba warns on broadcast_arrays' views
    value, drift, v_tt, v_td, v_dd, lower, upper, stamps, walk = (np.array(x, dtype=float).reshape(-1) for x in inputs)
    ends = np.empty((len(value), 3))
    # (rate tau - margin)^2 = z^2 (v_tt + 2 tau v_td + tau^2 v_dd), the diffusion folded into v_td: compiled, element by element
    drift_ends(value, drift, v_tt, v_td, v_dd, lower, upper, stamps, walk, normal_quantile(0.5 + 0.5 * confidence) ** 2, ends)
    return ends[:, 0].reshape(shape), ends[:, 1].reshape(shape), ends[:, 2].reshape(shape)


@cache
def normal_quantile(p: float) -> float:
    """The standard normal distribution's ``p`` quantile."""
    from scipy.special import ndtri  # imported when first needed: scipy.special takes a few tenths of a second

    return float(ndtri(p))


@dataclass(frozen=True)
class Prognosis:
    """One step's prognosis, N systems.

    Attributes:
        estimate: the confident suspect's estimate, NaN where none, (N,).
        eol, eol_low, eol_high: End of Life and interval (s), inf where none is predicted, (N,).
        end_of_life: each system's prediction, None where none.
    """

    estimate: np.ndarray
    eol: np.ndarray
    eol_low: np.ndarray
    eol_high: np.ndarray
    end_of_life: Sequence[EndOfLife | None]


class PrognosisStage(Protocol):
    """The prognosis of N systems: each confident suspect's End of Life from the estimator's output."""

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Start over for all systems (None), or for those where the boolean mask (N,) is true."""

    def record_adjustment(self, systems: np.ndarray, parameters: np.ndarray, changes: np.ndarray) -> None:
        """Maintenance moved parameter ``parameters[k]`` of system ``systems[k]`` by ``changes[k]`` (its SI unit)."""

    def update(self, estimates: ParameterEstimates, isolated: np.ndarray, confident: np.ndarray, t: np.ndarray) -> Prognosis:
        """Predict the End of Life of every confident suspect (class index ``isolated``, (N,)) at ``t`` (s, (N,))."""


def _no_prognosis(n: int) -> tuple[np.ndarray, np.ndarray, list[EndOfLife | None]]:
    """Empty per-step outputs: estimates NaN (N,), End of Life inf (N, 3), no predictions."""
    return np.full(n, np.nan), np.full((n, 3), math.inf), [None] * n


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


class TrendPrognosis:
    """Each confident suspect's recent estimates extrapolated to its safe limits (the paper's prognosis).

    Args:
        model: the monitored system (safe limits).
        degradable: the degradable parameters, in the estimator's order.
        config: extrapolation settings (``correlated``: the estimator's, how many successive estimates share data).
        history_length: estimates kept per parameter (steps).
        n_systems: N.
    """

    def __init__(self, model: SystemModel, degradable: tuple[str, ...], config: ExtrapolationConfig, history_length: int, n_systems: int):
        self.limits = [model.safe_limits[p] for p in degradable]
        self.config = config
        self.n = n_systems
        self.state = PrognosisState.new(n_systems, len(degradable), history_length)

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Start over for all systems (None), or for those where the boolean mask (N,) is true."""
        self.state.reset(systems)

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
        estimate, eol, predictions = _no_prognosis(self.n)
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


class DriftPrognosis:
    """Each confident suspect's tracked value and drift, with their covariance, carried to its safe limits.

    Needs an estimator that gives the drift and the (value, drift) covariance (``ParameterEstimates``);
    the record's ``time`` says when the values hold. The filter's state holds what the trend's history
    would: nothing of its own to keep, and a logged adjustment has already moved the estimate.

    Args:
        model: the monitored system (safe limits).
        degradable: the degradable parameters, in the estimator's order.
        config: extrapolation settings (``confidence`` of the interval; End-of-Life points beyond
            ``horizon`` are reported as inf).
        diffusion: each parameter's random walk from now on, as the estimator models it (unit^2/s), (D,).
        n_systems: N.
    """

    def __init__(self, model: SystemModel, degradable: tuple[str, ...], config: ExtrapolationConfig, diffusion: np.ndarray, n_systems: int):
        self.limits = np.array([model.safe_limits[p] for p in degradable], dtype=float)
        self._lower, self._upper = self.limits[:, 0].copy(), self.limits[:, 1].copy()
        self.config = config
        self.diffusion = np.asarray(diffusion, dtype=float)
        self.n = n_systems

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Nothing to forget: the estimator's filters hold the state."""

    def record_adjustment(self, systems: np.ndarray, parameters: np.ndarray, changes: np.ndarray) -> None:
        """Nothing to shift: the estimator moves its estimate by the logged change."""

    def update(self, estimates: ParameterEstimates, isolated: np.ndarray, confident: np.ndarray, t: np.ndarray) -> Prognosis:
        """The End of Life of every confident suspect (class index ``isolated``) from its value and drift at ``t`` (s);
        none for a suspect the isolation is unsure of, nor beyond the horizon (as far ahead as the trend route looks)."""
        out = np.empty((7, self.n))
        drift_prognosis(
            estimates.value, estimates.drift, estimates.variance, estimates.covariance, estimates.drift_variance, estimates.time,
            np.asarray(isolated), np.asarray(confident), self._lower, self._upper, self.diffusion, np.asarray(t, dtype=float),
            self._squared_quantile, self.config.horizon, out,
        )
        estimate, eol, eol_low, eol_high, drift, drift_variance, stamps = out  # stamps: a copy of t, which moves on
        predictions = DriftEndsOfLife(np.array(confident, dtype=bool), stamps, eol, eol_low, eol_high, estimate, drift, drift_variance)
        return Prognosis(estimate=estimate, eol=eol, eol_low=eol_low, eol_high=eol_high, end_of_life=predictions)

    def every_part(self, estimates: ParameterEstimates, named: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The End of Life and its interval (s) of every ``named`` part (N, D) at once, each from its own value and
        drift (``drift_end_of_life``), inf where a part is not named or its end lies beyond the horizon after
        the time its value describes; (N, D) each."""
        covariance = np.empty(estimates.value.shape + (2, 2))
        covariance[..., 0, 0], covariance[..., 1, 1] = estimates.variance, estimates.drift_variance
        covariance[..., 0, 1] = covariance[..., 1, 0] = estimates.covariance
        ends = drift_end_of_life(
            estimates.value, estimates.drift, covariance, self.limits, estimates.time, self.config.confidence, self.diffusion
        )
        eol, low, high = (np.where(named & (end - estimates.time <= self.config.horizon), end, math.inf) for end in ends)
        return eol, low, high

    @cached_property
    def _squared_quantile(self) -> float:
        """The square of the interval's confidence's normal quantile (found when first needed: scipy.special loads slowly)."""
        return normal_quantile(0.5 + 0.5 * self.config.confidence) ** 2


class DriftEndsOfLife(Sequence["EndOfLife | None"]):
    """Each of N systems' ``DriftPrognosis`` prediction, None where none, made when read (most steps nobody does).

    Args:
        made: which systems have a prediction, (N,); t: the prediction time (s), (N,); eol, eol_low, eol_high: End of
            Life and interval (s), (N,) each; value: the estimate it starts from; drift and drift_variance: the
            drift and its variance, (N,) each.
    """

    def __init__(
        self, made: np.ndarray, t: np.ndarray, eol: np.ndarray, eol_low: np.ndarray, eol_high: np.ndarray, value: np.ndarray, drift: np.ndarray,
        drift_variance: np.ndarray,
    ):
        self._made, self._t, self._ends = made, t, (eol, eol_low, eol_high)
        self._value, self._drift, self._drift_variance = value, drift, drift_variance

    def __len__(self) -> int:
        return len(self._t)

    @overload
    def __getitem__(self, i: int) -> EndOfLife | None: ...

    @overload
    def __getitem__(self, i: slice) -> tuple[EndOfLife | None, ...]: ...

    def __getitem__(self, i: int | slice) -> EndOfLife | None | tuple[EndOfLife | None, ...]:
        if isinstance(i, slice):
            return tuple(self[j] for j in range(*i.indices(len(self))))
        j = operator.index(i)
        if not -len(self) <= j < len(self):
            raise IndexError(f"system {j} out of range for {len(self)} systems")
        if not self._made[j]:
            return None
        eol, low, high = (float(end[j]) for end in self._ends)
        drift = float(self._drift[j])
        limit = ("lower" if drift < 0 else "upper") if math.isfinite(eol) else None
        return EndOfLife(
            float(self._t[j]), eol, low, high, limit, float(self._value[j]), drift,
            math.sqrt(max(float(self._drift_variance[j]), 0.0)), None,
        )
