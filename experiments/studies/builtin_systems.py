"""Isolation, false beliefs, estimate errors and false alarms of the PHM chain on every built-in system.

For spring_mass_damper (k, m, b), rlc_circuit (R1, L1, C1, R2) and dc_motor (Ra, La, K, J, bm): per
degradable parameter, ``--runs`` runs (default 20) under random loads drawn as the fault database draws
them (``ea_gym.diagnosis.database.draw_loads``), 1 % sensor noise, that parameter ramping linearly from
nominal at ``ONSET`` s to a safe limit (upper or lower, drawn per run) at the end of the run; and
``--runs`` fault-free runs per system. Each system's runs go through one batched chain
(``ea_gym.phm.build_chain`` with the shipped classifier, thresholds calibrated at the noise,
``PHMConfig.estimator_kind`` from ``--estimator``; ``ea_gym.phm.run_signals``, noise added step by step).

Recorded per system and parameter:

* detected: runs with an alarm by the end;
* isolated at the end: runs whose ``isolated`` parameter at the last step is the ramped one;
* right suspect: share of the post-detection steps (pooled over runs) whose ``isolated`` parameter is it;
* largest wrong belief: the largest belief (fused ``diagnosis``) ever put on another component
  (target: never >= 0.8); run-steps whose belief is not finite (NaN) are counted apart;
* estimate error: median over post-detection steps of |estimate - truth| / nominal for the ramped
  parameter, the truth taken at the time the estimate describes (``ParameterEstimates.time``);
* fault-free: runs that raised an alarm (target: none).

Targets (issue 17): isolated in >= 95 % of the runs, never a belief >= 0.8 on a wrong component, no
alarm on fault-free runs. Writes results.json, table.md (README-ready) and isolation.png into
experiments/results/builtin_systems/<estimator>/.

    python experiments/studies/builtin_systems.py                     # 20 runs of 100 s per parameter
    python experiments/studies/builtin_systems.py --estimator tracking
    python experiments/studies/builtin_systems.py --smoke             # 2 runs of 40 s, spring_mass_damper only
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's ea_gym and experiments.common, installed or not

from ea_gym.diagnosis.database import draw_loads
from ea_gym.files import json_ready, save_figure, write_json, write_text
from ea_gym.models import SystemModel, get_model
from ea_gym.phm import ESTIMATORS, ChainTiming, HealthStatus, PHMConfig, build_chain, classifier_for, run_signals
from ea_gym.plant import run_model
from ea_gym.pyplot import plt
from ea_gym.sensors import add_sensor_noise
from experiments.common import parse_with_smoke

SYSTEMS = ("spring_mass_damper", "rlc_circuit", "dc_motor")
RESULTS = Path(__file__).resolve().parents[1] / "results" / "builtin_systems"
NOISE = 0.01  # fraction of each signal's RMS
ONSET = 10.0  # s: the ramp's start
TARGETS = {"isolated": 0.95, "wrong_belief": 0.8, "fault_free_alarms": 0}
#: the smoke run: 2 runs of 40 s per parameter, spring_mass_damper unless --systems says otherwise
SMOKE = {"runs": 2, "duration": 40.0, "systems": ["spring_mass_damper"]}


def ramp(model: SystemModel, parameter: str | None, limit: float, duration: float) -> Any:
    """Parameters at times t (T, P): ``parameter`` linear from nominal at ONSET to ``limit`` at ``duration``."""
    nominal = model.parameter_vector()

    def parameters_at(t: np.ndarray) -> np.ndarray:
        values = np.repeat(nominal[None], len(t), 0)
        if parameter is not None:
            j = model.parameter_names.index(parameter)
            progress = np.clip((np.asarray(t) - ONSET) / (duration - ONSET), 0.0, 1.0)
            values[:, j] = nominal[j] + (limit - nominal[j]) * progress
        return values

    return parameters_at


def plan(model: SystemModel, runs: int, rng: np.random.Generator) -> list[tuple[str | None, float]]:
    """The runs of a system: (ramped parameter or None, the limit it heads for), ``runs`` per parameter, then fault-free."""
    rows: list[tuple[str | None, float]] = []
    for name, (lower, upper) in model.safe_limits.items():
        rows += [(name, upper if rng.random() < 0.5 else lower) for _ in range(runs)]
    return rows + [(None, float("nan"))] * runs


def run_system(system: str, estimator: str, runs: int, duration: float, seed: int) -> tuple[list[tuple[str | None, float]], list[HealthStatus], Any]:
    """Simulate a system's runs and feed them through one batched chain; the plan, statuses and ramps."""
    model = get_model(system)
    rng = np.random.default_rng(seed)
    rows = plan(model, runs, rng)
    config = PHMConfig(timing=ChainTiming(noise=NOISE), estimator_kind=estimator)
    chain = build_chain(model, config, classifier_for(model), rng, n_systems=len(rows))
    t = np.arange(int(round(duration * config.timing.sample_rate)) + 1) / config.timing.sample_rate
    loads = draw_loads(model, len(rows), rng)
    ramps = [ramp(model, parameter, limit, duration) for parameter, limit in rows]
    clean = []
    for load, parameters_at in zip(loads, ramps):
        plant = run_model(model, t, load, parameters_at)
        clean.append(chain.sensors.measure(plant.parameters[None], plant.states[None], 0.0, rng)[0])
    u = np.stack([load.value(t) for load in loads])
    du = np.stack([load.derivative(t) for load in loads])
    statuses = run_signals(chain, np.stack(clean), u, du, noise=lambda chunk: add_sensor_noise(chunk, NOISE, rng))
    return rows, statuses, ramps


def parameter_metrics(model: SystemModel, rows: Sequence[int], j: int, statuses: Sequence[HealthStatus], ramps: Sequence[Any]) -> dict[str, Any]:
    """Metrics of the runs ``rows`` that ramp degradable parameter j (index into the fault classes less "none")."""
    alarm = np.stack([s.alarm[rows] for s in statuses])  # (steps, runs)
    isolated = np.stack([s.isolated[rows] for s in statuses])
    belief = np.stack([s.diagnosis[rows] for s in statuses])  # (steps, runs, K)
    right = 1 + j
    wrong = np.delete(belief[..., 1:], j, axis=-1)
    name = model.parameter_names.index(list(model.safe_limits)[j])
    nominal = model.parameter_vector()[name]
    errors = []
    for row in rows:
        for s in statuses:
            if s.alarm[row]:
                truth = ramps[row](np.array([s.estimation.time[row, j]]))[0, name]
                errors.append(abs(s.estimates[row, j] - truth) / nominal)
    return {
        "runs": len(rows), "detected": float(alarm[-1].mean()), "isolated": float(np.mean(isolated[-1] == right)),
        "right_suspect": float(np.mean(isolated[alarm] == right)) if alarm.any() else None,
        "wrong_belief": float(np.nanmax(wrong, initial=0.0)),
        "invalid_belief_steps": int(np.sum(~np.isfinite(belief).all(-1))),
        "estimate_error": float(np.median(errors)) if errors else None,
        "detection_time": float(np.nanmedian([s for s in statuses[-1].detection_time[rows]])) if alarm[-1].any() else None,
    }


def system_metrics(system: str, rows: list[tuple[str | None, float]], statuses: list[HealthStatus], ramps: Sequence[Any]) -> dict[str, Any]:
    """Every parameter's metrics and the fault-free runs' alarms and largest belief on a fault."""
    model = get_model(system)
    result: dict[str, Any] = {"parameters": {}}
    for j, name in enumerate(model.safe_limits):
        mine = [i for i, (parameter, _) in enumerate(rows) if parameter == name]
        result["parameters"][name] = parameter_metrics(model, mine, j, statuses, ramps)
    free = [i for i, (parameter, _) in enumerate(rows) if parameter is None]
    ever = np.any(np.stack([s.alarm[free] for s in statuses]), axis=0)
    result["fault_free"] = {
        "runs": len(free), "alarms": int(ever.sum()),
        "largest_fault_belief": float(np.nanmax(np.stack([s.diagnosis[free, 1:] for s in statuses]), initial=0.0)),
    }
    return result


def measure_all(estimator: str, systems: Sequence[str], runs: int, duration: float, seed: int) -> dict[str, Any]:
    result: dict[str, Any] = {"estimator": estimator, "runs": runs, "duration": duration, "noise": NOISE, "onset": ONSET,
                              "seed": seed, "targets": TARGETS, "systems": {}}
    for k, system in enumerate(systems):
        started = time.perf_counter()
        rows, statuses, ramps = run_system(system, estimator, runs, duration, seed + k)
        result["systems"][system] = {**system_metrics(system, rows, statuses, ramps), "seconds": time.perf_counter() - started}
        print(f"{system}: {result['systems'][system]}", flush=True)
    return result


def table(result: dict[str, Any]) -> str:
    """README-ready markdown: one row per system and parameter, one per system's fault-free runs."""
    def cell(value: float | None, spec: str) -> str:
        return "n/a" if value is None else format(value, spec)

    lines = [
        f"Estimator `{result['estimator']}`: {result['runs']} random-load runs of {result['duration']:g} s per parameter at "
        f"{100 * result['noise']:g} % noise, the parameter ramping from nominal at {result['onset']:g} s to a safe limit at the end.",
        "",
        "| system | parameter | detected | isolated at the end | right suspect after detection | largest wrong belief "
        "| median estimate error / nominal | fault-free runs with an alarm |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for system, s in result["systems"].items():
        for name, m in s["parameters"].items():
            flag = " (!)" if m["wrong_belief"] >= TARGETS["wrong_belief"] else ""
            flag += f" ({m['invalid_belief_steps']} run-steps NaN)" if m["invalid_belief_steps"] else ""
            lines.append(
                f"| {system} | {name} | {m['detected']:.2f} | {m['isolated']:.2f} | {cell(m['right_suspect'], '.2f')} "
                f"| {m['wrong_belief']:.2f}{flag} | {cell(m['estimate_error'], '.3f')} | |"
            )
        free = s["fault_free"]
        lines.append(f"| {system} | fault-free | | | | | | {free['alarms']} of {free['runs']} |")
    return "\n".join(lines) + "\n"


def figure(result: dict[str, Any]) -> Any:
    """Isolation at the end and the largest wrong belief per parameter, the targets as lines."""
    labels, isolated, wrong = [], [], []
    for system, s in result["systems"].items():
        for name, m in s["parameters"].items():
            labels.append(f"{system.split('_')[0]} {name}")
            isolated.append(m["isolated"])
            wrong.append(m["wrong_belief"])
    x = np.arange(len(labels))
    fig, ax = plt.subplots(figsize=(max(6.0, 0.6 * len(labels)), 3.8))
    ax.bar(x - 0.2, isolated, 0.4, label="isolated at the end")
    ax.bar(x + 0.2, wrong, 0.4, label="largest wrong belief")
    ax.axhline(TARGETS["isolated"], color="C0", ls="--", lw=0.8, label="isolation target")
    ax.axhline(TARGETS["wrong_belief"], color="C1", ls=":", lw=0.8, label="wrong-belief ceiling")
    ax.set(xticks=x, ylim=(0, 1.05), title=f"Built-in systems, estimator {result['estimator']}")
    ax.set_xticklabels(labels, rotation=45, ha="right")
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    return fig


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--estimator", default=PHMConfig().estimator_kind, choices=sorted(ESTIMATORS), help="the chain's parameter estimator")
    parser.add_argument("--systems", nargs="+", choices=SYSTEMS, default=list(SYSTEMS), help="which built-ins (default all)")
    parser.add_argument("--runs", type=int, default=20, help="runs per parameter and fault-free runs per system (default 20)")
    parser.add_argument("--duration", type=float, default=100.0, help="seconds per run (default 100)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the first system (the next ones add 1)")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default experiments/results/builtin_systems/<estimator>)")
    args = parse_with_smoke(parser, argv, SMOKE)
    if args.runs < 1:
        parser.error(f"--runs must be >= 1, got {args.runs}")
    if not args.duration > 2 * ONSET:
        parser.error(f"--duration must be > {2 * ONSET:g} s, got {args.duration}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    result = measure_all(args.estimator, args.systems, args.runs, args.duration, args.seed)
    out = args.out if args.out is not None else RESULTS / args.estimator
    write_json(out / "results.json", json_ready(result))
    write_text(out / "table.md", table(result))
    save_figure(figure(result), out / "isolation.png")
    print(table(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
