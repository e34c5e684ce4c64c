"""The ``ea-gym`` command."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from ea_gym.models import ParameterError
from ea_gym.scenario import ScenarioError


def _simulate(args: argparse.Namespace) -> int:
    from ea_gym.energy import windowed_energy
    from ea_gym.files import write_json
    from ea_gym.plant import simulate
    from ea_gym.plots import plot_energy
    from ea_gym.scenario import load_scenario

    scenario = load_scenario(args.scenario)
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


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ea-gym",
        description="Energy-Activity prognostics and health management on bond-graph models.",
    )
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

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
    simulate.add_argument("--out", required=True, metavar="DIR", help="directory for energy.json and energy.png (created)")
    simulate.add_argument(
        "--window", type=_positive_float, default=1.0, metavar="SECONDS",
        help="Energy Activity window length in s, a whole number of sample periods (default: 1.0)",
    )
    simulate.set_defaults(run=_simulate)
    return parser


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
