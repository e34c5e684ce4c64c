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


def _phm(args: argparse.Namespace) -> int:
    import numpy as np
    from tqdm import tqdm

    from ea_gym.phm import PHMConfig, build_chain, classifier_for, run_scenario
    from ea_gym.reporting import write_phm_outputs
    from ea_gym.scenario import load_scenario

    scenario = load_scenario(args.scenario)
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


def _reproduce(args: argparse.Namespace) -> int:
    from ea_gym.diagnosis.classifier import FaultClassifier
    from ea_gym.reproduce import reproduce

    classifier = None if args.classifier is None else FaultClassifier.load(args.classifier)
    summary = reproduce(Path(args.out), classifier, seed=args.seed)
    print(
        f"End of Life, fault: {summary['eol_fault']:.1f} s (truth {summary['eol_fault_true']:.1f} s, paper 55 s); "
        f"corrective action: {summary['eol_corrective']:.1f} s (truth {summary['eol_corrective_true']:.1f} s, paper 113 s); "
        f"{summary['wall_time_s']} s; wrote {args.out}/report.md"
    )
    return 0


def _train(args: argparse.Namespace) -> int:
    from agents.training import TrainingRun, train

    run = TrainingRun(
        algo=args.algo, timesteps=args.timesteps, obs_mode=args.obs_mode, n_envs=args.n_envs, seed=args.seed,
        vec_env=args.vec_env, eval_every=args.eval_every, checkpoint_every=args.checkpoint_every, eval_episodes=args.eval_episodes,
        teacher=args.teacher, teacher_parameter=args.teacher_parameter, teacher_steps=args.teacher_steps,
        dagger_rounds=args.dagger_rounds,
    )
    summary = train(run, Path(args.out), resume=None if args.resume is None else Path(args.resume), progress_bar=not args.no_progress)
    print(f"trained {args.algo} for {args.timesteps} steps in {summary['wall_time_s']} s ({summary['steps_per_s']} steps/s); wrote {args.out}")
    return 0


def _benchmark(args: argparse.Namespace) -> int:
    from agents.benchmark import run_benchmark

    ppo = None if args.no_ppo else (Path(args.ppo) if args.ppo is not None else _default_ppo())
    result = run_benchmark(args.episodes, args.seed, Path(args.out), ppo, tune_episodes=args.tune_episodes, progress=not args.no_progress)
    rows = result["policies"]
    ranking = ", ".join(f"{name} {rows[name]['mean_cost']:.0f}" for name in result["ranking"])
    skipped = "".join(f"; skipped {name}: {note}" for name, note in result["skipped"].items())
    print(f"mean episode cost: {ranking}{skipped}; wrote {args.out}/benchmark.md")
    return 0


def _default_ppo() -> Path | None:
    """``agents/data/ppo_phm`` beside the installed package, if a policy was trained there."""
    import agents

    directory = Path(agents.__file__).parent / "data" / "ppo_phm"
    return directory if directory.is_dir() else None


def _positive_int(text: str) -> int:
    value = int(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text}")
    return value


def _non_negative_int(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text}")
    return value


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
    phm.add_argument("--out", required=True, metavar="DIR", help="directory for results.json, report.md and figures (created)")
    phm.add_argument(
        "--classifier", metavar="PATH", default=None,
        help="isolation network file (default: the one shipped for the system; trained on the spot if there is none)",
    )
    phm.set_defaults(run=_phm)

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

    train = commands.add_parser(
        "train",
        help="train a maintenance policy with stable-baselines3 on the batched environment",
        description=(
            "Train PPO, A2C or DQN on ea_gym/SpringMassDamper-v0 (continue_after_failure=True) with normalised "
            "observations and rewards. Writes DIR/model.zip, DIR/vecnormalize.pkl, DIR/training.json, the best "
            "model on held-out validation seeds (DIR/best), checkpoints (DIR/checkpoints), evaluations and, when "
            "tensorboard is installed, TensorBoard logs (DIR/tensorboard)."
        ),
    )
    train.add_argument("--algo", choices=["ppo", "dqn", "a2c"], default="ppo", help="algorithm (default ppo)")
    train.add_argument("--timesteps", type=_positive_int, default=200_000, help="environment steps (default 200000)")
    train.add_argument("--obs-mode", choices=["phm", "sensors", "oracle"], default="phm", help="information regime (default phm)")
    train.add_argument("--out", required=True, metavar="DIR", help="output directory (created)")
    train.add_argument("--n-envs", type=_positive_int, default=16, help="parallel environments (default 16)")
    train.add_argument("--vec-env", choices=["batched", "subproc"], default="batched",
                       help="the native batched VecEnv (default) or a SubprocVecEnv of single environments")
    train.add_argument("--seed", type=int, default=0, help="seed of the algorithm and of the training environments (default 0)")
    train.add_argument("--eval-every", type=_positive_int, default=20_000, help="steps between evaluations (default 20000)")
    train.add_argument("--checkpoint-every", type=_positive_int, default=50_000, help="steps between checkpoints (default 50000)")
    train.add_argument("--eval-episodes", type=_positive_int, default=32, help="validation episodes per evaluation (default 32)")
    train.add_argument("--resume", metavar="CHECKPOINT", default=None, help="continue from a checkpoint .zip (or a model.zip)")
    train.add_argument("--teacher", choices=["rul_threshold", "corrective_band", "corrective_band_quiet", "oracle", "oracle_corrective", "periodic"], default=None,
                       help="clone this rule policy into the actor-critic before learning (PPO, A2C; default none)")
    train.add_argument("--teacher-parameter", type=float, default=None,
                       help="the teacher's RUL threshold or period in s, or its band for every component (default: agents.training.TEACHERS)")
    train.add_argument("--teacher-steps", type=_positive_int, default=100_000, help="environment steps the teacher runs, and each DAgger round (default 100000)")
    train.add_argument("--dagger-rounds", type=_non_negative_int, default=0,
                       help="DAgger rounds after the cloning: the learner acts, the teacher labels, the policy is refitted "
                            "on all labelled steps (default 0; needs --teacher)")
    train.add_argument("--no-progress", action="store_true", help="no progress bar")
    train.set_defaults(run=_train)

    benchmark = commands.add_parser(
        "benchmark",
        help="compare the maintenance policies (oracle, PPO, RUL threshold, periodic, run to failure) on common seeds",
        description=(
            "Tune the rule-based policies on tuning seeds 0..K-1 (RUL thresholds of the Oracle and of RulThreshold, "
            "Periodic's period), then evaluate every policy on the same N evaluation seeds (100000 + S * 10000 + i, "
            "disjoint from the training and validation seeds of ea-gym train) on ea_gym/SpringMassDamper-v0 with "
            "continue_after_failure=True: Oracle (obs_mode oracle), a trained PPO agent (its own obs_mode), "
            "RulThreshold (phm), Periodic (sensors) and RunToFailure (sensors). Writes DIR/benchmark.json (mean cost "
            "with its 95 % interval, failures, availability, maintenance actions and cost ratio to the oracle per "
            "policy), DIR/benchmark.md (the table sorted by mean cost, the tuned parameters and the command), "
            "DIR/cost_distribution.png and DIR/timelines.png (one episode per policy). The phm mode runs at about "
            "250 steps/s: the defaults take several minutes."
        ),
    )
    benchmark.add_argument("--episodes", type=_positive_int, default=100, help="evaluation episodes per policy (default 100)")
    benchmark.add_argument("--seed", type=int, default=0, help="benchmark seed S: evaluation seeds 100000 + S * 10000 + i (default 0)")
    benchmark.add_argument("--out", required=True, metavar="DIR", help="output directory (created)")
    ppo_choice = benchmark.add_mutually_exclusive_group()
    ppo_choice.add_argument(
        "--ppo", metavar="DIR", default=None,
        help="trained agent directory (model.zip, vecnormalize.pkl, training.json from ea-gym train); default "
        "agents/data/ppo_phm of the installed package when it exists; a directory without a model is skipped with a note",
    )
    ppo_choice.add_argument("--no-ppo", action="store_true", help="evaluate no PPO agent (noted as skipped)")
    benchmark.add_argument("--tune-episodes", type=_positive_int, default=300, metavar="K",
                           help="tuning episodes per grid value, seeds 0..K-1 (default 300)")
    benchmark.add_argument("--no-progress", action="store_true", help="no progress bars")
    benchmark.set_defaults(run=_benchmark)
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
