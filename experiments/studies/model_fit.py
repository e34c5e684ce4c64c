"""Data the model cannot explain: the model-fit test (``ea_gym.phm.fit``) on records made outside ea-gym.

Every record comes from an independent ODE (``scipy.integrate.solve_ivp`` on each system's equations written
out here, not ea-gym's simulator) under a multisine (five tones) or a band-limited random load (forty tones of
random amplitude and phase) within the model's excitation band, around its nominal load, with 1 % sensor noise
(std a fraction of each signal's RMS over each second). It is written as a measurement CSV and run through
``ea-gym phm --system MODEL --measurements CSV --noise 0.01 --out DIR`` (the CLI's ``main``, in process).
Systems: spring_mass_damper, rlc_circuit, dc_motor and the two-mass model file
``experiments/models/two_mass_chain.yaml``. Cases:

* healthy: the machine is the model, the record is right: ``model_fit.ok`` should be true;
* unit: the load column in kN where the model reads N (its values 1000 x too small);
* time base: the data sampled at 200 Hz, its t column saying 100 Hz;
* form: the model file's C element (the first) with its ``form`` flipped (compliance <-> stiffness), the
  value unchanged; dc_motor has no C element (n/a).

A misfit case passes when ``model_fit.ok`` is false, no part is isolated and no End of Life is given; a
healthy one when ``ok`` is true.

The other side: today's single-fault scenarios (``experiments/scenarios/*.json``), each written as a CSV by
``ea-gym simulate SCENARIO --csv F`` and run through the chain on that record (as ``ea-gym phm --system
... --measurements F`` does, at the scenario's noise) with the test on and off: ``ok``, detection time,
isolated parameter and End-of-Life predictions side by side.

Writes results.json and table.md into experiments/results/model_fit/.

    python experiments/studies/model_fit.py            # 4 systems x 4 cases x 2 loads x 5 seeds, 40 s records
    python experiments/studies/model_fit.py --smoke    # spring_mass_damper, 1 seed, one load, 25 s; one scenario
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's ea_gym and experiments.common, installed or not

from ea_gym.cli import main as ea_gym_main
from ea_gym.diagnosis.training import cached_isolation_path, isolation_network, shipped_classifier_path
from ea_gym.files import json_ready, write_json, write_text
from ea_gym.model_files import load_system
from experiments.common import ROOT, machine_info, parse_with_smoke

RESULTS = Path(__file__).resolve().parents[1] / "results" / "model_fit"
TWO_MASS = ROOT / "experiments" / "models" / "two_mass_chain.yaml"
SYSTEMS = ("spring_mass_damper", "rlc_circuit", "dc_motor", "two_mass_chain")
CASES = ("healthy", "unit", "time_base", "form")
LOADS = ("multisine", "random")
NOISE = 0.01
RATE = 100.0  # Hz: the t column's rate
SCENARIOS = ROOT / "experiments" / "scenarios"
SMOKE = {"systems": ["spring_mass_damper"], "seeds": 1, "loads": ["multisine"], "duration": 25.0, "scenarios": ["mass_m_ramp"]}

#: each system's equations in its measured signals' order (flows of I, displacements of C), nominal values:
#: (state, load) -> derivative
Equations = Callable[[np.ndarray, float], np.ndarray]


def spring_mass_damper(x: np.ndarray, u: float) -> np.ndarray:
    """[v, x]: m v' = F - k x - b v (m 10 kg, k 100 N/m, b 0.5 N s/m)."""
    v, q = x
    return np.array([(u - 100.0 * q - 0.5 * v) / 10.0, v])


def rlc_circuit(x: np.ndarray, u: float) -> np.ndarray:
    """[i, q]: L1 i' = U - R1 i - q / C1, q' = i - q / (C1 R2) (R1 2 ohm, L1 1 H, C1 0.01 F, R2 50 ohm)."""
    i, q = x
    return np.array([u - 2.0 * i - q / 0.01, i - q / (0.01 * 50.0)])


def dc_motor(x: np.ndarray, u: float) -> np.ndarray:
    """[i, w]: La i' = V - Ra i - K w, J w' = K i - bm w (Ra 1 ohm, La 0.05 H, K 0.1, J 0.01, bm 0.001)."""
    i, w = x
    return np.array([(u - i - 0.1 * w) / 0.05, (0.1 * i - 0.001 * w) / 0.01])


def two_mass_chain(x: np.ndarray, u: float) -> np.ndarray:
    """[v1, x1, x12, v2] (m1, k1, k2, m2): the coupling force f = k2 x12 + b2 (v1 - v2);
    m1 v1' = F - k1 x1 - b1 v1 - f, m2 v2' = f (m1 10, k1 100, b1 0.5, k2 50, b2 0.3, m2 5)."""
    v1, x1, x12, v2 = x
    coupling = 50.0 * x12 + 0.3 * (v1 - v2)
    return np.array([(u - 100.0 * x1 - 0.5 * v1 - coupling) / 10.0, v1, v1 - v2, coupling / 5.0])


EQUATIONS: dict[str, Equations] = {
    "spring_mass_damper": spring_mass_damper, "rlc_circuit": rlc_circuit, "dc_motor": dc_motor, "two_mass_chain": two_mass_chain,
}


def system_path(system: str) -> str:
    """What ``--system`` names: the built-in, or the two-mass model file."""
    return str(TWO_MASS) if system == "two_mass_chain" else system


def load_function(kind: str, nominal: float, bandwidth: float, rng: np.random.Generator) -> Callable[[np.ndarray], np.ndarray]:
    """A load around ``nominal`` (its unit) of tones up to ``bandwidth`` Hz: five of equal amplitude ("multisine") or
    forty of random amplitude ("random", band-limited noise); fluctuations of about 30 % of nominal RMS."""
    tones = 5 if kind == "multisine" else 40
    frequency = rng.uniform(0.05, bandwidth, tones)
    amplitude = np.ones(tones) if kind == "multisine" else rng.rayleigh(1.0, tones)
    amplitude *= 0.3 * nominal * np.sqrt(2.0 / np.sum(amplitude**2))
    phase = rng.uniform(0.0, 2.0 * np.pi, tones)

    def load(t: np.ndarray) -> np.ndarray:
        return nominal + np.sum(amplitude * np.sin(2.0 * np.pi * frequency * np.asarray(t)[..., None] + phase), axis=-1)

    return load


def simulate(system: str, load: Callable[[np.ndarray], np.ndarray], duration: float, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """The clean signals (T, nx) at ``rate`` Hz over ``duration`` s from rest, and the time grid."""
    f = EQUATIONS[system]
    t = np.arange(round(duration * rate) + 1) / rate
    nx = len(load_system(system_path(system)).state_names)
    solution = solve_ivp(lambda s, x: f(x, float(load(np.array(s)))), (0.0, t[-1]), np.zeros(nx), t_eval=t, method="DOP853", rtol=1e-10,
                         atol=1e-12, max_step=0.5 / rate)
    return t, solution.y.T


def sensor_noise(signals: np.ndarray, samples: int, rng: np.random.Generator) -> np.ndarray:
    """``signals`` (T, nx) with noise of std NOISE x each signal's RMS over each block of ``samples``."""
    noisy = signals.copy()
    for start in range(0, len(signals), samples):
        block = signals[start : start + samples]
        noisy[start : start + samples] += NOISE * np.sqrt(np.mean(block**2, axis=0)) * rng.standard_normal(block.shape)
    return noisy


def flipped_model(system: str, folder: Path) -> Path | None:
    """A model file of ``system`` with its first C element's form flipped, its value unchanged; None without a C element."""
    model = load_system(system_path(system))
    elements = model.graph.elements
    storage = [name for name in model.state_names if elements[name].kind.value == "C"]
    if not storage:
        return None
    from ea_gym.bondgraph import CForm

    lines = [f"name: {model.name}_flipped", "elements:"]
    # the degradable elements last, in the model's order of limits: the isolation classes' order, the network's
    order = [name for name in elements if name not in model.safe_limits] + list(model.safe_limits)
    for name in order:
        element = elements[name]
        fields = [f"kind: {json.dumps(element.kind.value)}"]
        if name in model.nominal:
            fields.append(f"value: {model.nominal[name]!r}")
        if element.kind.value == "C":
            form = "compliance" if element.c_form is CForm.STIFFNESS else "stiffness"
            if name != storage[0]:
                form = "stiffness" if form == "compliance" else "compliance"
            fields.append(f"form: {form}")
        if name in model.safe_limits:
            fields.append(f"limits: {list(model.safe_limits[name])}")
        lines.append(f"  {name}: {{{', '.join(fields)}}}")
    lines.append("bonds: " + json.dumps([[bond.tail, bond.head] for bond in model.graph.bonds]))
    lines.append(f"load: {{source: {model.load_source}, nominal: {model.nominal_load!r}, bandwidth: {model.excitation_bandwidth!r}}}")
    path = folder / f"{system}_flipped.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def write_record(path: Path, system: str, t: np.ndarray, load: np.ndarray, signals: np.ndarray) -> None:
    """The measurement CSV: t, the load source, every storage element's signal."""
    model = load_system(system_path(system))
    header = ",".join(("t", model.load_source, *model.state_names))
    np.savetxt(path, np.column_stack([t, load, signals]), fmt="%.12g", delimiter=",", header=header, comments="")


def network_path(system: str) -> Path:
    """The isolation network of ``system``'s own model (shipped, or trained once and cached): the flipped model
    file, which has the same parameters under another name, is run with it (``--classifier``)."""
    model = load_system(system_path(system))
    shipped = shipped_classifier_path(model.name)
    if shipped.is_file():
        return shipped
    isolation_network(model)
    return cached_isolation_path(model)


def make_record(system: str, case: str, kind: str, seed: int, duration: float, folder: Path) -> tuple[str, Path] | None:
    """The (--system, CSV) of one run; None where the case does not apply (form flipped without a C element)."""
    model = load_system(system_path(system))
    rng = np.random.default_rng(seed)
    load = load_function(kind, model.nominal_load, model.excitation_bandwidth, rng)
    rate = 2.0 * RATE if case == "time_base" else RATE
    t, clean = simulate(system, load, duration * RATE / rate, rate)  # as many samples whatever the rate
    signals = sensor_noise(clean, round(rate), rng)
    column = load(t) / 1000.0 if case == "unit" else load(t)
    stamps = t * rate / RATE  # the t column: the 200 Hz data stamped at 100 Hz
    target = system_path(system)
    if case == "form":
        flipped = flipped_model(system, folder)
        if flipped is None:
            return None
        target = str(flipped)
    path = folder / f"{system}_{case}_{kind}_{seed}.csv"
    write_record(path, system, stamps, column, signals)
    return target, path


def run_phm(system: str, target: str, csv: Path, out: Path) -> dict[str, Any]:
    """``ea-gym phm --system target --measurements csv --noise 0.01 --classifier (system's)``'s results.json."""
    with contextlib.redirect_stdout(io.StringIO()):
        code = ea_gym_main(["phm", "--system", target, "--measurements", str(csv), "--noise", str(NOISE), "--out", str(out),
                            "--classifier", str(network_path(system))])
    if code != 0:
        raise RuntimeError(f"ea-gym phm on {csv} exited with {code}")
    results: dict[str, Any] = json.loads((out / "results.json").read_text())
    return results


def verdict(case: str, results: dict[str, Any]) -> bool:
    """A misfit case: ok false, nothing isolated, no End of Life; healthy: ok true."""
    fit = results["model_fit"]
    if case == "healthy":
        return fit["ok"] is True
    return fit["ok"] is False and results["isolated_parameter"] is None and not results["eol_predictions"]


def scenario_runs(name: str, folder: Path) -> dict[str, Any]:
    """Scenario ``name``'s ``simulate --csv`` record through the chain with the model-fit test on and off."""
    from ea_gym.measurements import read_measurements
    from ea_gym.phm import ChainTiming, ModelFitConfig, PHMConfig, build_chain, classifier_for, run_measurements
    from ea_gym.reporting import chain_results
    from ea_gym.scenario import load_scenario

    source = SCENARIOS / f"{name}.json"
    csv = folder / f"{name}.csv"
    with contextlib.redirect_stdout(io.StringIO()):
        if ea_gym_main(["simulate", str(source), "--csv", str(csv)]) != 0:
            raise RuntimeError(f"ea-gym simulate {source} failed")
    model = load_scenario(source).model
    scenario = load_scenario(source)
    measurements = read_measurements(csv, model)
    row: dict[str, Any] = {"scenario": name}
    for label, enabled in (("off", False), ("on", True)):
        timing = ChainTiming(sample_rate=measurements.sample_rate, noise=scenario.noise)
        config = PHMConfig(timing=timing, fit=ModelFitConfig(enabled=enabled))
        chain = build_chain(model, config, classifier_for(model), np.random.default_rng(0))
        results = chain_results(run_measurements(chain, measurements), chain, None, str(csv))
        predictions = results["eol_predictions"]
        row[label] = {
            "ok": results["model_fit"]["ok"], "statistic": results["model_fit"]["statistic"], "detection_time": results["detection_time"],
            "isolated": results["isolated_parameter"], "eol_predictions": len(predictions),
            "first_eol_t": predictions[0]["t"] if predictions else None, "final_rul": predictions[-1]["rul"] if predictions else None,
        }
    return row


def scenario_table(rows: list[dict[str, Any]]) -> str:
    """Per scenario, test off -> on: ok, detection time, isolated parameter, End-of-Life predictions (first at, last RUL)."""
    lines = ["| scenario | ok | detection (s) off / on | isolated off / on | EoL predictions off / on | first at (s) off / on "
             "| last RUL (s) off / on |", "|---|---|---|---|---|---|---|"]

    def both(row: dict[str, Any], key: str) -> str:
        return " / ".join("-" if row[side][key] is None else f"{row[side][key]:.4g}" if isinstance(row[side][key], float)
                          else str(row[side][key]) for side in ("off", "on"))

    for row in rows:
        lines.append(f"| {row['scenario']} | {row['on']['ok']} | {both(row, 'detection_time')} | {both(row, 'isolated')} "
                     f"| {both(row, 'eol_predictions')} | {both(row, 'first_eol_t')} | {both(row, 'final_rul')} |")
    return "\n".join(lines) + "\n"


def table(rows: list[dict[str, Any]], systems: Sequence[str], loads: Sequence[str]) -> str:
    """Per system and case: passed / runs, and the NIS statistic's range."""
    lines = ["| system | case | passed | NIS per dof (min - max) | band (high) |", "|---|---|---|---|---|"]
    for system in systems:
        for case in CASES:
            cell = [r for r in rows if r["system"] == system and r["case"] == case and r["load"] in loads]
            if not cell:
                lines.append(f"| {system} | {case} | n/a (no C element) | - | - |" if case == "form" else f"| {system} | {case} | - | - | - |")
                continue
            stats = [r["statistic"] for r in cell if r["statistic"] is not None]
            spread = f"{min(stats):.3g} - {max(stats):.3g}" if stats else "-"
            high = cell[0]["band"][1] if cell[0]["band"] else None
            lines.append(f"| {system} | {case} | {sum(r['passed'] for r in cell)}/{len(cell)} | {spread} | {high:.3g} |" if high else
                         f"| {system} | {case} | {sum(r['passed'] for r in cell)}/{len(cell)} | {spread} | - |")
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--systems", nargs="+", default=list(SYSTEMS), choices=SYSTEMS)
    parser.add_argument("--seeds", type=int, default=5, help="seeds per system, case and load")
    parser.add_argument("--loads", nargs="+", default=list(LOADS), choices=LOADS)
    parser.add_argument("--duration", type=float, default=40.0, help="record length (s)")
    parser.add_argument("--scenarios", nargs="*", default=sorted(p.stem for p in SCENARIOS.glob("*.json")))
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parse_with_smoke(parser, argv, SMOKE)
    started = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory(prefix="ea-gym-model-fit-") as scratch:
        folder = Path(scratch)
        for system in args.systems:
            for case in CASES:
                for kind in args.loads:
                    for seed in range(args.seeds):
                        made = make_record(system, case, kind, seed, args.duration, folder)
                        if made is None:
                            continue
                        results = run_phm(system, *made, folder / "out" / made[1].stem)
                        fit = results["model_fit"]
                        rows.append({
                            "system": system, "case": case, "load": kind, "seed": seed, "passed": verdict(case, results), "ok": fit["ok"],
                            "statistic": fit["statistic"], "band": fit["band"], "since": fit["since"],
                            "isolated": results["isolated_parameter"], "eol_predictions": len(results["eol_predictions"]),
                            "detection_time": results["detection_time"],
                        })
                        print(f"{system} {case} {kind} seed {seed}: ok {fit['ok']}, NIS {fit['statistic']}, passed {rows[-1]['passed']}", flush=True)
        scenarios = [scenario_runs(name, folder) for name in args.scenarios]
    text = table(rows, args.systems, args.loads) + "\nSingle-fault scenarios, their `ea-gym simulate --csv` records, model-fit test off / on:\n\n"
    text += scenario_table(scenarios)
    args.out.mkdir(parents=True, exist_ok=True)
    write_json(args.out / "results.json", json_ready({
        "noise": NOISE, "rate": RATE, "duration": args.duration, "seeds": args.seeds, "loads": args.loads, "runs": rows, "scenarios": scenarios,
        "wall_s": time.perf_counter() - started, "machine": machine_info(),
    }))
    write_text(args.out / "table.md", text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
