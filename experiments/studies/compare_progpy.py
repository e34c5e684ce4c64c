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

Real machines (issue 30, ``--real-cases``): the spring-mass-damper's independent records
(``experiments/studies/records.py``: its equations by hand, scipy's ``solve_ivp``; 1 % sensor noise), two or three
parts wearing with overlapping onsets, two wearing on a machine off its catalogue values (the chain commissioned on a
separate healthy record), one part wearing with 1 % noise on the load column too. On the same samples: the chain's
per-part outputs and the UKF with every parameter and its drift as states (``ukf_track``), scored per part by
``experiments/studies/part_tracks.py`` (the set of parts named degrading, each parameter's error, alpha-lambda and
coverage per wearing part).

    pip install -e '.[compare]'
    python experiments/studies/compare_progpy.py          # -> experiments/results/compare_progpy/
    python experiments/studies/compare_progpy.py --smoke  # mass ramp, seed 0, the UKF at 20 Hz, no tuning; off-nominal, times x 0.5
    python experiments/studies/compare_progpy.py --ukf-from experiments/results/compare_progpy/results.json

``--ukf-from`` runs the chain alone and takes the UKF's rows (its tuning, settings and every run's
track, rescored here) from an earlier complete run's results.json: the UKF sees only the recorded
signals, which depend on the scenarios and seeds alone, so its rows are the ones a complete run
would give (the real-machine cases' too where that run had them at the same ``--scale``). The table's notes and
results.json name that file and its run's arguments.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's ea_gym and experiments.common, installed or not

from ea_gym.energy import window_samples
from ea_gym.files import json_ready, save_figure, write_json, write_text
from ea_gym.metrics import estimation_errors
from ea_gym.models import SystemModel
from ea_gym.phm import ESTIMATORS, ChainTiming, JointFilterConfig, PHMChain, PHMConfig, build_chain, classifier_for, run_signals
from ea_gym.phm.joint import degrading_probability
from ea_gym.plant import run_model
from ea_gym.scenario import Scenario, load_scenario
from ea_gym.sensors import Sensors, add_sensor_noise
from experiments.common import parse_with_smoke
from experiments.studies.part_tracks import (
    PartTrack,
    alpha_hits,
    chain_run,
    hysteresis,
    interval_hits,
    prediction_mask,
    wear_scores,
    wear_summary,
)
from experiments.studies.records import NOISE, Record, case_record, system_model

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
NAMES = ("spring_k_ramp", "damper_b_ramp", "mass_m_ramp")
SEED_SHIFT = 100  # seed i runs with sensors.seed + 100 i
TUNING_SEEDS = (10, 11, 12)  # the spring scenario's seeds the UKF's process noise is chosen on
DRIFT_NOISE_GRID = (1e-5, 3e-5, 1e-4, 3e-4)
DEFAULT_DRIFT_NOISE = 3e-5  # used without tuning (--smoke); the grid's choice at 20 Hz
#: the smoke run: the mass ramp, seed 0, the UKF at 20 Hz, not tuned; the off-nominal machine at half its times
SMOKE = {"scenarios": ["mass_m_ramp"], "seeds": [0], "ukf_rate": 20.0, "drift_noise": DEFAULT_DRIFT_NOISE,
         "real_cases": ["off-nominal"], "scale": 0.5}
STEP = 1.0  # s of signal per chain update and between predictions
SETTLE = 10.0  # s after onset from which estimate errors count
Z95 = 1.959963984540054


# ---------------------------------------------------------------------------------------------------
# signals, generated once per (scenario, seed)
# ---------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Signals:
    """One run's recorded signals, fed to every estimator.

    Attributes:
        t: sample times (s), (T + 1,).
        clean: the plant's measured signals before noise, (2, T + 1).
        windows: noisy measured signals (velocity of the mass m/s, displacement of the spring m) of
            every step, (steps, 2, step + 1); step k spans samples k step .. (k + 1) step, and its last
            sample is drawn again (fresh noise) as the next step's first.
        expected: the nominal model's clean signals, (2, T + 1).
        load, load_rate: the load (N) and its rate (N/s), (T + 1,).
        truth: the true parameters, (T + 1, P) in ``model.parameter_names`` order.
        step: samples per step.
    """

    t: np.ndarray
    clean: np.ndarray
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
    sensors = Sensors(model)
    clean = sensors.measure(plant.parameters[None], plant.states[None], 0.0, rng)[0]
    expected = sensors.measure(model.parameter_vector()[None], reference.states[None], 0.0, rng)[0]
    step = window_samples(STEP, 1.0 / scenario.sample_rate)
    windows = [add_sensor_noise(clean[:, start : start + step + 1], scenario.noise, rng) for start in range(0, len(t) - step, step)]
    return Signals(t, clean, np.stack(windows), expected, load.value(t), load.derivative(t), plant.parameters, step)


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
    """The recorded signals through ``chain`` (``run_signals``, N = 1): each step gets the noisy chunk the UKF saw."""
    recorded = iter(signals.windows[:, None])
    statuses = run_signals(
        chain, signals.clean[None], signals.load[None], signals.load_rate[None], signals.expected[None], noise=lambda chunk: next(recorded)
    )
    column = chain.degradable.index(parameter)
    return Track(
        t=np.array([status.t[0] for status in statuses]),
        estimate=np.array([status.estimates[0, column] for status in statuses]),
        estimate_time=np.array([status.estimation.time[0, column] for status in statuses]),
        isolated=tuple(chain.classes[status.isolated[0]] if status.isolated[0] > 0 else "" for status in statuses),
        rul=np.array([status.rul[0] for status in statuses]),
    )


def chain_config(scenario: Scenario, estimator: str | None) -> PHMConfig:
    """The chain's settings at the scenario's noise, with the ``estimator`` kind (None: the default)."""
    config = PHMConfig(timing=ChainTiming(sample_rate=scenario.sample_rate, noise=scenario.noise))
    return config if estimator is None else replace(config, estimator_kind=estimator)


def estimator_label(estimator: str | None) -> str:
    return estimator or PHMConfig().estimator_kind


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

    class SpringMassDamperDrift(PrognosticsModel):
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


def recorded_signals(record: Record) -> Signals:
    """An independent record's noisy samples as the chain's 1 s steps see them (step k: samples k step .. (k + 1) step,
    its first the previous step's last), the load's rate its central difference (``numpy.gradient``: the chain's stream
    takes it so from the recorded load), the truth the machine's parameters."""
    measurements = record.measurements
    step = window_samples(STEP, measurements.sample_period)
    signals = measurements.signals.T
    windows = np.stack([signals[:, start : start + step + 1] for start in range(0, signals.shape[1] - step, step)])
    load_rate = np.gradient(measurements.load, measurements.sample_period)
    truth = record.machine.values(measurements.t)
    return Signals(measurements.t, record.clean.T, windows, record.clean.T, measurements.load, load_rate, truth, step)


def ukf_track(record: Record, settings: FilterSettings) -> PartTrack:
    """ProgPy's UKF with every part of the spring-mass-damper and its drift as states, on an independent record, read as the
    chain's per-part outputs by the chain's rules: P(degrading) = P(|drift| > ``JointFilterConfig.degrading_rate`` x the
    safe span per s), named from ``name_probability`` until below ``release_probability``; End of Life the drift's crossing
    (``drift_rul``: Fieller's interval) where named."""
    system = system_model(record.machine.system)
    parts = tuple(system.safe_limits)
    filtered = run_ukf(system, recorded_signals(record), NOISE, parts, settings)
    slots = [filtered.states.index(name) for name in parts]
    value, drift = filtered.mean[:, slots], filtered.mean[:, [s + 1 for s in slots]]
    variance = filtered.covariance[:, slots, slots]
    drift_variance = filtered.covariance[:, [s + 1 for s in slots], [s + 1 for s in slots]]
    limits = np.array([system.safe_limits[name] for name in parts])
    rules = JointFilterConfig()
    degrading = degrading_probability(drift, drift_variance, rules.degrading_rate * (limits[:, 1] - limits[:, 0]))
    named = hysteresis(degrading, rules.name_probability, rules.release_probability)
    ends = np.full((3,) + value.shape, np.inf)
    for s, j in zip(*np.nonzero(named)):
        pair = filtered.covariance[s][np.ix_([slots[j], slots[j] + 1], [slots[j], slots[j] + 1])]
        ends[:, s, j] = filtered.t[s] + np.array(drift_rul(value[s, j], drift[s, j], pair, tuple(limits[j])))
    steps = len(filtered.t)
    return PartTrack(
        t=filtered.t, parts=parts, value=value, std=np.sqrt(variance), degrading=degrading, named=named, eol=ends[0], eol_low=ends[1],
        eol_high=ends[2], alarm=named.any(axis=1), isolated=np.full(steps, -1), fits=np.ones(steps, dtype=bool),
        misfit=np.zeros(steps, dtype=bool), machine_eol=ends[0].min(axis=1),
    )


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


# ---------------------------------------------------------------------------------------------------
# scores
# ---------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RunScore:
    """One track's samples for issue 17's metrics (see the module docstring)."""

    estimate: np.ndarray  # in the error window
    truth: np.ndarray
    alpha: np.ndarray  # per prediction: within +-20 % of the true RUL
    covers: np.ndarray  # per prediction: the interval contains the true RUL
    bounded: np.ndarray  # per prediction: the interval is bounded
    isolated: str  # named at the true End of Life


def score_run(track: Track, scenario: Scenario) -> RunScore:
    """The samples of ``track`` the metrics count, against the scenario's truth."""
    assert scenario.fault is not None
    onset, eol = fault_window(scenario)
    errors = (track.t >= onset + SETTLE - 1e-9) & (track.t <= eol)
    truth = scenario.fault.profile.value(track.estimate_time[errors])
    predictions = prediction_mask(track.t, onset, eol)
    rul_true = eol - track.t[predictions]
    low, high = track.rul[predictions, 1], track.rul[predictions, 2]
    covers, bounded = interval_hits(low, high, rul_true)
    last = int(np.flatnonzero(track.t <= eol)[-1])
    alpha = alpha_hits(track.rul[predictions, 0], rul_true)
    return RunScore(track.estimate[errors], np.asarray(truth, dtype=float), alpha, covers, bounded, track.isolated[last])


def summarise(scores: Sequence[RunScore], parameter: str) -> dict[str, Any]:
    """Issue 17's figures over all seeds' runs of one scenario."""
    estimate = np.concatenate([s.estimate for s in scores])
    truth = np.concatenate([s.truth for s in scores])
    finite = np.isfinite(estimate)
    errors = estimation_errors(estimate[finite], truth[finite]) if finite.any() else {"median": np.nan, "max": np.nan, "rmse": np.nan}
    alpha, covers, bounded = (np.concatenate([getattr(s, name) for s in scores]) for name in ("alpha", "covers", "bounded"))
    return {
        "error_median": errors["median"],
        "error_max": errors["max"] if finite.all() else np.inf,  # a missing estimate is as bad as any
        "error_rmse": errors["rmse"],
        "missing_estimates": int((~finite).sum()),
        "alpha_lambda": float(alpha.mean()),
        "coverage": float((covers & bounded).mean()),  # unbounded intervals count as misses
        "coverage_unbounded_as_hits": float(covers.mean()),
        "predictions": int(alpha.size),
        "bounded_intervals": int(bounded.sum()),
        "isolated_right": sum(s.isolated == parameter for s in scores),
        "runs": len(scores),
    }


def tune_drift_noise(scenario: Scenario, settings: FilterSettings, grid: Sequence[float], log: Any) -> tuple[float, list[dict[str, Any]]]:
    """The drift noise of ``grid`` with the smallest RMS estimate error on the tuning seeds among those
    whose intervals cover the true RUL >= 90 % of the time (unbounded as misses); the best covering
    without one. The RMS error, not the median: a drift noise too small for the filter to follow the
    fault's onset has the smallest median error and the largest errors after the onset."""
    assert scenario.fault is not None
    parameter = scenario.fault.parameter
    signals = [record_signals(s, np.random.default_rng(s.sensor_seed)) for s in (with_seed(scenario, i) for i in TUNING_SEEDS)]
    rows = []
    for value in grid:
        tuned = replace(settings, drift_noise=value)
        records = [run_ukf(scenario.model, x, scenario.noise, (parameter,), tuned) for x in signals]
        scores = [score_run(filter_track(record, scenario.model, parameter), scenario) for record in records]
        rows.append({"drift_noise": value, **summarise(scores, parameter)})
        log(f"tuning drift_noise {value:g}: error median {rows[-1]['error_median']:.3g}, max {rows[-1]['error_max']:.3g}, "
            f"rms {rows[-1]['error_rmse']:.3g}; coverage {rows[-1]['coverage']:.2f}")
    covering = [row for row in rows if row["coverage"] >= 0.9]
    best = min(covering, key=lambda row: row["error_rmse"]) if covering else max(rows, key=lambda row: row["coverage"])
    return float(best["drift_noise"]), rows


# ---------------------------------------------------------------------------------------------------
# one (scenario, seed): the signals once, every estimator on them
# ---------------------------------------------------------------------------------------------------

UKF = "ProgPy UKF"
UKF_ALL = "ProgPy UKF, all three parameters as states"


def chain_method(estimator: str) -> str:
    return f"ea-gym chain ({estimator})"


def run_seed(scenario: Scenario, chains: dict[str, PHMChain], settings: FilterSettings | None, log: Any) -> dict[str, Track]:
    """Every estimator's track on the scenario's signals (its sensor seed as given); the chains' alone
    when ``settings`` is None (the UKFs' tracks taken from an earlier run)."""
    assert scenario.fault is not None
    parameter, system = scenario.fault.parameter, scenario.model
    signals = record_signals(scenario, np.random.default_rng(scenario.sensor_seed))
    tracks = {}
    start = time.perf_counter()
    if settings is not None:
        tracks[UKF] = filter_track(run_ukf(system, signals, scenario.noise, (parameter,), settings), system, parameter)
        everything = run_ukf(system, signals, scenario.noise, tuple(system.parameter_names), settings)
        tracks[UKF_ALL] = filter_track(everything, system, parameter, isolate_by_drift(everything, system))
    middle = time.perf_counter()
    for estimator, chain in chains.items():
        tracks[chain_method(estimator)] = run_chain(chain, signals, parameter)
    log(f"  seed {scenario.sensor_seed}: UKFs {middle - start:.0f} s, chain {time.perf_counter() - middle:.0f} s")
    return tracks


# ---------------------------------------------------------------------------------------------------
# outputs
# ---------------------------------------------------------------------------------------------------


def table(summary: dict[str, dict[str, dict[str, Any]]], scenarios: dict[str, Scenario]) -> str:
    """The markdown table: one row per estimator, the scenarios' parameters in the columns."""
    params = [(name, s.fault.parameter, s.model.units.get(s.fault.parameter, "")) for name, s in scenarios.items() if s.fault is not None]
    slash = " / ".join(p for _, p, _ in params)
    header = (
        "| | " + " | ".join(f"{p} median / max ({unit})" for _, p, unit in params)
        + f" | alpha-lambda {slash} | RUL 95 % interval covers truth {slash} (unbounded intervals as hits) | isolated right at End of Life {slash} |"
    )
    lines = [header, "|---" * (len(params) + 4) + "|"]
    for method, rows in summary.items():
        cells = [f"{rows[n]['error_median']:.2g} / {rows[n]['error_max']:.2g}" for n, _, _ in params]
        alpha = " / ".join(f"{rows[n]['alpha_lambda']:.2f}" for n, _, _ in params)
        coverage = " / ".join(f"{rows[n]['coverage']:.2f}" for n, _, _ in params)
        loose = " / ".join(f"{rows[n]['coverage_unbounded_as_hits']:.2f}" for n, _, _ in params)
        isolated = " / ".join(f"{rows[n]['isolated_right']} of {rows[n]['runs']}" for n, _, _ in params)
        lines.append(f"| {method} | " + " | ".join(cells) + f" | {alpha} | {coverage} ({loose}) | {isolated} |")
    return "\n".join(lines) + "\n"


def plot_estimates(tracks: dict[str, dict[str, list[Track]]], scenarios: dict[str, Scenario], path: Path) -> Path:
    """One panel per scenario: every estimator's estimate of the degrading parameter, all seeds, against the truth."""
    from ea_gym.pyplot import plt

    fig, axes = plt.subplots(len(scenarios), 1, figsize=(10, 3.6 * len(scenarios)), squeeze=False)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, (name, scenario) in zip(axes[:, 0], scenarios.items()):
        assert scenario.fault is not None
        parameter = scenario.fault.parameter
        onset, eol = fault_window(scenario)
        limit = min(scenario.model.safe_limits[parameter], key=lambda v: abs(v - scenario.fault.profile.value(np.array(eol))))  # type: ignore[union-attr]
        t = scenario.times()[:: int(round(scenario.sample_rate))]
        drawn = [scenario.fault.profile.value(t), np.array([limit])]
        for i, (method, runs) in enumerate(tracks[name].items()):
            style = {"color": colors[i % len(colors)], "ls": ("-", "--")[i % 2], "lw": 0.8, "zorder": 3}
            for s, track in enumerate(runs):
                ax.plot(track.estimate_time, track.estimate, label=method if s == 0 else None, **style)
                drawn.append(track.estimate)
        ax.plot(t, drawn[0], color="0.3", lw=3.0, zorder=2, label=f"true {parameter}")
        ax.axhline(limit, color="0.4", ls="--", lw=1.0, label="safe limit")
        ax.axvline(eol, color="0.4", ls=":", lw=1.0, label="true End of Life")
        values = np.concatenate([np.ravel(v) for v in drawn])
        values = values[np.isfinite(values)]
        pad = 0.05 * (values.max() - values.min())
        ax.set_ylim(values.min() - pad, values.max() + pad)
        ax.set_xlim(0.0, scenario.duration)
        ax.set_title(f"{name}: estimates of {parameter}, {len(next(iter(tracks[name].values())))} noise seeds")
        ax.set_ylabel(f"{parameter} ({scenario.model.units.get(parameter, '')})")
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    axes[-1, 0].set_xlabel("time the estimate describes (s)")
    fig.tight_layout()
    return save_figure(fig, path)


def track_data(track: Track) -> dict[str, Any]:
    return {"t": track.t, "estimate": track.estimate, "estimate_time": track.estimate_time, "isolated": list(track.isolated),
            "rul": track.rul[:, 0], "rul_low": track.rul[:, 1], "rul_high": track.rul[:, 2]}


def read_track(data: dict[str, Any]) -> Track:
    """The inverse of ``track_data`` after JSON (which wrote NaN and inf as null: a missing estimate is NaN, a missing RUL inf)."""
    def numbers(key: str, missing: float) -> np.ndarray:
        return np.array([missing if v is None else v for v in data[key]], dtype=float)

    rul = np.stack([numbers(key, np.inf) for key in ("rul", "rul_low", "rul_high")], axis=1)
    return Track(numbers("t", np.nan), numbers("estimate", np.nan), numbers("estimate_time", np.nan), tuple(data["isolated"]), rul)


@dataclass(frozen=True)
class EarlierUKF:
    """The UKF's rows of an earlier complete run: its settings, tuning, tracks per scenario and method, and where they came from."""

    settings: FilterSettings
    tuning: list[dict[str, Any]]
    tracks: dict[str, dict[str, list[Track]]]
    source: dict[str, Any]
    real: dict[str, dict[str, Any]]


def read_earlier_ukf(path: Path, names: Sequence[str], seeds: Sequence[int], scale: float) -> EarlierUKF:
    """The UKF's rows of ``path`` (a results.json of this script), for ``names`` and ``seeds``, and its real-machine cases'
    where it ran them at the time ``scale``.

    Raises:
        ValueError: the file lacks a scenario, a UKF method, or ran other seeds.
    """
    data = json.loads(path.read_text())
    if list(data.get("seeds", [])) != list(seeds):
        raise ValueError(f"--ukf-from: {path} ran seeds {data.get('seeds')}, not {list(seeds)}")
    tracks = {}
    for name in names:
        runs = data.get("runs", {}).get(name, {})
        if not all(method in runs for method in (UKF, UKF_ALL)):
            raise ValueError(f"--ukf-from: {path} has no UKF runs of {name}")
        tracks[name] = {method: [read_track(run) for run in runs[method]] for method in (UKF, UKF_ALL)}
    source = {"path": str(path), "arguments": data.get("arguments"), **({"reused_from": data["ukf_source"]} if "ukf_source" in data else {})}
    # the real-machine cases' UKF summaries, where that run had them at the same time scale (else they are run again)
    real = {case: rows[UKF_ALL] for case, rows in data.get("real_cases", {}).items() if UKF_ALL in rows and data.get("real_scale") == scale}
    return EarlierUKF(FilterSettings(**data["ukf"]), data.get("tuning", []), tracks, source, real)


# ---------------------------------------------------------------------------------------------------
# real machines (issue 30): several parts wearing, a machine off its catalogue values, a noisy load column
# ---------------------------------------------------------------------------------------------------

REAL_SYSTEM = "spring_mass_damper"
#: case -> (the records' case in ``records.CASES``, the load column's noise)
REAL_CASES = {"two parts": ("two parts", 0.0), "three parts": ("three parts", 0.0), "off-nominal": ("off-nominal", 0.0),
              "noisy load": ("single part", NOISE)}
#: the UKF's prior spread (fraction of nominal) on an off-nominal machine: as wide as the joint filter's prior (0.15 of the safe span,
#: 3 to 6 % of nominal here); 0.02, 0.05 and 0.1 gave errors within 30 % of each other on seed 0
OFF_NOMINAL_SPREAD = 0.05
REAL_CHAIN = "ea-gym chain (per-part outputs)"


def real_case(case: str, seeds: Sequence[int], scale: float, settings: FilterSettings | None, log: Any) -> dict[str, dict[str, Any]]:
    """The chain and ProgPy's UKF (every parameter jointly; not run where ``settings`` is None) on one real-machine case's records:
    each one's ``part_tracks.wear_summary`` and run time per record."""
    kind, load_noise = REAL_CASES[case]
    runs: dict[str, list[dict[str, Any]]] = {REAL_CHAIN: [], UKF_ALL: []}
    seconds = {REAL_CHAIN: 0.0, UKF_ALL: 0.0}
    for seed in seeds:
        record, healthy = case_record(REAL_SYSTEM, kind, seed, scale, load_noise)
        began = time.perf_counter()
        track = chain_run(record, load_noise=load_noise, commissioning=healthy if kind == "off-nominal" else None)
        runs[REAL_CHAIN].append(wear_scores(track, record.machine))
        seconds[REAL_CHAIN] += time.perf_counter() - began
        if settings is not None:
            began = time.perf_counter()
            told = replace(settings, value_spread=OFF_NOMINAL_SPREAD) if kind == "off-nominal" else settings
            runs[UKF_ALL].append(wear_scores(ukf_track(record, told), record.machine))
            seconds[UKF_ALL] += time.perf_counter() - began
        log(f"  {case}, seed {seed}: " + ", ".join(f"{method} {seconds[method]:.0f} s so far" for method in runs))
    return {method: {**wear_summary(done), "seconds_per_record": seconds[method] / len(done)} for method, done in runs.items() if done}


def real_table(cases: dict[str, dict[str, dict[str, Any]]]) -> str:
    """Per real-machine case: each parameter's median error by both filters and their ratio; the set named, alpha-lambda and
    coverage per wearing part, and the time per record of each."""
    lines = ["| case | parameter | wearing | chain median abs error | UKF median abs error | chain / UKF |", "|---|---|---|---|---|---|"]
    for case, rows in cases.items():
        chain, ukf = rows[REAL_CHAIN], rows[UKF_ALL]
        for part, error in chain["error_median"].items():
            wearing = "yes" if part in chain["alpha_lambda"] else "no"
            lines.append(f"| {case} | {part} | {wearing} | {error:.3g} | {ukf['error_median'][part]:.3g} | {error / ukf['error_median'][part]:.2f} |")
    lines += ["", "| case | method | set named exactly | alpha-lambda per wearing part | RUL 95 % coverage per wearing part | s per record |",
              "|---|---|---|---|---|---|"]
    for case, rows in cases.items():
        for method, row in rows.items():
            alpha = ", ".join(f"{part} {value:.2f}" for part, value in row["alpha_lambda"].items())
            coverage = ", ".join(f"{part} {value:.2f}" for part, value in row["coverage"].items())
            lines.append(f"| {case} | {method} | {row['set_named']:.3f} | {alpha} | {coverage} | {row['seconds_per_record']:.1f} |")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------------------
# command line
# ---------------------------------------------------------------------------------------------------


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenarios", nargs="+", choices=NAMES, default=list(NAMES), help="which ramps (default all three)")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4], help="seeds i: sensors.seed + 100 i (default 0..4)")
    parser.add_argument("--estimator", action="append", default=None, choices=sorted(ESTIMATORS),
                        help="the chain's estimator, PHMConfig.estimator_kind (repeat for several; default: PHMConfig's default)")
    parser.add_argument("--ukf-rate", type=float, default=None, help="UKF steps per s (Hz), a divisor of the sample rate (default: the sample rate)")
    parser.add_argument("--drift-noise", type=float, default=None, help="the UKF's drift noise, not tuned (default: tuned on seeds 10..12)")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "results" / "compare_progpy", help="output folder")
    parser.add_argument("--ukf-from", type=Path, default=None, help="run the chain alone, the UKF's rows from this earlier results.json")
    parser.add_argument("--real-cases", nargs="*", choices=list(REAL_CASES), default=list(REAL_CASES),
                        help="issue 30's real-machine cases on independent records (default all; none: leave them out)")
    parser.add_argument("--scale", type=float, default=1.0, help="the real-machine cases' onsets, times to the limit and lengths multiplied by it")
    args = parse_with_smoke(parser, argv, SMOKE)
    if not 0.2 <= args.scale <= 10:
        parser.error(f"--scale: expected a factor in [0.2, 10], got {args.scale}")
    if any(seed < 0 for seed in args.seeds):
        parser.error(f"--seeds: must be >= 0, got {args.seeds}")
    if args.ukf_rate is not None and not args.ukf_rate > 0:
        parser.error(f"--ukf-rate: must be > 0 Hz, got {args.ukf_rate}")
    if args.drift_noise is not None and not args.drift_noise >= 0:
        parser.error(f"--drift-noise: must be >= 0, got {args.drift_noise}")
    if args.ukf_from is not None and not args.ukf_from.is_file():
        parser.error(f"--ukf-from: expected an earlier results.json of this script, {args.ukf_from} is not a file")
    if args.ukf_from is not None and (args.smoke or args.ukf_rate is not None or args.drift_noise is not None):
        parser.error("--ukf-from: the UKF's settings come from that file; leave out --smoke, --ukf-rate and --drift-noise")
    return args


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    earlier = None
    if args.ukf_from is not None:
        try:
            earlier = read_earlier_ukf(args.ukf_from, args.scenarios, args.seeds, args.scale)
        except (ValueError, KeyError, TypeError, json.JSONDecodeError) as error:
            print(f"compare_progpy: {error}", file=sys.stderr)
            return 2
    elif importlib.util.find_spec("progpy") is None:
        print("compare_progpy: ProgPy is not installed; pip install -e '.[compare]' (progpy==1.9.0)", file=sys.stderr)
        return 2
    scenarios = {name: load_scenario(SCENARIOS / f"{name}.json") for name in args.scenarios}
    spring = load_scenario(SCENARIOS / "spring_k_ramp.json")
    settings = FilterSettings(rate=args.ukf_rate or spring.sample_rate)
    tuning: list[dict[str, Any]] = []
    if earlier is not None:
        settings, tuning = earlier.settings, earlier.tuning
    elif args.drift_noise is None:
        drift_noise, tuning = tune_drift_noise(spring, settings, DRIFT_NOISE_GRID, log)
        settings = replace(settings, drift_noise=drift_noise)
    else:
        settings = replace(settings, drift_noise=args.drift_noise)
    estimators = args.estimator or [None]
    tracks: dict[str, dict[str, list[Track]]] = {}
    summary: dict[str, dict[str, dict[str, Any]]] = {}
    for name, scenario in scenarios.items():
        assert scenario.fault is not None
        log(f"{name}:")
        classifier = classifier_for(scenario.model)
        chains = {estimator_label(e): build_chain(scenario.model, chain_config(scenario, e), classifier, np.random.default_rng(scenario.sensor_seed))
                  for e in estimators}
        runs = [run_seed(with_seed(scenario, seed), chains, None if earlier else settings, log) for seed in args.seeds]
        tracks[name] = {**(earlier.tracks[name] if earlier else {}), **{method: [run[method] for run in runs] for method in runs[0]}}
        for method, method_tracks in tracks[name].items():
            summary.setdefault(method, {})[name] = summarise([score_run(t, scenario) for t in method_tracks], scenario.fault.parameter)
    real: dict[str, dict[str, dict[str, Any]]] = {}
    for case in args.real_cases:
        log(f"{case} ({REAL_SYSTEM}, independent records):")
        rows = real_case(case, args.seeds, args.scale, None if earlier and case in earlier.real else settings, log)
        real[case] = {**rows, **({UKF_ALL: earlier.real[case]} if earlier and case in earlier.real else {})}
    markdown = table(summary, scenarios)
    notes = (
        f"\nSeeds {args.seeds} (sensors.seed + 100 i); the UKF at {settings.rate:g} Hz (one sample in {spring.sample_rate / settings.rate:g} "
        f"of the same noisy samples), drift noise {settings.drift_noise:g} "
        "of nominal per s per sqrt(s)" + (" (the smallest RMS error on the spring ramp's seeds 10..12)" if tuning else " (given, not tuned)")
        + (f"; the UKF's rows from {earlier.source['path']} (an earlier run, arguments {earlier.source['arguments']}: the UKF sees only "
           "the recorded signals, the same for the same scenarios and seeds)" if earlier else "")
        + f". Errors from {SETTLE:g} s after onset to the true End of Life (the chain's estimate against the truth at the time it "
        "describes); alpha-lambda (alpha 0.2) and coverage over predictions every second from 50 to 90 % of the way from onset to End of Life.\n"
    )
    if real:
        notes += (f"\n# Real machines: several parts wearing, off-nominal machines, a noisy load column ({REAL_SYSTEM})\n\nIndependent "
                  "records (experiments/studies/records.py: the equations by hand, scipy's solve_ivp), 1 % sensor noise, seeds "
                  f"{args.seeds}, times x {args.scale:g}: the chain's per-part outputs against ProgPy's UKF with every parameter and its drift as "
                  f"states on the same samples (on the off-nominal machine its prior spread {OFF_NOMINAL_SPREAD:g} of nominal; the chain "
                  "commissioned on a separate 30 s healthy record); errors from 10 s after the first onset, the set named from 30 s after "
                  "each onset, alpha-lambda and coverage as above per wearing part (experiments/studies/part_tracks.py).\n\n" + real_table(real))
    write_text(args.out / "table.md", markdown + notes)
    plot_estimates(tracks, scenarios, args.out / "estimates.png")
    write_json(args.out / "results.json", json_ready({
        "arguments": list(argv if argv is not None else sys.argv[1:]),
        "seeds": args.seeds, "ukf": {**vars(settings)}, "tuning": tuning, **({"ukf_source": earlier.source} if earlier else {}), "summary": summary,
        "runs": {name: {method: [track_data(t) for t in runs] for method, runs in by_method.items()} for name, by_method in tracks.items()},
        "real_cases": real, "real_scale": args.scale,
    }))
    print(markdown + notes)
    return 0


if __name__ == "__main__":
    sys.exit(main())
