"""The ``ea-gym`` command."""

from __future__ import annotations

import argparse
import contextlib
import math
import signal
import sys
from collections.abc import Iterable, Sequence
from importlib.metadata import entry_points
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from ea_gym.cli_args import (
    COMMAND_GROUP,
    Subcommands,
    column_mapping,
    column_names,
    columns_given,
    fraction_below_one,
    non_negative_float,
    positive_float,
    sample_rate_option,
    seconds_within,
)
from ea_gym.interrupts import Terminated, interrupts_raised
from ea_gym.models import SystemModel

if TYPE_CHECKING:
    from ea_gym.measurements import Measurements
    from ea_gym.phm import Commissioning
    from ea_gym.scenario import Scenario

#: the shortest healthy stretch a machine is commissioned on (s): two of the chain's steps
COMMISSION_LEAST = 2.0
#: the absolute part of how far --noise may sit from the record's estimate before the command warns: a noise-free record
#: of a fast model reads ~0.1 % (ea_gym.measurements.noise_estimate)
NOISE_MARGIN = 0.002


def _simulate(args: argparse.Namespace) -> int:
    from ea_gym.files import check_output_directory, staged_output
    from ea_gym.scenario import load_scenario

    if args.out is None and args.csv is None:
        raise ValueError("give --out DIR (Energy Activity) or --csv FILE (measurements), or both")
    if args.out is not None:
        check_output_directory(args.out)
    if args.csv is not None:
        check_output_directory(Path(args.csv).parent / ".")
        if Path(args.csv).is_dir():
            raise ValueError(f"--csv: {args.csv} is a directory; expected a file to write")
    scenario = load_scenario(args.scenario, args.system)
    from ea_gym.energy import window_samples  # the numerical kernels, once the file is valid

    if args.out is not None:
        if args.window > scenario.duration:
            raise ValueError(f"--window: {args.window:g} s is longer than the run ({scenario.duration:g} s); expected at most its duration")
        try:
            window_samples(args.window, 1.0 / scenario.sample_rate)
        except ValueError as error:
            raise ValueError(f"--window: {error}") from None
    with contextlib.ExitStack() as stack:  # the CSV and the directory appear together, or neither
        if args.out is not None:
            _write_energy(scenario, stack.enter_context(staged_output(args.out)), args.window)
        if args.csv is not None:
            _write_measurements(scenario, Path(args.csv))
    if args.out is not None:
        print(f"wrote {Path(args.out) / 'energy.json'} and {Path(args.out) / 'energy.png'} (windows of {args.window:g} s)")
    return 0


def _write_measurements(scenario: Scenario, path: Path) -> None:
    """The scenario's sensor record (its noise and seed) as a measurement CSV."""
    import numpy as np

    from ea_gym.measurements import write_measurements
    from ea_gym.phm import scenario_measurements

    measurements = scenario_measurements(scenario, np.random.default_rng(scenario.sensor_seed))
    write_measurements(path, scenario.model, measurements)
    print(f"wrote {path} ({len(measurements.t)} samples at {scenario.sample_rate:g} Hz, sensor noise {scenario.noise:g}, "
          f"load noise {scenario.load_noise:g})")


def _write_energy(scenario: Scenario, out: Path, window: float) -> None:
    """Every element's EA and EAI per window of the scenario's true signals, with their figure."""
    from ea_gym.energy import windowed_energy
    from ea_gym.files import write_json
    from ea_gym.plant import simulate
    from ea_gym.plots import plot_energy

    trajectory = simulate(scenario)
    energy = windowed_energy(trajectory.power, trajectory.sample_period, window, scenario.model.rco_elements)
    elements = {}
    for name, ea in energy.ea.items():
        elements[name] = {"ea": ea.tolist()}
        if name in energy.eai:
            elements[name]["eai"] = energy.eai[name].tolist()
    plot_energy(trajectory, energy, out / "energy.png")
    write_json(out / "energy.json", {"window": window, "t": energy.t.tolist(), "elements": elements})


def _progress(steps: Iterable[int]) -> Iterable[int]:
    from tqdm import tqdm

    return tqdm(steps, desc="PHM chain", unit="step", leave=False)


def _phm(args: argparse.Namespace) -> int:
    from ea_gym.files import check_output_directory

    if (args.scenario is None) == (args.measurements is None):
        raise ValueError("give a SCENARIO to simulate or --measurements DATA.csv (with --system), one of them")
    if args.commission is not None and args.commission_seconds is not None:
        raise ValueError("--commission: give a healthy record or --commission-seconds S (the record's first seconds), not both")
    check_output_directory(args.out)
    if args.measurements is not None:
        return _phm_measurements(args)
    given = [option for option, value in (("--noise", args.noise), ("--seed", args.seed), ("--columns", args.columns),
                                          ("--ignore-columns", args.ignore_columns), ("--sample-rate", args.sample_rate),
                                          ("--load-noise", args.load_noise), ("--commission", args.commission))
             if value is not None and value != []]
    if given:
        raise ValueError(f"{given[0]} goes with --measurements; a scenario names its sensor and load noise, seed, signals and sample rate"
                         + (" (commission from its first seconds with --commission-seconds S)" if given[0] == "--commission" else ""))
    from ea_gym.scenario import load_scenario

    scenario = load_scenario(args.scenario, args.system)  # before the chain's heavy imports: a bad file is refused at once
    model = scenario.model
    model.check_degradable()
    if args.commission_seconds is not None:
        seconds_within("--commission-seconds", args.commission_seconds, COMMISSION_LEAST, scenario.duration, "the scenario")

    import numpy as np

    from ea_gym.phm import build_chain, chain_config, classifier_for, run_scenario
    from ea_gym.reporting import write_phm_outputs
    from ea_gym.reporting.results import RunInputs

    rng = np.random.default_rng(scenario.sensor_seed)
    config = chain_config(scenario.sample_rate, scenario.noise, scenario.load_noise)
    classifier = classifier_for(model, args.classifier)
    chain = build_chain(model, config, classifier, rng)
    inputs = RunInputs()
    if args.commission_seconds is not None:
        from ea_gym.phm import scenario_measurements

        # the scenario's sensor record (as simulate --csv writes it), its own draw of the noise
        record = scenario_measurements(scenario, np.random.default_rng(scenario.sensor_seed))
        commissioning = _commission(model, record.first(args.commission_seconds), scenario.noise, scenario.load_noise)
        chain.commission(commissioning.value)
        inputs = RunInputs(commissioning=commissioning,
                           commissioning_source=f"the first {args.commission_seconds:g} s of the scenario's sensor record")
    run = run_scenario(scenario, chain, rng, progress=_progress)
    results = write_phm_outputs(Path(args.out), run, chain, scenario, f"PHM chain on {args.scenario}", inputs=inputs)
    _print_outcome(results, args.out)
    return 0


def _commission(model: SystemModel, healthy: Measurements, noise: float, load_noise: float) -> Commissioning:
    """The healthy machine's own values fitted on the record ``healthy`` (at the chain's sample rate) with its noise levels
    (``ea_gym.phm.commission``); ``PHMChain.commission`` makes them the chain's healthy machine."""
    import numpy as np

    from ea_gym.phm import commission

    load_rate = np.gradient(healthy.load, healthy.sample_period)  # the recorded load's derivative, as the stream takes it
    return commission(model, healthy.signals.T[None], healthy.load[None], load_rate[None], healthy.sample_rate, noise, load_noise)


def _models(args: argparse.Namespace) -> int:
    from ea_gym.models import MODELS, get_model

    for name in MODELS:
        model = get_model(name)
        print(f"{name}: {model.description}")
        print("\n".join(_parameter_lines(model)))
    return 0


def _model(args: argparse.Namespace) -> int:
    from ea_gym.bondgraph import Kind
    from ea_gym.model_files import load_model_file, printable

    model = load_model_file(args.file)
    space = model.state_space
    elements = model.graph.elements
    # a description is free text: a terminal's escape sequences in it are shown, not obeyed
    print(f"{model.name}: {printable(model.description)}" if model.description else model.name)
    print("causality (the causal stroke sits at the end of the bond whose element receives the effort):")
    for bond, setter in zip(model.graph.bonds, space.causality.effort_setter):
        print(f"  {bond.tail} -> {bond.head}: stroke at {bond.other(setter)} ({setter} sets the effort)")
    for name, quantity in space.causality.inputs.items():
        kind = elements[name].kind
        note = " (integral)" if kind.is_storage else ""
        print(f"  {name} ({kind.value}): its input is its {quantity}{note}")
    states = ", ".join(f"{name} ({'p' if elements[name].kind is Kind.I else 'q'})" for name in model.state_names)
    print(f"states: {states}")
    print("parameters:")
    print("\n".join(_parameter_lines(model)))
    load_unit = model.units.get(model.load_source, "")
    constant = "".join(f"; {name} = {value:g} {model.units.get(name, '')}".rstrip() for name, value in model.source_values.items())
    print(
        f"load: {model.load_source}, nominal {model.nominal_load:g} {load_unit}".rstrip()
        + (f", scale {model.load_scale:g} {load_unit}".rstrip() if model.load_scale is not None else "")
        + f", random loads up to {model.excitation_bandwidth:g} Hz{constant}"
    )
    fastest = model.fastest_mode()  # SystemModel.check_resolved's rule: |lambda| < pi * sample_rate
    print(f"fastest mode: |lambda| = {fastest:.3g} 1/s at the nominal values; a sample rate above {fastest / math.pi:.3g} Hz resolves it")
    return 0


def _parameter_lines(model: SystemModel) -> list[str]:
    """One line per parameter: its nominal value and unit, and its safe limits (degradable) or none."""
    lines = []
    for name in model.parameter_names:
        unit = model.units.get(name, "")
        limits = model.safe_limits.get(name)
        where = f"limits [{limits[0]:g}, {limits[1]:g}]" if limits else "no limits (not degradable)"
        lines.append(f"  {name} = {model.nominal[name]:g} {unit}".rstrip() + f", {where}")
    return lines


def _phm_measurements(args: argparse.Namespace) -> int:
    """The chain on a measurement CSV of ``--system``: thresholds calibrated at ``--noise``, no truth; commissioned on
    a healthy record (``--commission``) or the record's first seconds (``--commission-seconds``) where asked."""
    from ea_gym.measurements import noise_estimate, resampled
    from ea_gym.model_files import load_system

    if args.system is None:
        raise ValueError("--measurements needs --system MODEL, the model whose elements the columns are named after")
    model = load_system(args.system)
    model.check_degradable()
    recorded, healthy = _records(args, model)
    import numpy as np  # the chain's heavy imports (numba, scipy, torch) once the files are valid: a refusal comes at once

    from ea_gym.phm import build_chain, chain_config, chain_sample_rate, check_duration, classifier_for, run_measurements
    from ea_gym.reporting import write_phm_outputs
    from ea_gym.reporting.results import RunInputs

    rate = chain_sample_rate(recorded.sample_rate)
    measurements = recorded if rate == recorded.sample_rate else resampled(recorded, rate)
    check_duration(measurements, chain_config(rate, 0.0))  # before the calibration and the network
    if healthy is not None:
        healthy = healthy if rate == healthy.sample_rate else resampled(healthy, rate)
        if healthy.duration < COMMISSION_LEAST:
            raise ValueError(f"--commission: {args.commission} lasts {healthy.duration:g} s; expected {COMMISSION_LEAST:g} s or more")
    # thresholds calibrated below the record's noise raise alarms on a healthy machine: without --noise, the record's own
    step = round(recorded.sample_rate)  # the noise over 1 s steps, from the model's residuals
    estimate = noise_estimate(recorded, model, step)
    noise = estimate if args.noise is None else args.noise
    # resampled, the record's white noise keeps its density over its own band: white noise of that density at the chain's rate
    density = math.sqrt(rate / recorded.sample_rate)
    load_noise = 0.0 if args.load_noise is None else args.load_noise
    commissioning, source = None, None
    if healthy is not None or args.commission_seconds is not None:
        fitted_on = healthy if healthy is not None else measurements.first(args.commission_seconds)
        commissioning = _commission(model, fitted_on, noise * density, load_noise * density)
        source = str(args.commission) if healthy is not None else f"the first {args.commission_seconds:g} s of {args.measurements}"
        # the machine's own values explain the record better than the catalogue's: what they leave is the sensors' noise
        estimate = noise_estimate(recorded, model, step, parameters=dict(zip(commissioning.names, commissioning.value[0].tolist())))
        noise = estimate if args.noise is None else args.noise
    rng = np.random.default_rng(0 if args.seed is None else args.seed)
    chain = build_chain(model, chain_config(rate, noise * density, load_noise * density), classifier_for(model, args.classifier), rng)
    if commissioning is not None:
        chain.commission(commissioning.value)
    run = run_measurements(chain, measurements, progress=_progress)
    noise_source = "the record's estimate" if args.noise is None else "--noise"
    load_source = "assumed exact" if args.load_noise is None else "--load-noise"
    lines = [
        f"Times are seconds since the record's first sample (t = {recorded.t[0]:g} s in {args.measurements}).",
        (f"The record's sensor noise looks like {estimate:.2%} of the signals' RMS (ea_gym.measurements.noise_estimate"
         + (", from the commissioned machine's residuals" if commissioning is not None else "")
         + f"); the detection thresholds are calibrated for {noise:.2%} ({noise_source})."),
        (f"The load is read with noise of {load_noise:.2%} of its RMS ({load_source}"
         + ("; give --load-noise FRACTION where its sensor is noisy: the model's residuals cannot tell it from the sensors' noise)."
            if args.load_noise is None else ").")),
    ]
    if commissioning is not None:
        lines.append(f"The chain's healthy machine is commissioned on {source}: "
                     + ", ".join(f"{name} = {value:.4g}" for name, value in zip(commissioning.names, commissioning.value[0])) + ".")
    if measurements is not recorded:
        lines[0] = (f"Times are seconds since t = {measurements.t[0]:g} s in {args.measurements}, the first sample the resampling "
                    "filter sees the record on both sides of.")
        lines.append(f"The record's {recorded.sample_rate:g} Hz are resampled to {rate:g} Hz, a whole number of samples per "
                     f"EA sub-window (ea_gym.measurements.resampled); at that rate the noise reads {noise * density:.2%}.")
    print("\n".join(lines[1:]))
    # the estimate holds to a few % on a record the model explains (noise_estimate): a factor 1.5 either way contradicts --noise
    if estimate > 1.5 * noise + NOISE_MARGIN:
        print(f"ea-gym phm: warning: --noise {noise:g} is likely too low for this record: alarms may be false", file=sys.stderr)
    elif noise > 1.5 * estimate + NOISE_MARGIN:
        print(f"ea-gym phm: warning: --noise {noise:g} is likely too high for this record: faults may be detected late", file=sys.stderr)
    inputs = RunInputs(noise_source="estimated" if args.noise is None else "--noise", noise_estimate=estimate,
                       load_noise_source=load_source, commissioning=commissioning, commissioning_source=source)
    results = write_phm_outputs(
        Path(args.out), run, chain, None, f"PHM chain on {args.measurements} ({model.name})", sections=lines,
        measurements=str(args.measurements), inputs=inputs,
    )
    _print_outcome(results, args.out)
    return 0


def _records(args: argparse.Namespace, model: SystemModel) -> tuple[Measurements, Measurements | None]:
    """The record (--measurements) and the healthy one (--commission, with the same columns and rate; None without),
    read and checked, --commission-seconds within the record."""
    from ea_gym.measurements import read_measurements

    columns, ignore = columns_given(args.columns), [name for names in args.ignore_columns for name in names]
    recorded = read_measurements(args.measurements, model, columns=columns, ignore=ignore, sample_rate=args.sample_rate)
    healthy = None
    if args.commission is not None:
        healthy = read_measurements(args.commission, model, columns=columns, ignore=ignore, sample_rate=args.sample_rate)
        if healthy.sample_rate != recorded.sample_rate:
            raise ValueError(f"--commission: {args.commission} is sampled at {healthy.sample_rate:g} Hz, {args.measurements} at "
                             f"{recorded.sample_rate:g} Hz; expected a healthy record at the record's rate")
    if args.commission_seconds is not None:
        seconds_within("--commission-seconds", args.commission_seconds, COMMISSION_LEAST, recorded.duration, args.measurements)
    return recorded, healthy


def _print_outcome(results: dict, out: str) -> None:
    from ea_gym.reporting import fit_text
    from ea_gym.reporting.report import degrading_text, isolation_text

    detection = results["detection_time"]
    outcome = "no fault detected" if detection is None else f"detection at {detection:g} s, isolated parameter {isolation_text(results)}"
    print(fit_text(results))
    print(degrading_text(results))
    print(f"{outcome}; wrote {out}/results.json and report.md")


def _train_isolation(args: argparse.Namespace) -> int:
    from ea_gym.diagnosis.training import cached_isolation_path, isolation_network, shipped_classifier_path
    from ea_gym.model_files import load_system

    model = load_system(args.system)
    model.check_degradable()
    cached = cached_isolation_path(model)
    had = cached.is_file()
    classifier = isolation_network(model)
    if cached.is_file():  # the package ships none for this model
        where, state = cached, "already cached" if had else "trained and cached"
    else:
        where, state = shipped_classifier_path(model.name), "shipped with the package"
    print(f"isolation network for {model.name} (classes {', '.join(classifier.classes)}): {state} at {where}")
    return 0


def _reproduce(args: argparse.Namespace) -> int:
    from ea_gym.diagnosis.classifier import FaultClassifier
    from ea_gym.files import check_output_directory, staged_output
    from ea_gym.reproduce import headline, reproduce

    check_output_directory(args.out)
    classifier = None if args.classifier is None else FaultClassifier.load(args.classifier)
    with staged_output(args.out, last="results.json") as staging:
        summary = reproduce(staging, classifier, seed=args.seed)
    print(f"{headline(summary)}; {summary['wall_time_s']} s; wrote {args.out}/report.md")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The ``ea-gym`` parser: its own subcommands, then those of the ``ea_gym.commands`` entry points (train, benchmark)."""
    parser = _OneLineParser(
        prog="ea-gym",
        description="Energy-Activity prognostics and health management on bond-graph models.",
    )
    parser.add_argument("--debug", action="store_true", help="on an error, show the traceback too")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_simulate(commands)
    _add_phm(commands)
    _add_reproduce(commands)
    _add_models(commands)
    _add_train_isolation(commands)
    for entry in entry_points(group=COMMAND_GROUP):
        entry.load()(commands)
    return parser


def _add_simulate(commands: Subcommands) -> None:
    simulate = commands.add_parser(
        "simulate",
        help="simulate a scenario: each element's Energy Activity and EAI per window, or its sensors' record as CSV",
        description=(
            "Simulate the plant of a scenario file (JSON or YAML) under its load and fault profile and write "
            "DIR/energy.json (EA per window of every element, EAI of the R, C and I components) and "
            "DIR/energy.png (signals, parameters, EA and EAI over time). Computed from the plant's true "
            "efforts and flows. With --csv, also (or only) the measurements its sensors record."
        ),
    )
    simulate.add_argument("scenario", help="scenario file (.json, .yaml or .yml)")
    _add_system(simulate)
    simulate.add_argument("--out", metavar="DIR", help="directory for energy.json and energy.png (created)")
    simulate.add_argument(
        "--csv", metavar="FILE",
        help=("write what the plant's sensors record, with the scenario's sensor and load noise, as a measurement CSV for "
              "'ea-gym phm --measurements' (columns t, the load source, every storage element's signal)"),
    )
    simulate.add_argument(
        "--window", type=positive_float, default=1.0, metavar="SECONDS",
        help="Energy Activity window length in s, a whole number of sample periods (default: 1.0)",
    )
    simulate.set_defaults(run=_simulate)


def _add_phm(commands: Subcommands) -> None:
    phm = commands.add_parser(
        "phm",
        help="run the whole PHM chain on a scenario or on recorded measurements: detection, isolation, estimate, End of Life, RUL",
        description=(
            "Run the Energy-Activity PHM chain step by step on a simulated scenario (its plant, the fault-free "
            "reference model, measured with the scenario's sensor noise) or on a machine's recorded measurements "
            "(--system MODEL --measurements DATA.csv: the reference model driven by the recorded load). Writes "
            "DIR/results.json (whether the model fits the data, the parts judged degrading, every component's estimate, "
            "degrading probability and RUL with its interval at every step, detection time, isolated parameter, class "
            "probabilities, End-of-Life predictions and, for a scenario with faults, metrics against the truth per "
            "faulty part), the figures (time-frequency map, every component's estimate and RUL, signals; for a scenario "
            "also the estimate's error) and DIR/report.md; prints the model-fit verdict and the degrading parts. The "
            "chain's healthy machine is the model's nominal values, or the machine's own fitted on a healthy record "
            "(--commission) or the record's first seconds (--commission-seconds). The measurement CSV: one header row; "
            "a column t (s, increasing, uniformly sampled at any "
            "rate); a column named after the model's load source (its value, SI); one column per storage element named "
            "after it: an I element's flow (velocity, current), a C element's displacement q (extension, charge). "
            "Delimiter , or ; (a ; file may write 1,5 for 1.5); a UTF-8 byte-order mark is skipped. A header cell may "
            "give its unit in brackets, 't [s]' or 'v (mm/s)': the column's SI unit or a decimal prefix of it "
            "(converted); any other unit is refused. A record whose rate is not a multiple of 10 Hz is resampled to the "
            "next one (band-limited) for the chain."
        ),
    )
    phm.add_argument("scenario", nargs="?", help="scenario file (.json, .yaml or .yml); or use --measurements")
    _add_system(phm, "; with --measurements, the machine's model (required)")
    phm.add_argument("--out", required=True, metavar="DIR", help="directory for results.json, report.md and figures (created)")
    phm.add_argument(
        "--classifier", metavar="PATH", default=None,
        help="isolation network file (default: the one shipped for the system, else the cached one, else one trained now and cached)",
    )
    phm.add_argument("--measurements", metavar="DATA.csv", help="run the chain on this recorded CSV instead of a scenario")
    phm.add_argument(
        "--columns", type=column_mapping, action="append", default=[], metavar="NAME=COLUMN",
        help="with --measurements: read the model's column NAME (t, the load source, a storage element) from the file's COLUMN (repeatable)",
    )
    phm.add_argument(
        "--ignore-columns", type=column_names, action="append", default=[], metavar="A,B",
        help="with --measurements: leave these columns of the file unread (any other column the model does not name is refused)",
    )
    phm.add_argument(
        "--sample-rate", type=sample_rate_option, metavar="HZ",
        help=("with --measurements: the record's sample rate, where its timestamps are rounded (256 Hz written to 1 ms): "
              "each t must then lie within its rounding of t0 + k / HZ, and that grid is used (default: t's own, "
              "uniform within 1 %% of a period)"),
    )
    phm.add_argument(
        "--noise", type=non_negative_float, metavar="FRACTION",
        help=("with --measurements: the sensors' noise std as a fraction of each signal's RMS over a 1 s step "
              "(0.01 = 1 %%), which the detection thresholds are calibrated for (default: estimated from the "
              "record, from the innovations of a Kalman filter of the model's nominal values, ea_gym.measurements."
              "noise_estimate). Set it from a fault-free stretch of the record or the sensors' data sheet; "
              "the command prints the record's estimate and warns when --noise is off it by more than a factor "
              "1.5. Too low raises "
              "alarms on a healthy machine; too high detects faults later."),
    )
    phm.add_argument(
        "--load-noise", type=fraction_below_one("a load noise fraction in [0, 1)"), metavar="FRACTION",
        help=("with --measurements: the load measurement's noise std as a fraction of the load's RMS over a 1 s step, "
              "carried through the filters (default: 0, the load assumed exact; the model's residuals cannot tell it "
              "from the sensors' noise, so it is not estimated). results.json's run says which"),
    )
    phm.add_argument(
        "--commission", metavar="HEALTHY.csv",
        help=("with --measurements: a record of the same machine while healthy (the same columns, options and sample rate "
              "as DATA.csv, at least 2 s): the chain first fits the machine's own values of its parts (inside their "
              "limits) from it and takes them as the healthy machine, so that a machine off its catalogue values is not "
              "taken for a fault (ea_gym.phm.commission)"),
    )
    phm.add_argument(
        "--commission-seconds", type=positive_float, metavar="S",
        help=("commission the healthy machine from the first S seconds (at least 2, at most the record's duration) of the "
              "record itself (with a scenario: of its sensor record, as simulate --csv writes it); the machine is taken "
              "as healthy over them. The chain still diagnoses the whole record, those seconds included"),
    )
    phm.add_argument("--seed", type=int, default=None, help="with --measurements: seed of the threshold calibration (default 0)")
    phm.set_defaults(run=_phm)


def _add_reproduce(commands: Subcommands) -> None:
    reproduce = commands.add_parser(
        "reproduce",
        help="reproduce the paper's section 4 (Table 2 system, Fig 10 fault, Table 3 End of Life)",
        description=(
            "Train the isolation network on the fault database (unless --classifier is given), then run the "
            "chain on the paper's fault under the paper's constant load and under a persistently exciting "
            "load, each noise-free and at 1%% sensor noise. Writes DIR/results.json (eol_fault, "
            "eol_corrective and every run's numbers), DIR/report.md (beside the paper's Table 3) and one "
            "directory of figures per run."
        ),
    )
    reproduce.add_argument("--out", required=True, metavar="DIR", help="output directory (created)")
    reproduce.add_argument("--classifier", metavar="PATH", default=None, help="load this isolation network instead of training one")
    reproduce.add_argument("--seed", type=int, default=0, help="seed of the database, training and sensor noise (default 0)")
    reproduce.set_defaults(run=_reproduce)


def _add_system(parser: argparse.ArgumentParser, also: str = "") -> None:
    parser.add_argument(
        "--system", metavar="MODEL", default=None,
        help=f"the system to run instead of the scenario's: a built-in name (ea-gym models) or a model file (.yaml, .yml, .json){also}",
    )


def _add_models(commands: Subcommands) -> None:
    models = commands.add_parser(
        "models", help="list the built-in systems with their parameters and safe limits",
        description="List the built-in systems: name, description, every parameter's nominal value, unit and safe limits.",
    )
    models.set_defaults(run=_models)
    model = commands.add_parser(
        "model",
        help="check a model file and print its causality, states, parameters and limits",
        description=(
            "Check a model file (YAML or JSON: elements, bonds, load; see the README's Model files) and print "
            "each bond's causal stroke, each element's input, the states, the parameters with their limits and "
            "the load. A bad file: one line naming the element, bond or field and what was expected, exit code 2."
        ),
    )
    model.add_argument("file", help="model file (.yaml, .yml or .json)")
    model.set_defaults(run=_model)
def _add_train_isolation(commands: Subcommands) -> None:
    train = commands.add_parser(
        "train-isolation",
        help="train a system's isolation network ahead of time (it is cached for every later run)",
        description=(
            "Simulate the system's fault database and train its isolation network (about a minute), unless the "
            "package ships one for it or the cache already holds one. The cache is the user's cache directory, "
            "or $EA_GYM_CACHE_DIR; environments and `ea-gym phm` read the network from there."
        ),
    )
    train.add_argument(
        "--system", required=True, metavar="MODEL", help="the system: a built-in name (ea-gym models) or a model file (.yaml, .yml, .json)"
    )
    train.set_defaults(run=_train_isolation)


class _OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (with where to find the usage), exit code 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def error_line(error: BaseException) -> str:
    """An error's message on one line: a multi-line message (a scenario's problems) joined with '; '."""
    if isinstance(error, OSError) and error.strerror:
        return f"{error.filename}: {error.strerror}" if error.filename else error.strerror
    head, *rest = [line.strip() for line in str(error).splitlines() if line.strip()] or [type(error).__name__]
    return " ".join([head, "; ".join(rest)]) if rest else head


#: the arguments that name a command's input files, in the order an internal error names them
INPUT_ARGUMENTS = {"scenario": "", "file": "", "source": "", "system": "--system ", "measurements": "--measurements ", "commission": "--commission ",
                   "classifier": "--classifier ", "resume": "--resume ", "ppo": "--ppo ", "tuned": "--tuned "}


def _inputs(args: argparse.Namespace) -> str:
    """The command's input files as given on its command line."""
    named = [f"{flag}{getattr(args, name)}" for name, flag in INPUT_ARGUMENTS.items() if getattr(args, name, None) not in (None, False)]
    return ", ".join(named) or "its arguments"


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; a bad input is one line on stderr and exit code 2, an interruption (SIGINT, SIGTERM) exit code 130 or
    143 once the outputs staged so far are removed; ``--debug`` lets the exception through, with its traceback."""
    parser = build_parser()
    args = parser.parse_args(argv)
    prefix = f"ea-gym {args.command}"
    try:
        with interrupts_raised():
            return int(args.run(args))
    except (ValueError, TypeError, OSError) as error:  # bad input (ScenarioError, ParameterError, ...): one line, exit 2
        if args.debug:
            raise
        print(f"{prefix}: error: {error_line(error)}", file=sys.stderr)
    except KeyboardInterrupt as interrupt:
        if args.debug:
            raise
        terminated = isinstance(interrupt, Terminated)
        print(f"{prefix}: {'terminated (SIGTERM)' if terminated else 'interrupted (SIGINT)'}; outputs in progress removed", file=sys.stderr)
        return 128 + int(signal.SIGTERM if terminated else signal.SIGINT)
    except Exception as error:  # a case no check caught: still one line, naming the inputs, and that it is the program's fault
        if args.debug:
            raise
        print(f"{prefix}: error: internal error ({type(error).__name__}: {error_line(error)}) on {_inputs(args)}; "
              "rerun with --debug for the traceback", file=sys.stderr)
    return 2


if __name__ == "__main__":
    raise SystemExit(main())
