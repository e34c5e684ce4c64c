"""Fault profiles and degradation processes."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


class ProfileError(ValueError):
    """An invalid profile point; ``index`` is the culprit point's index (None for the whole profile)."""

    def __init__(self, index: int | None, reason: str) -> None:
        where = "profile" if index is None else f"profile point {index}"
        super().__init__(f"{where}: {reason}")
        self.index = index
        self.reason = reason

    def __reduce__(self):  # keep the two-argument constructor picklable (multiprocessing)
        return (type(self), (self.index, self.reason))


@dataclass(frozen=True)
class PiecewiseLinearProfile:
    """A parameter's value over time: piecewise linear between the points (``times`` in s,
    ``values`` in the parameter's SI unit), held constant before the first and after the last.

    ``times`` must be finite, >= 0 and strictly increasing; ``values`` finite and as many.
    """

    times: tuple[float, ...]
    values: tuple[float, ...]

    def __post_init__(self) -> None:
        times = tuple(float(t) for t in self.times)
        values = tuple(float(v) for v in self.values)
        if not times:
            raise ProfileError(None, "needs at least one point")
        if len(times) != len(values):
            raise ProfileError(None, f"{len(times)} times but {len(values)} values")
        for i, (t, v) in enumerate(zip(times, values)):
            if not math.isfinite(t):
                raise ProfileError(i, f"time {t!r} s is not finite")
            if t < 0:
                raise ProfileError(i, f"time {t!r} s is negative; times must be >= 0")
            if i > 0 and not t > times[i - 1]:
                raise ProfileError(
                    i,
                    f"time {t!r} s is not above the previous time {times[i - 1]!r} s; "
                    "times must be strictly increasing",
                )
            if not math.isfinite(v):
                raise ProfileError(i, f"value {v!r} is not finite")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "values", values)

    def value(self, t: np.ndarray) -> np.ndarray:
        """The profile at times t (s), elementwise over any shape of t."""
        return np.interp(np.asarray(t, dtype=float), self.times, self.values)

    def trend_end_of_life(self, t: np.ndarray, limits: tuple[float, float]) -> np.ndarray:
        """Ground-truth End of Life (s) seen from each time t (s): where the current trend meets a limit.

        The line through (t, value(t)) with the slope of the profile's segment containing t (0 before
        the first and from the last point on; at a breakpoint, the segment that starts there) is
        extended to the limit it heads for: the lower one if the slope is negative, the upper one if
        positive. This is what a perfect degree-1 extrapolation of the parameter predicts.

        Args:
            t: times (s), any shape.
            limits: (lower, upper) safe limits, in the parameter's unit, lower < upper.

        Returns:
            End of Life (s), shaped like t: inf where the slope is 0, t itself where value(t) is
            already at or beyond a limit.
        """
        lower, upper = (float(x) for x in limits)
        if not lower < upper:
            raise ValueError(f"limits must be (lower, upper) with lower < upper, got {limits!r}")
        t = np.asarray(t, dtype=float)
        times = np.asarray(self.times)
        values = np.asarray(self.values)
        slopes = np.append(np.diff(values) / np.diff(times), 0.0)  # segment starting at each point
        index = np.searchsorted(times, t, side="right") - 1  # last point at or before t (-1: before all)
        slope = np.where(index >= 0, slopes[np.clip(index, 0, None)], 0.0)
        value = self.value(t)
        with np.errstate(divide="ignore", invalid="ignore"):
            eol = np.where(
                slope < 0, t + (lower - value) / slope, np.where(slope > 0, t + (upper - value) / slope, np.inf)
            )
        outside = (value <= lower) | (value >= upper)
        return np.where(outside, t, eol)


WEAR_PROCESSES = ("linear", "gamma", "wiener")


@dataclass(frozen=True)
class WearConfig:
    """How one component degrades once its fault has arrived.

    Rates are fractions of the distance from the nominal value to the safe limit the wear heads for,
    per second, so that one setting fits every component.

    Attributes:
        process: "linear" (constant drift), "gamma" (monotone gamma-process jumps with that mean
            drift) or "wiener" (drift plus Brownian motion).
        direction: -1 toward the lower limit, +1 toward the upper, 0 drawn at random per fault.
        rate: (low, high) range the fault's mean drift rate is drawn from, 1/s.
        arrival: (low, high) range the fault's arrival time is drawn from, s after the (re)start;
            equal ends give a fixed onset (the paper's fault starts at 5 s).
        volatility: gamma and Wiener processes: std of the wear accumulated in 10 s relative to its mean.
    """

    process: str = "linear"
    direction: int = 0
    rate: tuple[float, float] = (0.005, 0.015)
    arrival: tuple[float, float] = (0.0, 150.0)
    volatility: float = 0.3

    def __post_init__(self) -> None:
        if self.process not in WEAR_PROCESSES:
            raise ValueError(f"wear process must be one of {WEAR_PROCESSES}, got {self.process!r}")
        if self.direction not in (-1, 0, 1):
            raise ValueError(f"wear direction must be -1, 0 or 1, got {self.direction!r}")
        for name in ("rate", "arrival"):
            low, high = getattr(self, name)
            if not (math.isfinite(low) and math.isfinite(high) and 0 <= low <= high):
                raise ValueError(f"wear {name} must be a range (low, high) with 0 <= low <= high, got {(low, high)!r}")
        if not (math.isfinite(self.volatility) and self.volatility >= 0):
            raise ValueError(f"wear volatility must be >= 0, got {self.volatility!r}")

    def random_walk_std(self, nominal: float, limits: tuple[float, float]) -> float:
        """Std of the wear's random part per sqrt(s), in the parameter's unit, of a component at ``nominal``
        with safe ``limits``: 0 for linear wear; for gamma and Wiener wear (``Wear.advance``) the increments'
        variance is (volatility |v| 10 s)^2 / 10 s per s, v the fault's mean drift, taken here as its root
        mean square over the rates and directions a fault may draw."""
        if self.process == "linear":
            return 0.0
        low, high = self.rate
        distances = [limits[1] - nominal, nominal - limits[0]]
        chosen = distances if self.direction == 0 else [distances[0] if self.direction > 0 else distances[1]]
        mean_square_drift = (low * low + low * high + high * high) / 3.0 * sum(d * d for d in chosen) / len(chosen)
        return self.volatility * math.sqrt(10.0 * mean_square_drift)


class Wear:
    """Degradation of the components of N systems, one fault at a time per system.

    At every (re)start a system draws which of the wearing components will fail, when its fault
    arrives, its direction and mean rate; from the arrival on the parameter drifts by the process's
    increments. System i draws only from its own generator ``rngs[i]``, so a system's wear does not
    depend on how many others are stepped with it.

    Args:
        nominal: nominal values of the wearing components, (D,).
        limits: their (lower, upper) safe limits, (D, 2).
        configs: one WearConfig per wearing component.
        n_systems: N.
        columns: where the wearing components sit in the rows of values that ``advance`` and ``true_rul`` are
            given (a system's whole parameter vector, say), (D,); None: columns 0..D-1.
    """

    def __init__(
        self, nominal: np.ndarray, limits: np.ndarray, configs: list[WearConfig], n_systems: int, columns: np.ndarray | None = None
    ):
        self.nominal = np.asarray(nominal, dtype=float)
        self.limits = np.asarray(limits, dtype=float)
        self.configs = list(configs)
        self.columns = np.arange(len(self.nominal)) if columns is None else np.asarray(columns, dtype=np.intp)
        self._linear = np.array([config.process == "linear" for config in self.configs], dtype=bool)
        self.faulty = np.zeros(n_systems, dtype=int)
        self.arrival = np.full(n_systems, np.inf)
        self.velocity = np.zeros(n_systems)  # mean drift of the faulty component, parameter unit per s

    def start(self, rngs: Sequence[np.random.Generator], clock: np.ndarray, systems: np.ndarray) -> None:
        """Draw a new fault for the systems in the boolean mask, arriving after their ``clock`` (s)."""
        for i in np.flatnonzero(systems).tolist():
            rng = rngs[i]
            d = int(rng.integers(len(self.configs)))
            config = self.configs[d]
            direction = config.direction or (1 if rng.random() < 0.5 else -1)
            limit = self.limits[d, 1] if direction > 0 else self.limits[d, 0]
            self.faulty[i] = d
            self.arrival[i] = clock[i] + rng.uniform(*config.arrival)
            self.velocity[i] = rng.uniform(*config.rate) * (limit - self.nominal[d])

    def advance(
        self, values: np.ndarray, clock: np.ndarray, dt: float, rngs: Sequence[np.random.Generator], running: np.ndarray | None = None
    ) -> None:
        """Wear the faulty components over [clock, clock + dt], in place: ``values`` (N, ...) in parameter units,
        component d in column ``columns[d]``. Only the ``running`` systems (N,) bool (None: all) wear; the
        others draw their random increments all the same, so that their generators stay in step."""
        from ea_gym._kernels.wear import steady_wear  # compiled: numba is imported when the first system wears

        n = len(values)
        running = np.ones(n, dtype=bool) if running is None else running
        active = np.empty(n)
        # linear wear (or none) draws nothing: compiled; the random processes draw row by row
        clock = np.asarray(clock, dtype=float)
        drawn = steady_wear(values, self.columns, running, self.faulty, self.arrival, self.velocity, clock, float(dt), self._linear, active)
        for i in drawn.tolist():
            rng = rngs[i]
            d = self.faulty[i]
            config, mean = self.configs[d], self.velocity[i] * active[i]
            if config.process == "gamma":
                # shape and scale from mean m and variance (v m)^2 (active / 10 s): the std over 10 s is v times the mean
                variance = (config.volatility * abs(self.velocity[i]) * 10.0) ** 2 * active[i] / 10.0
                scale = variance / abs(mean)
                increment = np.sign(mean) * rng.gamma(abs(mean) / scale, scale) if scale > 0 else mean
            else:
                sigma = config.volatility * abs(self.velocity[i]) * 10.0 / math.sqrt(10.0)
                increment = mean + sigma * math.sqrt(active[i]) * rng.standard_normal()
            if running[i]:
                values[i, self.columns[d]] += increment

    def true_rul(self, values: np.ndarray, clock: np.ndarray) -> np.ndarray:
        """Time (s) until the faulty component's mean trend reaches its limit; inf before the fault arrives.
        ``values`` (N, ...) as for ``advance``."""
        from ea_gym._kernels.wear import mean_trend_rul

        rul = np.empty(len(values))
        mean_trend_rul(values, self.columns, self.faulty, self.limits, self.velocity, self.arrival, np.asarray(clock, dtype=float), rul)
        return rul
