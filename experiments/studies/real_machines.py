"""Real machines (issue 30's acceptance): every part ages at once, the healthy machine is not the nominal model, the load
is measured with noise, and data the model cannot explain is said so.

Every record comes from an independent ODE (``experiments/studies/records.py``: each system's equations written out by
hand, scipy's ``solve_ivp`` at rtol 1e-9), 100 Hz, 1 % sensor noise (std a fraction of each signal's RMS over each
1 s step), a band-limited random (even seeds) or multisine (odd seeds) load, and goes through the chain's public API
as a user's CSV would (``ea_gym.measurements.Measurements`` -> ``ea_gym.phm.run_measurements``), set up as
``ea-gym phm --measurements REC --noise 0.01`` sets it up (``part_tracks.chain_run``); the per-part outputs are
``HealthStatus.parts``. Systems: spring_mass_damper, rlc_circuit, dc_motor and the model file
experiments/models/two_mass_chain.yaml; 5 seeds each.

a. Several parts wearing (``records.MULTI_PART``): two, then three parts ramping from nominal to their safe limits,
   onsets 40, 55 and 70 s, 100, 80 and 120 s to the limit, 200 s records. Targets: the set of degrading parts named
   exactly in >= 95 % of the steps from 30 s after an onset (``part_tracks.set_named_right``); each parameter's median
   estimate error (steps from 10 s after the first onset) <= 1.5 x that of ProgPy's UKF estimating every parameter
   jointly on the same samples (``compare_progpy.ukf_track``, 100 Hz; its ProgPy model is written for the
   spring-mass-damper alone, where it takes ~0.4 s per 1 s step, 80 s per record, with three parameters: the other
   systems, with four and five, have no UKF row); per wearing part, alpha-lambda (predictions from 50 to 90 % of the way
   from onset to End of Life within +-20 % of the true RUL) and coverage (their 95 % interval bounded and holding the
   true RUL) >= 0.9.
b. Healthy machines, every part constant at a value drawn in the middle half of its safe range, commissioned on a
   separate 30 s healthy record of the same machine (``ea_gym.phm.commission``, ``PHMChain.commission``): no alarm,
   no part named and no End of Life in >= 95 % of 40 records (120 s each); with the two-part wear of (a) added later
   (from those values), the targets of (a).
c. 1 % noise on the load column as well (the chain told so: ``ChainTiming.load_noise``), one part wearing (onset 40 s,
   100 s to its limit, 160 s records; seed i wears the i-th part, cyclically): no alarm, no part named and no End of Life before the onset in
   >= 95 % of the records; and the single-fault figures within 1.5 x of the same records with the exact load column
   (the same sensor noise): median error of the wearing part, alpha-lambda, coverage.
d. Misfits, on (a)'s two-part records (100 s): the load column 1000 x too small (kN read as N), 200 Hz data whose t
   column says 100 Hz, the model file's first C element with its form flipped (``model_fit.flipped_model``; dc_motor
   has none): the model-fit test says "does not fit" at the end, and no part is named, none isolated and no End of
   Life given at any step, in every case.

The records check: one record of the spring-mass-damper against ea-gym's own simulation (``ea_gym.plant.run_model``),
agreeing to 1e-6 of each signal's amplitude (``records.plant_agreement``).

Writes table.md (one row per criterion and system: measured, target, pass or miss), results.json and estimates.png
(each part's estimate and its probability of degrading on one three-part record) into experiments/results/real_machines/.

    python experiments/studies/real_machines.py          # the whole grid
    python experiments/studies/real_machines.py --smoke  # spring_mass_damper, one seed, every time halved, 2 healthy records
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's ea_gym and experiments, installed or not

from ea_gym.files import json_ready, save_figure, write_json, write_text
from ea_gym.measurements import Measurements
from ea_gym.model_files import load_system
from ea_gym.models import SystemModel
from ea_gym.phm import JointFilterConfig
from experiments.common import machine_info, parse_with_smoke
from experiments.studies.compare_progpy import FilterSettings, ukf_track
from experiments.studies.model_fit import flipped_model, network_path
from experiments.studies.part_tracks import PartTrack, chain_run, first_alarm, raised_by, wear_scores, wear_summary
from experiments.studies.records import (
    COMMISSIONING,
    DURATION,
    LOADS,
    MULTI_PART,
    NOISE,
    RATE,
    SYSTEMS,
    Machine,
    Record,
    case_record,
    draw_load,
    make_record,
    middle_half,
    plant_agreement,
    system_model,
    worn,
)

RESULTS = Path(__file__).resolve().parents[1] / "results" / "real_machines"
SHARE, RATIO, PROGNOSIS = 0.95, 1.5, 0.9  # the targets: share of steps or records, error ratio, alpha-lambda and coverage
HEALTHY_DURATION = 120.0  # s
MISFIT_DURATION = 100.0  # s
MISFITS = ("unit", "time_base", "form")
UKF_SYSTEM = "spring_mass_damper"  # the one system whose ProgPy model compare_progpy writes
SMOKE = {"systems": ["spring_mass_damper"], "seeds": [0], "scale": 0.5, "healthy": 2, "ukf_rate": 20.0}
Log = Callable[[str], None]


def seeded(*keys: int) -> np.random.Generator:
    """A generator of this script's own records (healthy machines, misfits), from their group, system, case and seed."""
    return np.random.default_rng([3030, *keys])


def several_parts(system: str, seeds: Sequence[int], scale: float, ukf: FilterSettings | None, log: Log) -> dict[str, Any]:
    """(a): two and three parts wearing from nominal; ProgPy's UKF beside the chain where ``ukf`` is given."""
    out: dict[str, Any] = {}
    for case in ("two parts", "three parts"):
        chain_runs, ukf_runs = [], []
        for seed in seeds:
            record, _ = case_record(system, case, seed, scale)
            chain_runs.append(wear_scores(chain_run(record), record.machine))
            if ukf is not None:
                ukf_runs.append(wear_scores(ukf_track(record, ukf), record.machine))
            log(f"{system}, {case}, seed {seed}: set named right in {chain_runs[-1]['set_right'].mean():.2f} of the steps")
        out[case] = {"chain": wear_summary(chain_runs), **({"ukf": wear_summary(ukf_runs)} if ukf_runs else {})}
    return out


def healthy_machines(system: str, records: int, seeds: Sequence[int], scale: float, log: Log) -> dict[str, Any]:
    """(b): healthy machines off their catalogue values, each commissioned on a separate healthy record; then "off-nominal"
    machines that wear two parts later."""
    alarms, raised = [], []
    for k in range(records):
        rng = seeded(1, SYSTEMS.index(system), k)
        machine = Machine(system, middle_half(system, rng))
        commissioning = make_record(machine, draw_load(system, LOADS[k % 2], rng), scale * COMMISSIONING, rng)
        record = make_record(machine, draw_load(system, LOADS[k % 2], rng), scale * HEALTHY_DURATION, rng)
        track = chain_run(record, commissioning=commissioning)
        alarms.append(first_alarm(track))
        raised.append(raised_by(track))
    runs = []
    for seed in seeds:
        record, commissioning = case_record(system, "off-nominal", seed, scale)
        runs.append(wear_scores(chain_run(record, commissioning=commissioning), record.machine))
    quiet = float(np.mean(np.isinf(alarms)))
    log(f"{system}, healthy: nothing raised in {quiet:.2f} of {records} records")
    return {"quiet": quiet, "records": records, "first_alarms": alarms, "raised_by": raised, "fault_later": wear_summary(runs)}


def noisy_load(system: str, seeds: Sequence[int], scale: float, log: Log) -> dict[str, Any]:
    """(c): one part wearing, the load column exact and with 1 % noise, on the same load and sensor noise; the errors of the
    wearing part alone (the single-fault figures)."""
    out = {}
    for label, fraction in (("exact", 0.0), ("noisy", NOISE)):
        runs = []
        for seed in seeds:
            record, _ = case_record(system, "single part", seed, scale, load_noise=fraction)
            scores = wear_scores(chain_run(record, load_noise=fraction), record.machine)
            (ramp,) = record.machine.ramps
            early = scores["first_alarm"] < ramp.onset
            runs.append({**scores, "errors": {ramp.parameter: scores["errors"][ramp.parameter]}, "early": scores["raised_by"] if early else ""})
        out[label] = {**wear_summary(runs), "quiet": [not run["early"] for run in runs], "raised_by": [run["early"] for run in runs]}
    log(f"{system}, 1 % load noise: nothing raised before onset in {np.mean(out['noisy']['quiet']):.2f} of the records")
    return out


def misfit_record(system: str, case: str, seed: int, scale: float, folder: Path) -> tuple[Record, SystemModel, str | None]:
    """(d): the two-part record of ``system`` presented wrongly; the model the chain is given and its network's path."""
    rng = seeded(2, SYSTEMS.index(system), MISFITS.index(case), seed)
    machine = worn(Machine(system), MULTI_PART[system][:2], scale)
    rate = 2.0 * RATE if case == "time_base" else RATE
    record = make_record(machine, draw_load(system, LOADS[seed % 2], rng), scale * MISFIT_DURATION * RATE / rate, rng, rate=rate)
    m = record.measurements
    if case == "unit":
        m = Measurements(t=m.t, load=m.load / 1000.0, signals=m.signals)
    elif case == "time_base":
        m = Measurements(t=m.t * rate / RATE, load=m.load, signals=m.signals)
    model, classifier = system_model(system), None
    if case == "form":
        path = flipped_model(system, folder)
        assert path is not None  # the caller skips a system without a C element
        model, classifier = load_system(path), str(network_path(system))
    return replace(record, measurements=m), model, classifier


def misfits(system: str, seeds: Sequence[int], scale: float, log: Log) -> dict[str, Any]:
    """(d): per case, how many records end with "does not fit" and nothing named, isolated or predicted at any step."""
    has_c = any(system_model(system).graph.elements[name].kind.value == "C" for name in system_model(system).state_names)
    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="ea-gym-real-machines-") as scratch:
        for case in MISFITS:
            if case == "form" and not has_c:
                continue
            passed, failures = [], []
            for seed in seeds:
                record, model, classifier = misfit_record(system, case, seed, scale, Path(scratch))
                try:
                    track = chain_run(record, model, classifier)
                except np.linalg.LinAlgError as error:  # the chain's filter broke down on the data: a miss, said so in the results
                    failures.append(f"seed {seed}: {type(error).__name__}: {error}")
                    passed.append(False)
                    continue
                silent = not track.named.any() and (track.isolated < 0).all() and np.isinf(track.eol).all() and np.isinf(track.machine_eol).all()
                passed.append(bool(track.misfit[-1] and silent))
            out[case] = {"passed": sum(passed), "runs": len(passed), "failures": failures}
            log(f"{system}, misfit ({case}): {sum(passed)} of {len(passed)} records said so and silent")
    return out


# ---------------------------------------------------------------------------------------------------
# the criteria: one row per criterion and system
# ---------------------------------------------------------------------------------------------------


def row(criterion: str, system: str, measured: str, target: str, passed: bool | None) -> dict[str, Any]:
    """A table row; ``passed`` None where the figure is not measured."""
    return {"criterion": criterion, "system": system, "measured": measured, "target": target,
            "verdict": "n/a" if passed is None else "pass" if passed else "miss"}


def first_raised(raised: Sequence[str]) -> str:
    """What the records that raised something raised first, and how many of them: "" where none did."""
    counts = Counter(what for what in raised if what)
    return f" (first raised: {'; '.join(f'{what} {n}' for what, n in counts.most_common())})" if counts else ""


def worst(figures: dict[str, float], low: bool = True) -> tuple[str, float]:
    """The part with the lowest (``low``) or highest figure."""
    part = (min if low else max)(figures, key=lambda name: figures[name])
    return part, figures[part]


def wear_rows(label: str, system: str, summaries: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Set named, alpha-lambda and coverage rows of (a) or (b) over ``summaries`` (pooled by run count)."""
    share = sum(s["set_named"] * s["set_steps"] for s in summaries) / sum(s["set_steps"] for s in summaries)
    rows = [row(f"{label}: set of degrading parts named exactly", system, f"{share:.3f}", f">= {SHARE}", share >= SHARE)]
    for figure, name in (("alpha_lambda", "alpha-lambda"), ("coverage", "95 % RUL coverage")):
        hits: dict[str, float] = {}
        predictions: dict[str, int] = {}
        for summary in summaries:  # each part's share over all its predictions
            for part, value in summary[figure].items():
                hits[part] = hits.get(part, 0.0) + value * summary["predictions"][part]
                predictions[part] = predictions.get(part, 0) + summary["predictions"][part]
        part, value = worst({part: hits[part] / max(predictions[part], 1) for part in hits})
        rows.append(row(f"{label}: {name} per degrading part (worst)", system, f"{value:.2f} ({part})", f">= {PROGNOSIS}", value >= PROGNOSIS))
    return rows


def ukf_rows(system: str, several: dict[str, Any]) -> list[dict[str, Any]]:
    """(a)'s estimate errors against the joint UKF's: the worst ratio over the cases and parameters."""
    criterion = "a. 2-3 parts wearing: median estimate error / the joint UKF's (worst parameter)"
    ratios = {f"{case}, {part}": summary["chain"]["error_median"][part] / summary["ukf"]["error_median"][part]
              for case, summary in several.items() if "ukf" in summary for part in summary["chain"]["error_median"]}
    if not ratios:
        return [row(criterion, system, "no UKF (its ProgPy model is the spring-mass-damper's)", f"<= {RATIO}", None)]
    where, ratio = worst(ratios, low=False)
    return [row(criterion, system, f"{ratio:.2f} ({where})", f"<= {RATIO}", ratio <= RATIO)]


def load_noise_rows(system: str, exact: dict[str, Any], noisy: dict[str, Any]) -> list[dict[str, Any]]:
    """(c): nothing raised before onset with the noisy load column; each single-fault figure's worst part, how many times worse
    than with the exact column (the error's ratio, alpha-lambda's and coverage's inverse ratio; 1 where both are 0)."""
    quiet = float(np.mean(noisy["quiet"]))
    rows = [row("c. 1 % load noise: nothing raised before onset", system, f"{quiet:.2f} of {len(noisy['quiet'])}{first_raised(noisy['raised_by'])}",
                f">= {SHARE}", quiet >= SHARE)]
    for figure, name, power in (("error_median", "median error of the wearing part", 1), ("alpha_lambda", "alpha-lambda", -1),
                                ("coverage", "95 % RUL coverage", -1)):
        ratios = {part: 1.0 if noisy[figure][part] == exact[figure][part] else (noisy[figure][part] / exact[figure][part]) ** power
                  if noisy[figure][part] > 0 else np.inf for part in exact[figure]}
        part, ratio = worst(ratios, low=False)
        rows.append(row(f"c. 1 % load noise: {name}, times worse than with the exact load (worst part)", system,
                        f"{ratio:.2f} ({part}: {exact[figure][part]:.3g} -> {noisy[figure][part]:.3g})", f"<= {RATIO}", ratio <= RATIO))
    return rows


def criteria(results: dict[str, dict[str, Any]], agreement: float) -> list[dict[str, Any]]:
    """Every criterion's row, from each system's results."""
    rows = [row("records: the independent ODE against ea_gym.plant.run_model (largest difference / amplitude)", UKF_SYSTEM, f"{agreement:.1e}",
                "<= 1e-6", agreement <= 1e-6)]
    for system, result in results.items():
        several, healthy, load_noise = result["several"], result["healthy"], result["load_noise"]
        rows += wear_rows("a. 2-3 parts wearing", system, [summary["chain"] for summary in several.values()])
        rows += ukf_rows(system, several)
        quiet = f"{healthy['quiet']:.3f} of {healthy['records']}{first_raised(healthy['raised_by'])}"
        rows.append(row("b. healthy off-nominal machines: no alarm, no part named, no End of Life", system, quiet, f">= {SHARE}",
                        healthy["quiet"] >= SHARE))
        rows += wear_rows("b. 2 parts wearing on an off-nominal machine", system, [healthy["fault_later"]])
        rows += load_noise_rows(system, load_noise["exact"], load_noise["noisy"])
        for case, cell in result["misfit"].items():
            crashed = f" ({len(cell['failures'])} raised an error)" if cell["failures"] else ""
            rows.append(row(f"d. misfit ({case}): does not fit; nothing named, isolated or predicted", system,
                            f"{cell['passed']} of {cell['runs']}{crashed}", "all", cell["passed"] == cell["runs"]))
    quiet = [q for result in results.values() for q in result["load_noise"]["noisy"]["quiet"]]
    rows.append(row("c. 1 % load noise: nothing raised before onset, every system's records", "all", f"{np.mean(quiet):.2f} of {len(quiet)}",
                    f">= {SHARE}", bool(np.mean(quiet) >= SHARE)))
    return rows


def table(rows: Sequence[dict[str, Any]]) -> str:
    """The markdown table of ``rows``."""
    lines = ["| criterion | system | measured | target | verdict |", "|---|---|---|---|---|"]
    lines += [f"| {r['criterion']} | {r['system']} | {r['measured']} | {r['target']} | {r['verdict']} |" for r in rows]
    return "\n".join(lines) + "\n"


def plot_parts(track: PartTrack, machine: Machine, path: Path) -> Path:
    """Each part's estimate (as its position in its safe range) against the truth, and its probability of degrading."""
    from ea_gym.pyplot import plt

    limits = np.array([system_model(machine.system).safe_limits[part] for part in track.parts])
    position = (track.value - limits[:, 0]) / (limits[:, 1] - limits[:, 0])
    truth = (machine.values(track.t)[:, [system_model(machine.system).parameter_names.index(p) for p in track.parts]] - limits[:, 0]) / (
        limits[:, 1] - limits[:, 0])
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(12, 7), sharex=True)
    colors, markers = plt.rcParams["axes.prop_cycle"].by_key()["color"], "os^DvP*X"
    every = max(1, len(track.t) // 20)
    for j, part in enumerate(track.parts):
        style = {"color": colors[j % len(colors)], "marker": markers[j % len(markers)], "markevery": every, "ms": 5}
        top.plot(track.t, position[:, j], lw=1.2, label=f"{part} estimate", **style)
        top.plot(track.t, truth[:, j], color=style["color"], ls="--", lw=1.0, label=f"{part} true")
        bottom.plot(track.t, track.degrading[:, j], lw=1.2, label=part, **style)
    for ramp in machine.ramps:
        for ax in (top, bottom):
            ax.axvline(ramp.onset, color="0.5", ls=":", lw=0.8)
    top.axhline(0.0, color="0.3", lw=0.8, label="safe limits")
    top.axhline(1.0, color="0.3", lw=0.8)
    top.set_ylabel("position in the safe range")
    top.set_title(f"{machine.system}: {', '.join(r.parameter for r in machine.ramps)} wearing (onsets dotted)")
    rules = JointFilterConfig()
    bottom.axhline(rules.name_probability, color="0.3", ls="--", lw=0.8, label=f"named from {rules.name_probability:g}")
    bottom.axhline(rules.release_probability, color="0.3", ls=":", lw=0.8, label=f"until below {rules.release_probability:g}")
    bottom.set_ylabel("P(degrading)")
    bottom.set_xlabel("t (s)")
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path)


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--systems", nargs="+", choices=SYSTEMS, default=list(SYSTEMS), help="which systems (default all four)")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4], help="record seeds (default 0..4)")
    parser.add_argument("--healthy", type=int, default=40, help="healthy records per system (b)")
    parser.add_argument("--scale", type=float, default=1.0, help="every onset, time to the limit and record length multiplied by it")
    parser.add_argument("--ukf-rate", type=float, default=RATE, help="ProgPy's UKF steps per s (Hz), a divisor of 100")
    parser.add_argument("--out", type=Path, default=RESULTS, help="output folder")
    args = parse_with_smoke(parser, argv, SMOKE)
    if not 0.2 <= args.scale <= 10:
        parser.error(f"--scale: expected a factor in [0.2, 10], got {args.scale}")
    return args


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    started = time.perf_counter()
    ukf = FilterSettings(rate=args.ukf_rate) if importlib.util.find_spec("progpy") is not None else None
    if ukf is None:
        log("real_machines: ProgPy is not installed (pip install -e '.[compare]'): no UKF rows")
    results: dict[str, dict[str, Any]] = {}
    for system in args.systems:
        began = time.perf_counter()
        results[system] = {
            "several": several_parts(system, args.seeds, args.scale, ukf if system == UKF_SYSTEM else None, log),
            "healthy": healthy_machines(system, args.healthy, args.seeds, args.scale, log),
            "load_noise": noisy_load(system, args.seeds, args.scale, log),
            "misfit": misfits(system, args.seeds, args.scale, log),
        }
        results[system]["seconds"] = time.perf_counter() - began
    check = worn(Machine(UKF_SYSTEM), MULTI_PART[UKF_SYSTEM], args.scale)
    agreement = plant_agreement(check, draw_load(UKF_SYSTEM, "random", seeded(3)), args.scale * DURATION["three parts"])
    rows = criteria(results, agreement)
    shown, _ = case_record(args.systems[-1], "three parts", args.seeds[0], args.scale)
    plot_parts(chain_run(shown), shown.machine, args.out / "estimates.png")
    wall = time.perf_counter() - started
    command = "python experiments/studies/real_machines.py" + (" --smoke" if args.smoke else "")
    notes = (f"\nSystems {args.systems}, seeds {args.seeds}, {args.healthy} healthy records per system, times x {args.scale:g}; ProgPy's UKF at "
             f"{args.ukf_rate:g} Hz. {wall:.0f} s on one process. Made by `{command}`; see its docstring for the cases and the metrics.\n")
    write_text(args.out / "table.md", "# Real machines: the acceptance of issue 30\n\n" + table(rows) + notes)
    write_json(args.out / "results.json", json_ready({
        "arguments": {**vars(args), "out": str(args.out)}, "criteria": rows, "agreement": agreement, "systems": results, "wall_s": wall,
        "machine": machine_info(),
    }))
    print(table(rows) + notes)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
