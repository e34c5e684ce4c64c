"""Element power (Table 1), Energy Activity (eq 4/7) and Energy Activity Index (eq 5).

Energy Activity integrates the absolute power of an element, EA = int |e f| dt (J), with the
trapezoidal rule over the samples. Windows are consecutive, aligned on samples, and share their
boundary sample. Every function takes arrays with any leading axes (systems, elements) and the
time axis last, or a mapping from element name to such arrays.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Literal, TypeVar, overload

import numpy as np

from ea_gym._kernels.activity import component_shares, interval_activities, summed_shares
from ea_gym.bondgraph.elements import CForm, Kind

Signals = TypeVar("Signals", np.ndarray, Mapping[str, np.ndarray])


def constitutive_power(
    kind: Kind | str,
    signal: Literal["effort", "flow"],
    S: np.ndarray,
    value: float | np.ndarray,
    sample_period: float,
    *,
    c_form: CForm | str = CForm.CAPACITANCE,
    integral: np.ndarray | None = None,
) -> np.ndarray:
    """Power absorbed by an R, C or I element from its input signal alone (the paper's Table 1, eq 6).

    Args:
        kind: "R", "C" or "I".
        signal: which power variable ``S`` is (the element's input in its causality).
        S: the input signal over time (effort in N, V, ...; flow in m/s, A, ...), time on the last axis.
        value: the component value phi (R: resistance; C: stiffness or capacitance per ``c_form``;
            I: inertance).
        sample_period: seconds between samples; used to integrate or differentiate ``S``.
        c_form: how a C element's value enters its law.
        integral: in integral causality, the energy variable (q of a C, p of an I) when it is known
            (measured or simulated); otherwise ``S`` is integrated from zero with the trapezoidal rule.

    Returns:
        P(t) = S(t) * phi * g(S(t)) in W (positive when the element absorbs power).
    """
    kind = Kind(kind)
    value = np.asarray(value, dtype=float)
    compliance = 1.0 / value if CForm(c_form) is CForm.STIFFNESS else value

    def integrated() -> np.ndarray:
        from scipy.integrate import cumulative_trapezoid  # a costly import, needed only without a measured integral

        return integral if integral is not None else cumulative_trapezoid(S, dx=sample_period, initial=0.0)

    def derivative() -> np.ndarray:
        return np.gradient(S, sample_period, axis=-1)

    if kind is Kind.R:
        return value * S**2 if signal == "flow" else S**2 / value
    if kind is Kind.C:
        # integral: e = q / C;  derivative: f = C de/dt
        return S * integrated() / compliance if signal == "flow" else S * compliance * derivative()
    if kind is Kind.I:
        # integral: f = p / I;  derivative: e = I df/dt
        return S * integrated() / value if signal == "effort" else S * value * derivative()
    raise ValueError(f"kind must be R, C or I for a constitutive power, got {kind.value!r}")


@overload
def _map(function: Callable[..., np.ndarray], signals: np.ndarray, *args: object) -> np.ndarray: ...
@overload
def _map(function: Callable[..., np.ndarray], signals: Mapping[str, np.ndarray], *args: object) -> dict[str, np.ndarray]: ...
def _map(
    function: Callable[..., np.ndarray], signals: np.ndarray | Mapping[str, np.ndarray], *args: object
) -> np.ndarray | dict[str, np.ndarray]:
    """``function`` applied to an array, or to every array of a mapping."""
    if isinstance(signals, Mapping):
        return {name: function(np.asarray(value), *args) for name, value in signals.items()}
    return function(np.asarray(signals), *args)


def _interval_activity(power: np.ndarray, sample_period: float) -> np.ndarray:
    """|P| integrated over each sample interval by the trapezoidal rule (J), shape (..., T)."""
    if not (isinstance(sample_period, (int, float, np.floating)) and math.isfinite(sample_period) and sample_period > 0):
        raise ValueError(f"sample_period must be a finite number of seconds > 0, got {sample_period!r}")
    if not np.all(np.isfinite(power)):
        raise ValueError("power contains NaN or inf; Energy Activity needs finite signals")
    lead, samples = power.shape[:-1], power.shape[-1]
    rows = np.ascontiguousarray(power, dtype=float).reshape(int(np.prod(lead)), samples)
    return interval_activities(rows, float(sample_period)).reshape(lead + (max(samples - 1, 0),))


def window_samples(window: float, sample_period: float) -> int:
    """Number of sample intervals in a window; the window must be a positive multiple of the period."""
    n = window / sample_period
    if not (np.isfinite(n) and n >= 1 and abs(n - round(n)) <= 1e-9 * max(1.0, n)):
        raise ValueError(
            f"window = {window} s must be a positive whole number of sample periods ({sample_period} s)"
        )
    return int(round(n))


def _sum_windows(areas: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Sums of consecutive groups of ``n`` interval areas, and the areas left over."""
    n_windows = areas.shape[-1] // n
    full = areas[..., : n_windows * n].reshape(areas.shape[:-1] + (n_windows, n)).sum(axis=-1)
    return full, areas[..., n_windows * n :]


def _windowed(power: np.ndarray, sample_period: float, window: float) -> np.ndarray:
    return _sum_windows(_interval_activity(power, sample_period), window_samples(window, sample_period))[0]


def energy_activity(power: Signals, sample_period: float, window: float | None = None) -> Signals:
    """Energy Activity (eq 4/7) in J.

    Args:
        power: element power (W), time on the last axis, sampled every ``sample_period`` seconds;
            an array or a mapping from element name to array.
        window: window length in s (a whole number of sample periods). ``None``: one window over the
            whole signal. A trailing partial window is left out.

    Returns:
        EA per window, shape (..., n_windows); window i spans samples [i n, (i + 1) n].
    """
    if window is None:
        return _map(lambda p: _interval_activity(p, sample_period).sum(axis=-1, keepdims=True), power)
    return _map(_windowed, power, sample_period, window)


def cumulative_energy_activity(power: Signals, sample_period: float) -> Signals:
    """Energy Activity from the first sample to every sample (J), same shape as ``power``; never decreases."""

    def cumulative(p: np.ndarray) -> np.ndarray:
        areas = _interval_activity(p, sample_period)
        return np.concatenate([np.zeros(areas.shape[:-1] + (1,)), np.cumsum(areas, axis=-1)], axis=-1)

    return _map(cumulative, power)


def activity_index(ea: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Energy Activity Index (eq 5) of every element in ``ea``: its share of their summed EA.

    Pass the R, C and I elements only (sources and junctions are not components). Where the sum is
    zero (a system at rest) the activity is shared equally, so the indices still sum to one.
    """
    if not ea:
        raise ValueError("activity_index needs at least one element")
    stacked = np.stack([np.asarray(v, dtype=float) for v in ea.values()])
    return dict(zip(ea.keys(), activity_shares(stacked, tuple(ea))))


def activity_shares(stacked: np.ndarray, names: Sequence[str]) -> np.ndarray:
    """``activity_index`` of the elements ``names`` whose EA (J) are the rows of ``stacked`` (len(names), ...):
    their shares, same shape (the EA summed over the rows in order)."""
    valid = np.isfinite(stacked) & (stacked >= 0)
    if not valid.all():
        row = int(np.flatnonzero(~valid.reshape(len(stacked), -1).all(axis=1))[0])
        raise ValueError(f"activity_index: the EA of {names[row]!r} must be finite and >= 0 J, got {float(stacked[row][~valid[row]].flat[0])!r}")
    total = stacked.sum(axis=0)
    safe = np.where(total > 0, total, 1.0)
    return np.where(total > 0, stacked / safe, 1.0 / len(stacked))


def component_activity_index(ea: np.ndarray, columns: np.ndarray, names: Sequence[str]) -> np.ndarray:
    """``activity_index`` of every row of ``ea`` (rows, E) in J: the components ``names`` are its ``columns``;
    returns (rows, C)."""
    shares = np.empty((len(ea), len(columns)))
    if component_shares(np.asarray(ea, dtype=float), np.asarray(columns, dtype=np.intp), shares) >= 0:
        activity_shares(np.ascontiguousarray(ea.T[columns]), names)  # raises, naming the component
    return shares


def step_activity_index(
    sub_ea: np.ndarray, sub_ea_reference: np.ndarray, columns: np.ndarray, names: Sequence[str]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every element's EA (J) over a step, (N, E), from its sub-windows' ``sub_ea`` (N, E, S), the same of the
    reference ``sub_ea_reference``, and the ``component_activity_index`` of each (components ``names`` at
    ``columns``), (N, C): in one compiled pass, the numbers of ``sub_ea.sum(-1)`` and of
    ``component_activity_index`` of both sums' rows stacked."""
    n = len(sub_ea)
    ea, shares = np.empty((2 * n, sub_ea.shape[1])), np.empty((2 * n, len(columns)))
    if summed_shares(sub_ea, sub_ea_reference, columns, ea, shares) >= 0:
        activity_shares(np.ascontiguousarray(ea.T[columns]), names)  # raises, naming the component
    return ea[:n], ea[n:], shares[:n], shares[n:]


@dataclass(frozen=True)
class WindowedEnergy:
    """EA of every element and EAI of the components, per window.

    Attributes:
        window: window length (s).
        t: start time of every window (s), relative to the first sample.
        ea: element name -> EA per window (J).
        eai: component name -> EAI per window (dimensionless, sums to one over the components).
    """

    window: float
    t: np.ndarray
    ea: dict[str, np.ndarray]
    eai: dict[str, np.ndarray]


def windowed_energy(
    power: Mapping[str, np.ndarray], sample_period: float, window: float, components: Sequence[str]
) -> WindowedEnergy:
    """EA per window of every element in ``power`` and EAI over ``components`` (the R, C and I elements)."""
    ea = dict(energy_activity(power, sample_period, window))
    eai = activity_index({name: ea[name] for name in components})
    n_windows = len(next(iter(ea.values())))
    return WindowedEnergy(window=window, t=np.arange(n_windows) * window, ea=ea, eai=eai)


class EnergyActivityAccumulator:
    """Streaming Energy Activity: takes power in chunks, gives the same windows as ``energy_activity``.

    Chunks hold consecutive samples (the first sample of a chunk follows the last of the previous
    one), with any leading axes, time last. Completed windows are summed from the same interval
    areas in the same order as the batch computation, so the results are identical.
    """

    def __init__(self, sample_period: float, window: float) -> None:
        self.sample_period = sample_period
        self.window = window
        self.n = window_samples(window, sample_period)
        self._last: np.ndarray | None = None
        self._pending: np.ndarray | None = None
        self.total: np.ndarray | float = 0.0  # cumulative EA since the first sample (J)

    def update(self, power: np.ndarray) -> np.ndarray:
        """Add samples; return the windows completed by them, shape (..., n_completed)."""
        power = np.asarray(power, dtype=float)
        joined = power if self._last is None else np.concatenate([self._last, power], axis=-1)
        self._last = power[..., -1:]
        areas = _interval_activity(joined, self.sample_period)
        self.total = self.total + areas.sum(axis=-1)
        if self._pending is not None:
            areas = np.concatenate([self._pending, areas], axis=-1)
        done, self._pending = _sum_windows(areas, self.n)
        return done
