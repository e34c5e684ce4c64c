"""Side by side on identical signals: NASA ProgPy's UnscentedKalmanFilter and the ea-gym chain (issue 17).

Three spring-mass-damper ramps (experiments/scenarios/{spring_k,damper_b,mass_m}_ramp.json), seeds
i = 0..4 shifting the scenario's sensor seed by 100 i. The signals of every (scenario, seed) are
generated once, as the chain's harness does (plant and nominal model simulated, measured, sensor noise
added step by step from a generator seeded from the scenario), and the same noisy samples go to:

* ProgPy 1.9's UKF on a spring-mass-damper whose states are the momentum p of the mass (kg m/s), the
  spring's displacement q (m), the degrading parameter and its drift rate (a random walk, the only
  process noise that matters); inputs the load (N) and its rate (N/s) at both ends of each interval;
  outputs the measured velocity p/m (m/s) and displacement (m). Measurement noise: the known noise
  fraction times each signal's RMS over the step (as the sensors scale it). The drift's process noise
  is chosen on the spring scenario's tuning seeds 10..12 and used unchanged for all three.
* The same UKF with all three parameters (k, b, m) and their drifts as states, told nothing about
  which degrades: it isolates the one furthest along the way from nominal to its safe limit.
* The ea-gym chain (``PHMConfig`` at the scenario's noise, the shipped classifier, thresholds
  calibrated as ``build_chain`` does), its estimator selectable with ``--estimator``.

The UKF's RUL carries the parameter and its drift with their covariance to the safe limit the drift
heads for (linear drift): point (limit - value) / drift, 95 % interval the times at which the limit lies
within 1.96 standard deviations of value + drift t (Fieller's interval for the ratio; unbounded while
the drift is not resolved). Metrics (issue 17): absolute estimate errors from 10 s after onset to the
true End of Life, median and max over all seeds' steps; alpha-lambda: the share of the predictions made
every second from 50 to 90 % of the way from onset to End of Life within +-20 % of the true RUL; the
share of those whose 95 % interval covers the true RUL, unbounded intervals counted as misses (and as
hits, beside it); isolation right at the true End of Life, runs out of runs.

    pip install -e '.[compare]'
    python experiments/compare_progpy.py                  # -> experiments/results/compare_progpy/
    python experiments/compare_progpy.py --quick          # mass ramp, seed 0, the UKF at 20 Hz, no tuning
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from ea_gym.diagnosis.monitor import Monitor, MonitorConfig
from ea_gym.energy import window_samples
from ea_gym.files import json_ready, save_figure, write_json, write_text
from ea_gym.metrics import estimation_errors
from ea_gym.models import SystemModel
from ea_gym.phm import PHMChain, PHMConfig, build_chain, classifier_for
from ea_gym.plant import run_model
from ea_gym.scenario import Scenario, load_scenario
from ea_gym.sensors import add_sensor_noise, measure

SCENARIOS = Path(__file__).resolve().parent / "scenarios"
NAMES = ("spring_k_ramp", "damper_b_ramp", "mass_m_ramp")
SEED_SHIFT = 100  # seed i runs with sensors.seed + 100 i
TUNING_SEEDS = (10, 11, 12)  # the spring scenario's seeds the UKF's process noise is chosen on
DRIFT_NOISE_GRID = (3e-5, 1e-4, 3e-4, 1e-3)
DEFAULT_DRIFT_NOISE = 1e-4  # used without tuning (--quick, --drift-noise)
STEP = 1.0  # s of signal per chain update and between predictions
SETTLE = 10.0  # s after onset from which estimate errors count
ALPHA = 0.2
PREDICTION_SPAN = (0.5, 0.9)  # of the way from onset to End of Life
Z95 = 1.959963984540054


# ---------------------------------------------------------------------------------------------------
# signals, generated once per (scenario, seed)
# ---------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Signals:
    """One run's recorded signals, fed to every estimator.

    Attributes:
        t: sample times (s), (T + 1,).
        windows: noisy measured signals (velocity of the mass m/s, displacement of the spring m) of
            every step, (steps, 2, step + 1); step k spans samples k step .. (k + 1) step, and its last
            sample is drawn again (fresh noise) as the next step's first.
        expected: the nominal model's clean signals, (2, T + 1).
        load, load_rate: the load (N) and its rate (N/s), (T + 1,).
        truth: the true parameters, (T + 1, P) in ``model.parameter_names`` order.
        step: samples per step.
    """

    t: np.ndarray
    windows: np.ndarray
    expected: np.ndarray
    load: np.ndarray
    load_rate: np.ndarray
    truth: np.ndarray
    step: int


def record_signals(scenario: Scenario, rng: np.random.Generator) -> Signals:
    """Simulate, measure and add sensor noise step by step exactly as ``ea_gym.phm.run_scenario`` does."""
    model = scenario.model
    t = scenario.times()
    load = scenario.make_load()
    x0 = scenario.initial_state_vector()
    plant = run_model(model, t, load, scenario.parameters_at, x0)
    reference = run_model(model, t, load, None, x0)
    monitor = Monitor(model, 1.0 / scenario.sample_rate, MonitorConfig(), 1)
    clean = measure(monitor, plant.parameters[None], plant.states[None], 0.0, rng)[0]
    expected = measure(monitor, model.parameter_vector()[None], reference.states[None], 0.0, rng)[0]
    step = window_samples(STEP, 1.0 / scenario.sample_rate)
    windows = [add_sensor_noise(clean[:, start : start + step + 1], scenario.noise, rng) for start in range(0, len(t) - step, step)]
    return Signals(t, np.stack(windows), expected, load.value(t), load.derivative(t), plant.parameters, step)


def with_seed(scenario: Scenario, seed: int) -> Scenario:
    """The scenario with its sensor seed shifted by ``SEED_SHIFT * seed``."""
    data = scenario.to_dict()
    data["sensors"]["seed"] = scenario.sensor_seed + SEED_SHIFT * seed
    return replace(load_scenario(data), source=scenario.source)


# ---------------------------------------------------------------------------------------------------
# the ground truth and the metrics (no ProgPy needed)
# ---------------------------------------------------------------------------------------------------


def fault_window(scenario: Scenario) -> tuple[float, float]:
    """(onset, End of Life) in s: when the fault's profile leaves its first value, and when the true
    parameter first crosses its safe limit (``model.safe_limits``)."""
    if scenario.fault is None:
        raise ValueError(f"{scenario.source}: fault: the comparison needs a degrading parameter")
    profile = scenario.fault.profile
    low, high = scenario.model.safe_limits[scenario.fault.parameter]
    points = list(zip(profile.times, profile.values))
    onset = next((t0 for (t0, v0), (_, v1) in zip(points, points[1:]) if v1 != v0), None)
    for (t0, v0), (t1, v1) in zip(points, points[1:]):
        if not low <= v1 <= high:
            limit = low if v1 < low else high
            return float(onset if onset is not None else t0), t0 + (limit - v0) / (v1 - v0) * (t1 - t0)
    raise ValueError(f"{scenario.source}: fault.profile: {scenario.fault.parameter} never crosses its safe limits {low, high}")


def prediction_mask(t: np.ndarray, onset: float, eol: float) -> np.ndarray:
    """Predictions evaluated by alpha-lambda and coverage: from 50 to 90 % of the way from onset to End of Life."""
    first, last = (onset + f * (eol - onset) for f in PREDICTION_SPAN)
    return (t >= first - 1e-9) & (t <= last + 1e-9)


def alpha_hits(rul: np.ndarray, rul_true: np.ndarray, alpha: float = ALPHA) -> np.ndarray:
    """Whether each point RUL (s) lies within +-alpha of the true RUL (bounds inclusive; inf misses).

    ``ea_gym.metrics.alpha_lambda`` judges the one prediction at a single lambda and refuses infinite
    predictions; issue 17 counts every prediction of a span, a missing one (inf) as a miss."""
    return np.isfinite(rul) & (np.abs(rul - rul_true) <= alpha * rul_true)


def interval_hits(low: np.ndarray, high: np.ndarray, rul_true: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(covers, bounded): whether each RUL interval (s) contains the true RUL, and whether it is bounded."""
    return (low <= rul_true) & (rul_true <= high), np.isfinite(low) & np.isfinite(high)


def drift_rul(value: float, drift: float, covariance: np.ndarray, limits: tuple[float, float], z: float = Z95) -> tuple[float, float, float]:
    """RUL (s) of a parameter drifting linearly at ``drift`` (unit/s) to the safe limit the drift heads for.

    Args:
        value, drift: the parameter's estimate and its drift rate.
        covariance: their 2 x 2 covariance.
        limits: the parameter's (low, high) safe limits.

    Returns:
        (point, low, high): point (limit - value) / drift (0 when past it, inf when no drift); the
        interval is every tau >= 0 at which |value + drift tau - limit| <= z sd(value + drift tau),
        bounded when drift^2 > z^2 var(drift).
    """
    if drift == 0 or not np.isfinite(drift):
        return np.inf, 0.0, np.inf
    gap = value - (limits[1] if drift > 0 else limits[0])
    point = max(-gap / drift, 0.0)
    (var_value, cov), (_, var_drift) = covariance
    # (gap + drift tau)^2 - z^2 (var_value + 2 tau cov + tau^2 var_drift) <= 0
    a, b, c = drift**2 - z**2 * var_drift, 2 * (drift * gap - z**2 * cov), gap**2 - z**2 * var_value
    disc = max(b * b - 4 * a * c, 0.0)
    roots = sorted(((-b - np.sqrt(disc)) / (2 * a), (-b + np.sqrt(disc)) / (2 * a))) if a != 0 else [-c / b] * 2
    if a > 0:
        return point, max(roots[0], 0.0), max(roots[1], 0.0)
    # the drift is not resolved: the limit stays within reach for ever
    return point, 0.0 if c <= 0 else min(r for r in roots if r >= 0), np.inf


# ---------------------------------------------------------------------------------------------------
# what each estimator gives at the end of every step
# ---------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Track:
    """One estimator on one run, at the end of every step.

    Attributes:
        t: end of the step (s), (S,).
        estimate: its estimate of the degrading parameter (SI), (S,).
        estimate_time: the time the estimate describes (s), (S,) (the chain's lags behind t).
        isolated: the parameter it names ("" for none), (S,).
        rul: point RUL, interval low and high (s), inf where none, (S, 3).
    """

    t: np.ndarray
    estimate: np.ndarray
    estimate_time: np.ndarray
    isolated: tuple[str, ...]
    rul: np.ndarray


def run_chain(chain: PHMChain, signals: Signals, parameter: str) -> Track:
    """The recorded signals step by step through ``chain`` (N = 1, reset first)."""
    chain.reset()
    step, column = signals.step, chain.degradable.index(parameter)
    t, estimate, isolated, rul = [], [], [], []
    for k, noisy in enumerate(signals.windows):
        part = slice(k * step, (k + 1) * step + 1)
        status = chain.update(noisy[None], signals.expected[None, :, part], signals.load[None, part], signals.load_rate[None, part])
        t.append(status.t[0])
        estimate.append(status.estimates[0, column])
        isolated.append(chain.classes[status.isolated[0]] if status.isolated[0] > 0 else "")
        rul.append(status.rul[0])
    t_array = np.array(t)
    return Track(t_array, np.array(estimate), t_array - chain.estimate_lag, tuple(isolated), np.array(rul))


def chain_config(scenario: Scenario, estimator: str | None) -> PHMConfig:
    """The chain's settings at the scenario's noise, with ``estimator`` where this ea-gym can choose one."""
    config = PHMConfig(sample_rate=scenario.sample_rate, noise=scenario.noise)
    if estimator is None or not isinstance(config.estimator, str):
        if estimator not in (None, "ea_inversion"):
            raise SystemExit(f"compare_progpy: --estimator {estimator!r}: this ea-gym's PHMConfig has one estimator, ea_inversion")
        return config
    return replace(config, estimator=estimator)  # type: ignore[arg-type]  # a name, where PHMConfig takes one


def estimator_label(estimator: str | None) -> str:
    default = PHMConfig().estimator
    return estimator or (default if isinstance(default, str) else "ea_inversion")


# ---------------------------------------------------------------------------------------------------
# ProgPy's side
# ---------------------------------------------------------------------------------------------------


def drift_model(system: SystemModel, estimated: Sequence[str]) -> Any:
    """A ProgPy ``PrognosticsModel`` of the spring-mass-damper with ``estimated`` parameters and their drifts as states.

    States p (kg m/s), q (m), then each estimated parameter (SI) and its drift rate (SI/s); the others
    stay nominal. Inputs: the load F (N) and its rate dF (N/s) at the start of the interval, F_next and
    dF_next at its end (a cubic between them). Outputs: the velocity p / m (m/s) and the displacement q (m).
    One classical Runge-Kutta step per interval, the parameters drifting along it.
    """
    from progpy import PrognosticsModel

    names = list(system.parameter_names)
    nominal = system.parameter_vector()
    slots = np.array([2 + 2 * i for i in range(len(estimated))], dtype=int)  # each estimated parameter's state
    columns = np.array([names.index(name) for name in estimated], dtype=int)
    m, k, b = (names.index(name) for name in ("m", "k", "b"))

    def derivative(state: np.ndarray, force: float) -> np.ndarray:
        values = nominal.copy()
        values[columns] = state[slots]
        velocity = state[0] / values[m]
        rate = np.zeros_like(state)
        rate[0] = force - values[k] * state[1] - values[b] * velocity
        rate[1] = velocity
        rate[slots] = state[slots + 1]
        return rate

    class SpringMassDamperDrift(PrognosticsModel):  # type: ignore[misc]
        inputs = ["F", "dF", "F_next", "dF_next"]
        states = ["p", "q", *(s for name in estimated for s in (name, f"{name}_drift"))]
        outputs = ["v", "x"]
        default_parameters = {"process_noise": 0.0, "measurement_noise": 0.0}

        def next_state(self, x: Any, u: Any, dt: float) -> Any:
            state = np.asarray(x.matrix, dtype=float)[:, 0]
            middle = 0.5 * (u["F"] + u["F_next"]) + dt * (u["dF"] - u["dF_next"]) / 8  # the cubic's midpoint
            r1 = derivative(state, u["F"])
            r2 = derivative(state + 0.5 * dt * r1, middle)
            r3 = derivative(state + 0.5 * dt * r2, middle)
            r4 = derivative(state + dt * r3, u["F_next"])
            return self.StateContainer((state + dt / 6 * (r1 + 2 * r2 + 2 * r3 + r4))[:, None])

        def output(self, x: Any) -> Any:
            state = np.asarray(x.matrix, dtype=float)[:, 0]
            mass = state[slots[list(estimated).index("m")]] if "m" in estimated else nominal[m]
            return self.OutputContainer(np.array([[state[0] / mass], [state[1]]]))

    return SpringMassDamperDrift()


@dataclass(frozen=True)
class FilterSettings:
    """The UKF's settings.

    Attributes:
        drift_noise: std of each drift rate's random walk, a fraction of the parameter's nominal value
            per s per sqrt(s) (the one tuned setting).
        rate: filter steps per s (Hz); a divisor of the sample rate.
        value_spread, drift_spread: the prior's std of each parameter (fraction of nominal) and of
            its drift (fraction of nominal per s), about nominal and no drift.
        state_noise: process noise variance of p and q per s (they follow the model exactly).
    """

    drift_noise: float = DEFAULT_DRIFT_NOISE
    rate: float = 100.0
    value_spread: float = 0.02
    drift_spread: float = 1e-3
    state_noise: float = 1e-10


@dataclass(frozen=True)
class FilterRecord:
    """The UKF's mean (S, n) and covariance (S, n, n) at the end of every step (t, (S,)), ``states`` naming n."""

    t: np.ndarray
    mean: np.ndarray
    covariance: np.ndarray
    states: tuple[str, ...]


def run_ukf(system: SystemModel, signals: Signals, noise: float, estimated: Sequence[str], settings: FilterSettings) -> FilterRecord:
    """ProgPy's UnscentedKalmanFilter over the recorded samples, each step's R from its signals' RMS."""
    from progpy.state_estimators import UnscentedKalmanFilter
    from progpy.uncertain_data import MultivariateNormalDist

    model = drift_model(system, estimated)
    h = float(signals.t[1] - signals.t[0])
    every = int(round(1.0 / (settings.rate * h)))
    if every < 1 or signals.step % every or not np.isclose(every * h * settings.rate, 1.0):
        raise ValueError(f"rate: {settings.rate} Hz must divide the sample rate {1 / h:g} Hz and the step's {signals.step} samples")
    dt = every * h
    nominal = dict(zip(system.parameter_names, system.parameter_vector()))
    scale = np.array([nominal[name] for name in estimated])
    mean = np.concatenate([signals.windows[0, :, 0] * 0.0, np.ravel([(v, 0.0) for v in scale])])
    prior = np.concatenate([[1e-8, 1e-8], np.ravel([((settings.value_spread * v) ** 2, (settings.drift_spread * v) ** 2) for v in scale])])
    Q = np.concatenate([[settings.state_noise * dt] * 2, np.ravel([(0.0, (settings.drift_noise * v) ** 2 * dt) for v in scale])])
    ukf = UnscentedKalmanFilter(model, MultivariateNormalDist(model.states, mean, np.diag(prior)), Q=np.diag(Q), R=np.eye(2), t0=float(signals.t[0]))
    means, covariances = [], []
    t, load, load_rate = signals.t, signals.load, signals.load_rate
    for k, window in enumerate(signals.windows):
        rms = np.sqrt(np.mean(window**2, axis=-1))
        ukf.filter.R = np.diag(np.maximum(noise * rms, 1e-9 * rms) ** 2)  # a floor keeps noise-free runs invertible
        for j in range(every, signals.step + 1, every):
            i = k * signals.step + j
            inputs = {"F": load[i - every], "dF": load_rate[i - every], "F_next": load[i], "dF_next": load_rate[i]}
            ukf.estimate(float(t[i]), inputs, {"v": window[0, j], "x": window[1, j]})
        means.append(ukf.filter.x.copy())
        covariances.append(ukf.filter.P.copy())
    ends = t[signals.step :: signals.step][: len(signals.windows)]
    return FilterRecord(ends, np.array(means), np.array(covariances), tuple(model.states))


def isolate_by_drift(record: FilterRecord, system: SystemModel) -> list[str]:
    """At every step, the estimated parameter furthest along the way from nominal to the safe limit it heads for."""
    names = [name for name in record.states[2::2]]
    nominal = np.array([dict(zip(system.parameter_names, system.parameter_vector()))[n] for n in names])
    low, high = (np.array([system.safe_limits[n][i] for n in names]) for i in (0, 1))
    deviation = record.mean[:, 2::2] - nominal
    progress = deviation / np.where(deviation > 0, high - nominal, nominal - low) * np.sign(deviation)
    return [names[j] for j in np.argmax(progress, axis=1)]


def filter_track(record: FilterRecord, system: SystemModel, parameter: str, isolated: Sequence[str] | None = None) -> Track:
    """The UKF's estimate of ``parameter`` and the RUL of ``isolated`` (default ``parameter``) at every step."""
    isolated = [parameter] * len(record.t) if isolated is None else list(isolated)
    rul = np.empty((len(record.t), 3))
    for s, name in enumerate(isolated):
        j = record.states.index(name)
        pair = record.covariance[s][np.ix_([j, j + 1], [j, j + 1])]
        rul[s] = drift_rul(record.mean[s, j], record.mean[s, j + 1], pair, system.safe_limits[name])
    estimate = record.mean[:, record.states.index(parameter)]
    return Track(record.t, estimate, record.t, tuple(isolated), rul)
