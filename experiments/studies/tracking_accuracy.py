"""Accuracy and speed of the tracking estimator on issue 17's three spring-mass-damper ramps.

Each scenario (experiments/scenarios/{spring_k,damper_b,mass_m}_ramp.json) runs with 5 sensor-noise
seeds (the scenario's seed + 100 i, i = 0..4), its signals generated as the chain's harness does
(plant, clean measurement, noise added step by step), the true hypothesis given. Printed per parameter:
median / max estimate error from 10 s after onset to the true End of Life, alpha-lambda (alpha 0.2:
the share of predictions within +-20 % of the true RUL, made every second from 50 to 90 % of the way
from onset to End of Life), the share of those predictions whose 95 % interval covers the true RUL
(unbounded intervals count as misses), ProgPy's UKF numbers from the issue beside them; whether the
true hypothesis holds the largest log-evidence; and the time per step at N = 1 and N = 256.

    python experiments/studies/tracking_accuracy.py            # the table (evaluation seeds 0..4)
    python experiments/studies/tracking_accuracy.py --systems  # every built-in's parameters, random loads
    python experiments/studies/tracking_accuracy.py --wear 1e-4  # RUL under linear / Wiener / gamma wear
    python experiments/studies/tracking_accuracy.py --tune     # process-noise and prior grid on the three ramps, tuning seeds 10..49
    python experiments/studies/tracking_accuracy.py --smoke    # the table on seed 0, the speed at N = 1 and 4
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's ea_gym and experiments.common, installed or not

from ea_gym.models import get_model
from ea_gym.phm.config import ExtrapolationConfig, TrackingConfig
from ea_gym.phm.estimation import ParameterEstimates, StepSignals
from ea_gym.phm.prognosis import DriftPrognosis
from ea_gym.phm.tracking import TrackingEstimator
from ea_gym.plant import run_model
from ea_gym.scenario import Scenario, load_scenario
from ea_gym.sensors import Sensors, add_sensor_noise
from experiments.common import parse_with_smoke

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
NAMES = ("spring_k_ramp", "damper_b_ramp", "mass_m_ramp")
# ProgPy UKF from issue 17: median, max error; alpha-lambda; coverage
UKF = {"k": (0.015, 0.15, 1.00, 0.95), "b": (0.0027, 0.009, 0.83, 0.96), "m": (0.0015, 0.018, 1.00, 1.00)}
STEP = 1.0  # s of signal per update, the chain's default
#: the smoke run: the table on one seed, the speed on a small batch
SMOKE = {"seeds": 1, "sizes": [1, 4]}


@dataclass
class Signals:
    """One run's step windows: measured (steps, 1, nx, L + 1), load and rate (steps, 1, L + 1), step ends t (steps,), true parameters (steps, P)."""

    measured: np.ndarray
    load: np.ndarray
    load_rate: np.ndarray
    t: np.ndarray
    truth: np.ndarray


def fault_parameter(scenario: Scenario) -> str:
    if scenario.fault is None:
        raise ValueError("the scenario has no fault")
    return scenario.fault.parameter


def scenario_signals(scenario: Scenario, seed: int) -> Signals:
    """The chain harness's signals: plant, clean measurement, then noise per step from ``seed``."""
    model, t = scenario.model, scenario.times()
    load = scenario.make_load()
    plant = run_model(model, t, load, scenario.parameters_at, scenario.initial_state_vector())
    rng = np.random.default_rng(seed)
    clean = Sensors(model).measure(plant.parameters[None], plant.states[None], 0.0, rng)
    u, du = load.value(t)[None], load.derivative(t)[None]
    step = int(round(STEP * scenario.sample_rate))
    starts = list(range(0, len(t) - step, step))
    measured = np.stack([add_sensor_noise(clean[..., s : s + step + 1], scenario.noise, rng) for s in starts])
    ends = np.array([s + step for s in starts])
    return Signals(
        measured, np.stack([u[:, s : s + step + 1] for s in starts]), np.stack([du[:, s : s + step + 1] for s in starts]),
        t[ends], plant.parameters[ends],
    )


def true_end_of_life(scenario: Scenario) -> tuple[float, float]:
    """Onset (s) and the time the true parameter first leaves its safe limits (s)."""
    name = fault_parameter(scenario)
    t = np.linspace(0.0, scenario.duration, 100001)
    values = scenario.parameters_at(t)[:, scenario.model.parameter_names.index(name)]
    lower, upper = scenario.model.safe_limits[name]
    onset = float(t[np.flatnonzero(values != values[0])[0] - 1])
    return onset, float(t[np.flatnonzero((values < lower) | (values > upper))[0]])


def chain_prognosis(estimator: TrackingEstimator) -> DriftPrognosis:
    """The chain's prognosis stage for ``estimator`` (``ea_gym.phm.tracking.tracking_stages``)."""
    return DriftPrognosis(estimator.model, estimator.degradable, ExtrapolationConfig(), estimator.diffusion, estimator.n)


def end_of_life(prognosis: DriftPrognosis, estimates: ParameterEstimates, j: int, t: np.ndarray) -> tuple[float, float, float]:
    """System 0's End of Life and interval (s) with degradable parameter ``j`` the confident suspect, at ``t`` (1,)."""
    out = prognosis.update(estimates, np.array([j + 1]), np.ones(1, dtype=bool), t)
    return float(out.eol[0]), float(out.eol_low[0]), float(out.eol_high[0])


def track_run(scenario: Scenario, signals: Signals, config: TrackingConfig) -> dict[str, np.ndarray]:
    """The true hypothesis's estimate, RUL and interval, and the evidence ranking, at every step end."""
    estimator = TrackingEstimator(scenario.model, scenario.sample_rate, scenario.noise, 1, config=config)
    prognosis = chain_prognosis(estimator)
    j = estimator.degradable.index(fault_parameter(scenario))
    rows: dict[str, list] = {"value": [], "rul": [], "low": [], "high": [], "best": []}
    suspects = np.ones((1, len(estimator.degradable)), dtype=bool)
    for k in range(len(signals.t)):
        step = StepSignals(signals.measured[k], signals.load[k], signals.load_rate[k], signals.t[k : k + 1])
        est = estimator.update(step, np.ones(1, dtype=bool), suspects)
        eol, low, high = end_of_life(prognosis, est, j, signals.t[k : k + 1])
        rows["value"].append(est.value[0, j])
        rows["rul"].append(eol - signals.t[k])
        rows["low"].append(low - signals.t[k])
        rows["high"].append(high - signals.t[k])
        rows["best"].append(int(np.argmax(est.log_evidence[0])) - 1 == j)
    return {key: np.array(value) for key, value in rows.items()}


def evaluate(scenario: Scenario, signals: Signals, run: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Errors over [onset + 10 s, EoL]; cone hits and interval coverage at the 50-90 % prediction times."""
    onset, eol = true_end_of_life(scenario)
    t = signals.t
    window = (t >= onset + 10.0) & (t <= eol)
    truth = signals.truth[:, scenario.model.parameter_names.index(fault_parameter(scenario))]
    error = np.abs(run["value"] - truth)[window]
    fraction = (t - onset) / (eol - onset)
    predict = (fraction >= 0.5) & (fraction <= 0.9)
    rul_true = eol - t[predict]
    rul = run["rul"][predict]
    hit = (rul >= 0.8 * rul_true) & (rul <= 1.2 * rul_true)
    covered = (run["low"][predict] <= rul_true) & (rul_true <= run["high"][predict]) & np.isfinite(run["high"][predict])
    return {"error": error, "hit": hit, "covered": covered, "best": run["best"][window]}


def accuracy(seeds: range, config: TrackingConfig, names: tuple[str, ...] = NAMES) -> dict[str, dict[str, np.ndarray]]:
    """Pooled ``evaluate`` results per fault parameter over ``seeds`` (offsets i: sensor seed + 100 i)."""
    results: dict[str, dict[str, np.ndarray]] = {}
    for name in names:
        scenario = load_scenario(SCENARIOS / f"{name}.json")
        runs = (scenario_signals(scenario, scenario.sensor_seed + 100 * i) for i in seeds)
        parts = [evaluate(scenario, s, track_run(scenario, s, config)) for s in runs]
        results[fault_parameter(scenario)] = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    return results


def print_table(results: dict[str, dict[str, np.ndarray]]) -> None:
    print("| parameter | median / max error | UKF | alpha-lambda | UKF | coverage | UKF | true hypothesis best |")
    print("|---|---|---|---|---|---|---|---|")
    for p, r in results.items():
        ukf = UKF[p]
        print(
            f"| {p} | {np.median(r['error']):.4g} / {np.max(r['error']):.4g} | {ukf[0]} / {ukf[1]} | {r['hit'].mean():.2f} | {ukf[2]:.2f} "
            f"| {r['covered'].mean():.2f} | {ukf[3]:.2f} | {r['best'].mean():.2f} |"
        )


def speed(n_systems: int, repeats: int = 20) -> float:
    """Seconds per update of N systems x 3 hypotheses (+ "none") on 1 s steps at 100 Hz."""
    scenario = load_scenario(SCENARIOS / "spring_k_ramp.json")
    signals = scenario_signals(scenario, 0)
    estimator = TrackingEstimator(scenario.model, scenario.sample_rate, scenario.noise, n_systems)
    suspects = np.ones((n_systems, 3), dtype=bool)
    alarm = np.ones(n_systems, dtype=bool)

    def step(k: int) -> StepSignals:
        tile = (n_systems, 1, 1)
        return StepSignals(
            np.tile(signals.measured[k], tile), np.tile(signals.load[k], tile[:2]), np.tile(signals.load_rate[k], tile[:2]),
            np.full(n_systems, signals.t[k]),
        )

    steps = [step(k) for k in range(repeats + 1)]
    estimator.update(steps[0], alarm, suspects)  # compile / warm up
    start = time.perf_counter()
    for s in steps[1:]:
        estimator.update(s, alarm, suspects)
    return (time.perf_counter() - start) / repeats


#: The tuning grid: (theta_prior, drift_prior) x drift_noise x theta_noise, on the tuning seeds 10..49.
TUNING_PRIORS = ((1e-3, 1e-4), (0.02, 1e-3))
TUNING_DRIFT_NOISE = (3e-5, 4e-5)
TUNING_THETA_NOISE = (3e-5, 1e-4)
TUNING_SEEDS = range(10, 50)


def tune() -> None:
    """The tuning grid on the tuning seeds of the three ramps; prints each setting's scores."""
    base = TrackingConfig()
    for (theta_prior, drift_prior), drift_noise, theta_noise in itertools.product(TUNING_PRIORS, TUNING_DRIFT_NOISE, TUNING_THETA_NOISE):
        config = replace(base, theta_prior=theta_prior, drift_prior=drift_prior, theta_noise=theta_noise, drift_noise=drift_noise)
        results = accuracy(TUNING_SEEDS, config)
        scores = "; ".join(
            f"{p} {np.median(r['error']):.4f}/{np.max(r['error']):.4f} al {r['hit'].mean():.3f} cov {r['covered'].mean():.2f}"
            for p, r in results.items()
        )
        setting = f"theta_prior {theta_prior:g} drift_prior {drift_prior:g} theta_noise {theta_noise:g} drift_noise {drift_noise:g}"
        print(f"{setting}: {scores}", flush=True)


def ramp_scenario(system: str, parameter: str | None, seed: int) -> Scenario:
    """A random-load run of a built-in: ``parameter`` ramping from nominal at 10 s to 2 % past its limit
    at 110 s (the limit it leaves is the lower one for a stiffness-like part that weakens: k), or none."""
    model = get_model(system)
    spec: dict = {
        "system": system, "duration": 110.0, "sensors": {"noise": 0.01, "seed": seed},
        "load": {
            "kind": "random", "mean": model.nominal_load, "std": 0.3 * model.nominal_load, "bandwidth": model.excitation_bandwidth, "seed": seed,
        },
    }
    if parameter is not None:
        nominal, (lower, upper) = model.nominal[parameter], model.safe_limits[parameter]
        end = 0.98 * lower if parameter == "k" else 1.02 * upper
        spec["fault"] = {"parameter": parameter, "profile": [[0, nominal], [10, nominal], [110, end]]}
    return load_scenario(spec)


def systems_table(seed: int = 5) -> None:
    """Every built-in's every degradable parameter, ramped under a random load (1 % noise): relative
    errors, cone hits, coverage, true hypothesis best; and which hypothesis a fault-free run favours."""
    print("| system | parameter | median / max relative error | alpha-lambda | coverage | true hypothesis best |")
    print("|---|---|---|---|---|---|")
    for system in ("spring_mass_damper", "rlc_circuit", "dc_motor"):
        model = get_model(system)
        for parameter in model.safe_limits:
            scenario = ramp_scenario(system, parameter, seed)
            signals = scenario_signals(scenario, seed)
            r = evaluate(scenario, signals, track_run(scenario, signals, TrackingConfig()))
            nominal = model.nominal[parameter]
            print(
                f"| {system} | {parameter} | {np.median(r['error']) / nominal:.4f} / {np.max(r['error']) / nominal:.4f} | {r['hit'].mean():.2f} "
                f"| {r['covered'].mean():.2f} | {r['best'].mean():.2f} |"
            )
        scenario = ramp_scenario(system, None, seed)
        estimator = TrackingEstimator(model, scenario.sample_rate, scenario.noise, 1)
        signals = scenario_signals(scenario, seed)
        for k in range(len(signals.t)):
            step = StepSignals(signals.measured[k], signals.load[k], signals.load_rate[k], signals.t[k : k + 1])
            evidence = estimator.update(step, np.zeros(1, dtype=bool), np.ones((1, len(estimator.degradable)), dtype=bool)).log_evidence[0]
        names = ("none",) + estimator.degradable
        print(f"| {system} | fault-free | best evidence at {signals.t[-1]:.0f} s: {names[int(np.argmax(evidence))]}, "
              f"log-evidence over none: {', '.join(f'{n} {e - evidence[0]:+.1f}' for n, e in zip(names[1:], evidence[1:]))} | | | |")


def wear_profile(process: str, parameter: str, rng: np.random.Generator) -> tuple[list[list[float]], float, float]:
    """A fault profile (1 s points) like the environment's ``Wear``: arrival at 20 s, a random direction, a
    mean rate of 0.5-1.5 % of the way to the limit per s, volatility 0.3; and that rate and limit."""
    model = get_model("spring_mass_damper")
    nominal, (lower, upper) = model.nominal[parameter], model.safe_limits[parameter]
    limit = upper if rng.random() < 0.5 else lower
    velocity = rng.uniform(0.005, 0.015) * (limit - nominal)
    times = np.arange(0.0, np.ceil(20.0 + 1.3 * (limit - nominal) / velocity) + 1.0)
    values = [nominal]
    for t in times[1:]:
        mean = velocity if t > 20.0 else 0.0
        if process == "linear" or mean == 0.0:
            increment = mean
        elif process == "wiener":
            increment = mean + 0.3 * abs(velocity) * np.sqrt(10.0) * rng.standard_normal()
        else:  # gamma: the std over 10 s is 0.3 x its mean
            scale = (0.3 * velocity * 10.0) ** 2 / 10.0 / abs(mean)
            increment = np.sign(mean) * rng.gamma(abs(mean) / scale, scale)
        values.append(values[-1] + increment)
    return [[float(t), float(v)] for t, v in zip(times, values)], velocity, limit


def wear_table(config: TrackingConfig, runs: int = 6) -> None:
    """RUL past half-way to the limit (the environment's acceptance regime) under linear, Wiener and
    gamma wear with random loads: median relative error against the mean trend's RUL, and coverage."""
    model = get_model("spring_mass_damper")
    print(f"theta_noise {config.theta_noise:g}, drift_noise {config.drift_noise:g}")
    print("| wear | parameter | RUL median relative error | interval coverage | steps |\n|---|---|---|---|---|")
    for process, parameter in itertools.product(("linear", "wiener", "gamma"), ("k", "m", "b")):
        errors, covered = [], []
        for seed in range(runs):
            profile, velocity, limit = wear_profile(process, parameter, np.random.default_rng(1000 + seed))
            scenario = ramp_scenario("spring_mass_damper", None, seed)
            scenario = load_scenario({**scenario.to_dict(), "duration": profile[-1][0], "fault": {"parameter": parameter, "profile": profile}})
            signals = scenario_signals(scenario, seed)
            estimator = TrackingEstimator(model, scenario.sample_rate, scenario.noise, 1, config=config)
            prognosis = chain_prognosis(estimator)
            j, nominal = estimator.degradable.index(parameter), model.nominal[parameter]
            truth = signals.truth[:, model.parameter_names.index(parameter)]
            for k in range(len(signals.t)):
                step = StepSignals(signals.measured[k], signals.load[k], signals.load_rate[k], signals.t[k : k + 1])
                est = estimator.update(step, np.ones(1, dtype=bool), np.ones((1, 3), dtype=bool))
                if 0.5 <= (truth[k] - nominal) / (limit - nominal) < 1.0:
                    rul = (limit - truth[k]) / velocity
                    eol, low, high = (end - signals.t[k] for end in end_of_life(prognosis, est, j, signals.t[k : k + 1]))
                    errors.append(abs(eol - rul) / rul)
                    covered.append(low <= rul <= high)
        print(f"| {process} | {parameter} | {np.median(errors):.3f} | {np.mean(covered):.2f} | {len(errors)} |", flush=True)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tune", action="store_true", help="process-noise and prior grid on the tuning seeds 10..49 instead of the table")
    parser.add_argument("--systems", action="store_true", help="every built-in's parameters under random loads instead of the table")
    parser.add_argument("--wear", type=float, metavar="THETA_NOISE", help="RUL under the environment's wear processes, at this theta_noise")
    parser.add_argument("--seeds", type=int, default=5, help="the table's evaluation seeds 0..SEEDS-1 (default 5)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 256], help="numbers of systems N timed (default 1 256)")
    args = parse_with_smoke(parser, argv, SMOKE)
    if args.tune:
        tune()
        return
    if args.systems:
        systems_table()
        return
    if args.wear is not None:
        wear_table(replace(TrackingConfig(), theta_noise=args.wear))
        return
    print_table(accuracy(range(args.seeds), TrackingConfig()))
    for n in args.sizes:
        seconds = speed(n)
        print(f"N = {n:3d} systems x 3 hypotheses (+ none): {1e3 * seconds:.3f} ms per 1 s step ({n / seconds:.0f} system-steps/s)")


if __name__ == "__main__":
    main()
