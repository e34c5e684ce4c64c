"""The ``ea-gym`` command."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from importlib.metadata import entry_points
from pathlib import Path

from ea_gym.cli_args import COMMAND_GROUP, Subcommands, positive_float
from ea_gym.models import ParameterError, SystemModel
from ea_gym.scenario import ScenarioError


def _simulate(args: argparse.Namespace) -> int:
    from ea_gym.energy import windowed_energy
    from ea_gym.files import write_json
    from ea_gym.plant import simulate
    from ea_gym.plots import plot_energy
    from ea_gym.scenario import load_scenario

    scenario = load_scenario(args.scenario, args.system)
    trajectory = simulate(scenario)
    energy = windowed_energy(
        trajectory.power, trajectory.sample_period, args.window, scenario.model.rco_elements
    )
    elements = {}
    for name, ea in energy.ea.items():
        elements[name] = {"ea": ea.tolist()}
        if name in energy.eai:
            elements[name]["eai"] = energy.eai[name].tolist()
    out = Path(args.out)
    plot_energy(trajectory, energy, out / "energy.png")
    write_json(out / "energy.json", {"window": args.window, "t": energy.t.tolist(), "elements": elements})
    print(f"wrote {out / 'energy.json'} and {out / 'energy.png'} ({len(energy.t)} windows of {args.window:g} s)")
    return 0


def _phm(args: argparse.Namespace) -> int:
    import numpy as np
    from tqdm import tqdm

    from ea_gym.phm import PHMConfig, build_chain, classifier_for, run_scenario
    from ea_gym.reporting import write_phm_outputs
    from ea_gym.scenario import load_scenario

    scenario = load_scenario(args.scenario, args.system)
    rng = np.random.default_rng(scenario.sensor_seed)
    model = scenario.model
    classifier = classifier_for(model, rng, args.classifier)
    config = PHMConfig(sample_rate=scenario.sample_rate, noise=scenario.noise)
    chain = build_chain(model, config, classifier, rng)
    run = run_scenario(scenario, chain, rng, progress=lambda steps: tqdm(steps, desc="PHM chain", unit="step", leave=False))
    results = write_phm_outputs(Path(args.out), run, chain, scenario, f"PHM chain on {args.scenario}")
    isolated = results["isolated_parameter"]
    print(f"detection at {results['detection_time']} s, isolated parameter {isolated}; wrote {args.out}/results.json and report.md")
    return 0


def _models(args: argparse.Namespace) -> int:
    from ea_gym.models import MODELS, get_model

    for name in MODELS:
        model = get_model(name)
        print(f"{name}: {model.description}")
        print("\n".join(_parameter_lines(model)))
    return 0


def _model(args: argparse.Namespace) -> int:
    from ea_gym.bondgraph import Kind
    from ea_gym.model_files import load_model_file

    model = load_model_file(args.file)
    space = model.state_space
    elements = model.graph.elements
    print(f"{model.name}: {model.description}" if model.description else model.name)
    print("causality (the causal stroke sits at the end of the bond whose element receives the effort):")
    for bond, setter in zip(model.graph.bonds, space.causality.effort_setter):
        print(f"  {bond.tail} -> {bond.head}: stroke at {bond.other(setter)} ({setter} sets the effort)")
    for name, signal in space.causality.inputs.items():
        kind = elements[name].kind
        note = " (integral)" if kind.is_storage else ""
        print(f"  {name} ({kind.value}): its input is its {signal}{note}")
    states = ", ".join(f"{name} ({'p' if elements[name].kind is Kind.I else 'q'})" for name in model.state_names)
    print(f"states: {states}")
    print("parameters:")
    print("\n".join(_parameter_lines(model)))
    constant = "".join(f"; {name} = {value:g} {model.units.get(name, '')}".rstrip() for name, value in model.source_values.items())
    print(
        f"load: {model.load_source}, nominal {model.nominal_load:g} {model.units.get(model.load_source, '')}".rstrip()
        + f", random loads up to {model.excitation_bandwidth:g} Hz{constant}"
    )
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


def _reproduce(args: argparse.Namespace) -> int:
    from ea_gym.diagnosis.classifier import FaultClassifier
    from ea_gym.reproduce import headline, reproduce

    classifier = None if args.classifier is None else FaultClassifier.load(args.classifier)
    summary = reproduce(Path(args.out), classifier, seed=args.seed)
    print(f"{headline(summary)}; {summary['wall_time_s']} s; wrote {args.out}/report.md")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The ``ea-gym`` parser: its own subcommands, then those of the ``ea_gym.commands`` entry points (train, benchmark)."""
    parser = argparse.ArgumentParser(
        prog="ea-gym",
        description="Energy-Activity prognostics and health management on bond-graph models.",
    )
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_simulate(commands)
    _add_phm(commands)
    _add_reproduce(commands)
    _add_models(commands)
    for entry in entry_points(group=COMMAND_GROUP):
        entry.load()(commands)
    return parser


def _add_simulate(commands: Subcommands) -> None:
    simulate = commands.add_parser(
        "simulate",
        help="simulate a scenario and write each element's Energy Activity and EAI per window",
        description=(
            "Simulate the plant of a scenario file (JSON or YAML) under its load and fault profile and write "
            "DIR/energy.json (EA per window of every element, EAI of the R, C and I components) and "
            "DIR/energy.png (signals, parameters, EA and EAI over time). Computed from the plant's true "
            "efforts and flows."
        ),
    )
    simulate.add_argument("scenario", help="scenario file (.json, .yaml or .yml)")
    _add_system(simulate)
    simulate.add_argument("--out", required=True, metavar="DIR", help="directory for energy.json and energy.png (created)")
    simulate.add_argument(
        "--window", type=positive_float, default=1.0, metavar="SECONDS",
        help="Energy Activity window length in s, a whole number of sample periods (default: 1.0)",
    )
    simulate.set_defaults(run=_simulate)


def _add_phm(commands: Subcommands) -> None:
    phm = commands.add_parser(
        "phm",
        help="run the whole PHM chain on a scenario: detection, isolation, parameter estimate, End of Life and RUL",
        description=(
            "Simulate the scenario's plant and the fault-free reference model, measure with the scenario's "
            "sensor noise, and run the Energy-Activity PHM chain step by step. Writes DIR/results.json "
            "(detection time, isolated parameter, class probabilities, the parameter estimate over time, "
            "End-of-Life predictions and, when the scenario has a fault, metrics against the truth), the "
            "figures (time-frequency map, estimate vs truth, estimate error, RUL, signals) and DIR/report.md."
        ),
    )
    phm.add_argument("scenario", help="scenario file (.json, .yaml or .yml)")
    _add_system(phm)
    phm.add_argument("--out", required=True, metavar="DIR", help="directory for results.json, report.md and figures (created)")
    phm.add_argument(
        "--classifier", metavar="PATH", default=None,
        help="isolation network file (default: the one shipped for the system; trained on the spot if there is none)",
    )
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


def _add_system(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--system", metavar="MODEL", default=None,
        help="the system to run instead of the scenario's: a built-in name (ea-gym models) or a model file (.yaml, .yml, .json)",
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


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except (ScenarioError, ParameterError, ValueError) as error:
        print(f"ea-gym {args.command}: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
