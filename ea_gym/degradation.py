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


def random_increment(config: WearConfig, velocity: float, seconds: float, rng: np.random.Generator) -> float:
    """A gamma or Wiener process's wear over ``seconds`` (s) of a fault whose mean drift is ``velocity`` (parameter
    unit per s), drawn from ``rng``: its mean is velocity x seconds, its std over 10 s ``config.volatility`` times
    the mean's (``WearConfig.random_walk_std``)."""
    mean = velocity * seconds
    if config.process == "gamma":
        # shape and scale from mean m and variance (v m)^2 (seconds / 10 s): the std over 10 s is v times the mean
        variance = (config.volatility * abs(velocity) * 10.0) ** 2 * seconds / 10.0
        scale = variance / abs(mean)
        return np.sign(mean) * rng.gamma(abs(mean) / scale, scale) if scale > 0 else mean
    sigma = config.volatility * abs(velocity) * 10.0 / math.sqrt(10.0)
    return mean + sigma * math.sqrt(seconds) * rng.standard_normal()


class WearProcesses:
    """M wear processes, each wearing one part of one system from its arrival on: what the single-fault world
    (``Wear``, one process per system) and the world where every part ages (``PartsWear``, one per system and
    part) share: a process's draw (direction, arrival, rate) and its increments over a step.

    Args:
        nominal: nominal values of the wearing parts, (D,).
        limits: their (lower, upper) safe limits, (D, 2).
        configs: one WearConfig per wearing part.
        systems: the system each process wears, (M,); system i draws only from its own generator ``rngs[i]``.
        columns: where the wearing parts sit in the rows of values that ``advance`` is given (a system's whole
            parameter vector, say), (D,); None: columns 0..D-1.
    """

    def __init__(self, nominal: np.ndarray, limits: np.ndarray, configs: list[WearConfig], systems: np.ndarray, columns: np.ndarray | None = None):
        self.nominal = np.asarray(nominal, dtype=float)
        self.limits = np.asarray(limits, dtype=float)
        self.configs = list(configs)
        self.columns = np.arange(len(self.nominal)) if columns is None else np.asarray(columns, dtype=np.intp)
        self._linear = np.array([config.process == "linear" for config in self.configs], dtype=bool)
        self.systems = np.asarray(systems, dtype=np.intp)
        m = len(self.systems)
        self.parts = np.zeros(m, dtype=int)  # the part each process wears
        self.arrival = np.full(m, np.inf)
        self.velocity = np.zeros(m)  # mean drift of each process, parameter unit per s

    def draw(self, rng: np.random.Generator, m: int, d: int, clock: float) -> int:
        """Process m wears part d from a fault drawn from ``rng`` (direction, then arrival after ``clock`` (s), then
        rate); returns its direction (-1 or +1)."""
        config = self.configs[d]
        direction = config.direction or (1 if rng.random() < 0.5 else -1)
        limit = self.limits[d, 1] if direction > 0 else self.limits[d, 0]
        self.parts[m] = d
        self.arrival[m] = clock + rng.uniform(*config.arrival)
        self.velocity[m] = rng.uniform(*config.rate) * (limit - self.nominal[d])
        return direction

    def advance(
        self, values: np.ndarray, clock: np.ndarray, dt: float, rngs: Sequence[np.random.Generator], running: np.ndarray | None = None
    ) -> None:
        """Wear the parts over [clock, clock + dt], in place: ``values`` (N, ...) in parameter units, part d in
        column ``columns[d]``, ``clock`` (N,) s. Only the ``running`` systems (N,) bool (None: all) wear; the
        others draw their random increments all the same, so that their generators stay in step."""
        from ea_gym._kernels.wear import steady_wear  # compiled: numba is imported when the first system wears

        n = len(values)
        running = np.ones(n, dtype=bool) if running is None else running
        active = np.empty(len(self.systems))
        # linear wear (or none) draws nothing: compiled; the random processes draw one by one
        clock = np.asarray(clock, dtype=float)
        drawn = steady_wear(
            values, self.systems, self.columns, running, self.parts, self.arrival, self.velocity, clock, float(dt), self._linear, active
        )
        for m in drawn.tolist():
            i, d = self.systems[m], self.parts[m]
            increment = random_increment(self.configs[d], self.velocity[m], active[m], rngs[i])
            if running[i]:
                values[i, self.columns[d]] += increment

    def mean_trend_rul(self, values: np.ndarray, clock: np.ndarray, velocity: np.ndarray, since: np.ndarray) -> np.ndarray:
        """Time (s) until each process's part, moving at ``velocity`` (M,) from its value in ``values`` (N, ...),
        reaches the limit it heads for: 0 past it, inf without drift and before ``since`` (M,) (s, on the
        systems' ``clock`` (N,))."""
        from ea_gym._kernels.wear import mean_trend_rul

        rul = np.empty(len(self.systems))
        mean_trend_rul(values, self.systems, self.columns, self.parts, self.limits, velocity, since, np.asarray(clock, dtype=float), rul)
        return rul


class Wear(WearProcesses):
    """Degradation of the components of N systems, one fault at a time per system (the v0 environments' world).

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

    Attributes:
        faulty: each system's faulty component, (N,); arrival: its fault's arrival (s); velocity: its mean drift
            (parameter unit per s).
    """

    def __init__(
        self, nominal: np.ndarray, limits: np.ndarray, configs: list[WearConfig], n_systems: int, columns: np.ndarray | None = None
    ):
        super().__init__(nominal, limits, configs, np.arange(n_systems), columns)

    @property
    def faulty(self) -> np.ndarray:
        """Each system's faulty component (its one process's part), (N,)."""
        return self.parts

    def start(self, rngs: Sequence[np.random.Generator], clock: np.ndarray, systems: np.ndarray) -> None:
        """Draw a new fault for the systems in the boolean mask, arriving after their ``clock`` (s)."""
        for i in np.flatnonzero(systems).tolist():
            rng = rngs[i]
            self.draw(rng, i, int(rng.integers(len(self.configs))), clock[i])

    def true_rul(self, values: np.ndarray, clock: np.ndarray) -> np.ndarray:
        """Time (s) until the faulty component's mean trend reaches its limit; inf before the fault arrives.
        ``values`` (N, ...) as for ``advance``."""
        return self.mean_trend_rul(values, clock, self.velocity, self.arrival)


#: the default background ageing (``PartsWear``), fraction of the distance from nominal to the limit per second
BACKGROUND_WEAR = 2e-4


class PartsWear(WearProcesses):
    """Every part of N systems ageing at once (the v1 environments' world): each part of each system has its
    own wear process and a slow background ageing, and starts from its own value within a tolerance.

    Installing part d in system i (at a (re)start, for every part, or when it is replaced) draws from the
    system's generator, in this order: its starting value, uniform within nominal +- ``tolerance`` x its safe
    span; then its fault as ``Wear``'s (direction, arrival after the clock, mean rate, from ``configs[d]``).
    A (re)start installs a system's parts in their order, so a system's draws do not depend on N.

    Each part ages in its fault's direction from the moment it is installed: a linear background drift of
    ``background`` x the distance from nominal to the limit it heads for, per second, and from the fault's
    arrival on the fault's process on top. Its mean trend is the sum of the two velocities (the background
    alone before the fault arrives); its true RUL is the time that trend takes to its limit from the part's
    value now (inf where neither drifts).

    Args:
        nominal: nominal values of the wearing parts, (D,).
        limits: their (lower, upper) safe limits, (D, 2).
        configs: one WearConfig per wearing part.
        n_systems: N.
        columns: where the parts sit in the rows of values (a system's whole parameter vector), (D,); None: 0..D-1.
        tolerance: half-width of the starting values' spread, fraction of each part's safe span (>= 0).
        background: background ageing, fraction of the distance from nominal to the limit per second (>= 0).

    Attributes:
        installed: when each part was installed (s, on its system's clock), (N, D); process i D + d wears
            part d of system i (``arrival``, ``velocity`` of the fault, ``background`` velocity (M,)).
    """

    def __init__(
        self, nominal: np.ndarray, limits: np.ndarray, configs: list[WearConfig], n_systems: int, columns: np.ndarray | None = None,
        tolerance: float = 0.0, background: float = 0.0,
    ):
        d = len(configs)
        super().__init__(nominal, limits, configs, np.repeat(np.arange(n_systems), d), columns)
        for name, value in (("tolerance", tolerance), ("background", background)):
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
        self.n, self.d = n_systems, d
        self.parts[:] = np.tile(np.arange(d), n_systems)
        self.tolerance, self.background_rate = float(tolerance), float(background)
        self.span = self.limits[:, 1] - self.limits[:, 0]
        self.background = np.zeros(len(self.systems))  # background velocity of each process's part, unit per s
        self.installed = np.zeros((n_systems, d))

    def install(
        self, rngs: Sequence[np.random.Generator], clock: np.ndarray, systems: np.ndarray, parts: np.ndarray, values: np.ndarray
    ) -> None:
        """Install a new part ``parts[k]`` in system ``systems[k]`` (pairs in the order given): its value in
        ``values`` (N, ...) drawn within tolerance, its wear process drawn, from the system's ``clock`` (s) on."""
        for i, d in zip(np.asarray(systems).tolist(), np.asarray(parts).tolist()):
            rng = rngs[i]
            values[i, self.columns[d]] = self.nominal[d] + rng.uniform(-self.tolerance, self.tolerance) * self.span[d]
            m = i * self.d + d
            direction = self.draw(rng, m, d, clock[i])
            limit = self.limits[d, 1] if direction > 0 else self.limits[d, 0]
            self.background[m] = self.background_rate * (limit - self.nominal[d])
            self.installed[i, d] = clock[i]

    def start(self, rngs: Sequence[np.random.Generator], clock: np.ndarray, systems: np.ndarray, values: np.ndarray) -> None:
        """New parts throughout the systems in the boolean mask ``systems`` (N,), in each system's part order."""
        rows = np.flatnonzero(systems)
        self.install(rngs, clock, np.repeat(rows, self.d), np.tile(np.arange(self.d), len(rows)), values)

    def advance(
        self, values: np.ndarray, clock: np.ndarray, dt: float, rngs: Sequence[np.random.Generator], running: np.ndarray | None = None
    ) -> None:
        """Age the parts over [clock, clock + dt], in place: the background drift of the ``running`` systems, then
        the faults' processes (``WearProcesses.advance``)."""
        running = np.ones(len(values), dtype=bool) if running is None else running
        aged = self.background.reshape(self.n, self.d) * dt
        values[:, self.columns] += np.where(running[:, None], aged, 0.0)
        super().advance(values, clock, dt, rngs, running)

    def arrived(self, clock: np.ndarray) -> np.ndarray:
        """Whether each part's fault has arrived at the systems' ``clock`` (N,), (N, D)."""
        return (np.asarray(clock)[self.systems] >= self.arrival).reshape(self.n, self.d)

    def true_rul(self, values: np.ndarray, clock: np.ndarray) -> np.ndarray:
        """Time (s) until each part's mean trend (background, plus the fault once arrived) reaches its limit, (N, D)."""
        clock = np.asarray(clock, dtype=float)
        velocity = self.background + np.where(clock[self.systems] >= self.arrival, self.velocity, 0.0)
        return self.mean_trend_rul(values, clock, velocity, self.installed.reshape(-1)).reshape(self.n, self.d)
