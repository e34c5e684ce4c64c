"""Side by side on identical signals: the "joint" filter and ProgPy 1.9's UKF, each estimating every parameter jointly (issue 30, item 2).

Multi-fault cases on the spring-mass-damper: two or three parts ramping with overlapping onsets at
different rates (``CASES``), seeds 0..4 (each its own band-limited random load, ``draw_loads``, and
sensor noise), 200 s at 100 Hz, 1 % sensor noise of each 1 s step's RMS. The plant (``run_model``) is
simulated once per (case, seed) and the same noisy samples go to:

* the joint filter (``ea_gym.phm.JointFilter``, its default ``JointFilterConfig``), step by step;
* ProgPy's UnscentedKalmanFilter with k, m, b and their drifts as states, told nothing about which
  degrade (``experiments/studies/compare_progpy.py``'s ``run_ukf``: its model, prior and the drift
  noise that script chose on its tuning seeds, 3e-5).

Metrics: each parameter's absolute estimate error at the end of every step from 10 s after the case's
first onset to the end, median over all seeds' steps (the target: the joint filter's <= 1.5 x the
UKF's); "set named": the share of steps from 30 s after the last onset at which the parts whose
P(|drift| > ``JointFilterConfig.degrading_rate`` x the safe span per s) exceeds 0.5 are exactly the
ramping ones (the same rule on both filters' drift and its variance); each filter's run time per
record and per 1 s step (one process, one core).

    python experiments/studies/joint_filter.py          # -> experiments/results/joint_filter/
    python experiments/studies/joint_filter.py --smoke  # one case, one seed, 110 s, the UKF at 20 Hz
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's ea_gym and experiments, installed or not

from ea_gym.diagnosis.database import draw_loads
from ea_gym.energy import window_samples
from ea_gym.files import json_ready, write_json, write_text
from ea_gym.models import SystemModel, spring_mass_damper
from ea_gym.phm import JointFilter, JointFilterConfig, StepSignals
from ea_gym.phm.joint import degrading_probability
from ea_gym.plant import run_model
from ea_gym.sensors import Sensors, add_sensor_noise
from experiments.common import machine_info, parse_with_smoke
from experiments.studies.compare_progpy import FilterSettings, Signals, run_ukf

#: case -> (parameter, onset s, rate unit/s): k at 3e-3, b at 3e-3, m at 2.5e-3 of their safe span per s
CASES: dict[str, tuple[tuple[str, float, float], ...]] = {
    "k+b": (("k", 40.0, -0.06), ("b", 70.0, 6e-4)),
    "k+m": (("k", 40.0, -0.06), ("m", 55.0, 5e-3)),
    "k+m+b": (("k", 40.0, -0.06), ("m", 55.0, 5e-3), ("b", 70.0, 6e-4)),
}
RATE = 100.0  # Hz
NOISE = 0.01
STEP = 1.0  # s
SETTLE = 10.0  # s after the first onset from which estimate errors count
SET_SETTLE = 30.0  # s after the last onset from which the named set counts
SEED_SHIFT = 1000  # the records' generators are seeded 1000 + seed: apart from the tests' and the tuning's
SMOKE = {"cases": ["k+b"], "seeds": [0], "duration": 110.0, "ukf_rate": 20.0}
JOINT, UKF = "joint filter", "ProgPy UKF (all parameters)"


def record(model: SystemModel, faults: Sequence[tuple[str, float, float]], seed: int, duration: float) -> Signals:
    """The plant under ramps ``faults`` (``run_model``), measured and noised step by step, for every filter."""
    rng = np.random.default_rng(SEED_SHIFT + seed)
    t = np.arange(int(round(duration * RATE)) + 1) / RATE
    load = draw_loads(model, 1, rng)[0]
    names = list(model.parameter_names)

    def parameters(times: np.ndarray) -> np.ndarray:
        values = np.repeat(model.parameter_vector()[None], len(times), axis=0)
        for name, onset, slope in faults:
            values[:, names.index(name)] += slope * np.maximum(times - onset, 0.0)
        return values

    plant = run_model(model, t, load, parameters)
    clean = Sensors(model).measure(plant.parameters[None], plant.states[None], 0.0, rng)[0]
    step = window_samples(STEP, 1.0 / RATE)
    windows = np.stack([add_sensor_noise(clean[:, s : s + step + 1], NOISE, rng) for s in range(0, len(t) - step, step)])
    # ``expected`` (the nominal model's signals) is read by neither filter: the clean signals stand in
    return Signals(t, clean, windows, clean, load.value(t), load.derivative(t), plant.parameters, step)


def run_joint(model: SystemModel, signals: Signals) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The joint filter over the record: value (S, D), drift and its variance (S, D) at every step's end; its run time (s)."""
    joint = JointFilter(model, RATE, NOISE)
    step, values, drifts, variances = signals.step, [], [], []
    began = time.perf_counter()
    for k, window in enumerate(signals.windows):
        part = slice(k * step, (k + 1) * step + 1)
        estimates = joint.update(
            StepSignals(window[None], signals.load[None, part], signals.load_rate[None, part], signals.t[None, (k + 1) * step]),
            np.zeros(1, dtype=bool), np.ones((1, len(joint.degradable)), dtype=bool),
        )
        values.append(estimates.value[0])
        drifts.append(estimates.drift[0])
        variances.append(estimates.drift_variance[0])
    return np.array(values), np.array(drifts), np.array(variances), time.perf_counter() - began


def score(model: SystemModel, faults: Sequence[tuple[str, float, float]], signals: Signals, value: np.ndarray,
          probability: np.ndarray, names: Sequence[str]) -> dict[str, Any]:
    """One filter on one record: absolute errors per parameter in the error window, and whether the named set was right per step."""
    ends = signals.t[signals.step :: signals.step][: len(value)]
    index = np.round(ends * RATE).astype(int)
    columns = [list(model.parameter_names).index(name) for name in names]
    truth = signals.truth[index][:, columns]
    first, last = min(f[1] for f in faults), max(f[1] for f in faults)
    window = ends >= first + SETTLE - 1e-9
    ramping = np.array([name in {f[0] for f in faults} for name in names])
    named = probability > 0.5
    counted = ends >= last + SET_SETTLE - 1e-9
    return {
        "errors": {name: np.abs(value[window, j] - truth[window, j]) for j, name in enumerate(names)},
        "set_right": np.all(named[counted] == ramping, axis=1),
    }


def run_case(model: SystemModel, case: str, seed: int, duration: float, ukf: FilterSettings) -> dict[str, dict[str, Any]]:
    """Both filters on one (case, seed)'s record."""
    faults = CASES[case]
    signals = record(model, faults, seed, duration)
    config = JointFilterConfig()
    value, drift, variance, seconds = run_joint(model, signals)
    names = JointFilter(model, RATE, NOISE).degradable
    limits = np.array([model.safe_limits[name] for name in names])
    rate = config.degrading_rate * (limits[:, 1] - limits[:, 0])
    steps = len(signals.windows)
    out = {JOINT: {**score(model, faults, signals, value, degrading_probability(drift, variance, rate), names), "seconds": seconds, "steps": steps}}
    began = time.perf_counter()
    filtered = run_ukf(model, signals, NOISE, names, ukf)
    seconds = time.perf_counter() - began
    slots = [filtered.states.index(name) for name in names]
    u_value, u_drift = filtered.mean[:, slots], filtered.mean[:, [s + 1 for s in slots]]
    u_variance = filtered.covariance[:, [s + 1 for s in slots], [s + 1 for s in slots]]
    out[UKF] = {**score(model, faults, signals, u_value, degrading_probability(u_drift, u_variance, rate), names), "seconds": seconds, "steps": steps}
    return out


def summarise(runs: list[dict[str, dict[str, Any]]], names: Sequence[str]) -> dict[str, dict[str, Any]]:
    """Per filter: each parameter's median (and 95th percentile) absolute error over all runs' steps, the set named right, times."""
    summary = {}
    for method in (JOINT, UKF):
        errors = {name: np.concatenate([run[method]["errors"][name] for run in runs]) for name in names}
        seconds = np.array([run[method]["seconds"] for run in runs])
        steps = np.array([run[method]["steps"] for run in runs])
        summary[method] = {
            "error_median": {name: float(np.median(e)) for name, e in errors.items()},
            "error_p95": {name: float(np.percentile(e, 95)) for name, e in errors.items()},
            "set_right": float(np.concatenate([run[method]["set_right"] for run in runs]).mean()),
            "seconds_per_record": float(seconds.mean()),
            "ms_per_step": float(1000 * seconds.sum() / steps.sum()),
        }
    return summary


def table(summaries: dict[str, dict[str, dict[str, Any]]], names: Sequence[str], seeds: Sequence[int]) -> str:
    """The markdown table: per case and parameter, both filters' median errors and their ratio; set named; times."""
    lines = [
        f"# Joint estimation of every parameter: the joint filter vs ProgPy's UKF (spring_mass_damper, 1 % noise, seeds {list(seeds)})",
        "",
        "| case | parameter | ramping | joint median abs error | UKF median abs error | ratio (target <= 1.5) |",
        "|---|---|---|---|---|---|",
    ]
    for case, summary in summaries.items():
        ramping = {f[0] for f in CASES[case]}
        for name in names:
            joint, ukf = summary[JOINT]["error_median"][name], summary[UKF]["error_median"][name]
            lines.append(f"| {case} | {name} | {'yes' if name in ramping else 'no'} | {joint:.4g} | {ukf:.4g} | {joint / ukf:.2f} |")
    lines += ["", "| case | filter | set named exactly | s per record | ms per 1 s step |", "|---|---|---|---|---|"]
    for case, summary in summaries.items():
        for method in (JOINT, UKF):
            row = summary[method]
            lines.append(f"| {case} | {method} | {row['set_right']:.3f} | {row['seconds_per_record']:.2f} | {row['ms_per_step']:.2f} |")
    return "\n".join(lines) + "\n"


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cases", nargs="+", choices=list(CASES), default=list(CASES), help="which multi-fault cases (default all)")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4], help="record seeds (default 0..4)")
    parser.add_argument("--duration", type=float, default=200.0, help="record length (s)")
    parser.add_argument("--ukf-rate", type=float, default=RATE, help="UKF steps per s (Hz), a divisor of the sample rate")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "results" / "joint_filter", help="output folder")
    return parse_with_smoke(parser, argv, SMOKE)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    model = spring_mass_damper()
    names = JointFilter(model, RATE, NOISE).degradable
    ukf = FilterSettings(rate=args.ukf_rate)
    summaries = {}
    for case in args.cases:
        runs = []
        for seed in args.seeds:
            runs.append(run_case(model, case, seed, args.duration, ukf))
            print(f"{case} seed {seed}: joint {runs[-1][JOINT]['seconds']:.1f} s, UKF {runs[-1][UKF]['seconds']:.1f} s", flush=True)
        summaries[case] = summarise(runs, names)
    markdown = table(summaries, names, args.seeds)
    command = "python experiments/studies/joint_filter.py" + (" --smoke" if args.smoke else "")
    write_text(args.out / "table.md", markdown + f"\nMade by `{command}`; see its docstring for the metrics.\n")
    write_json(args.out / "results.json", json_ready({
        "arguments": {**vars(args), "out": str(args.out)}, "cases": {case: CASES[case] for case in args.cases},
        "ukf": vars(ukf), "summary": summaries, "machine": machine_info(),
    }))
    print(markdown)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
