"""The ``train``, ``benchmark`` and ``convert-agent`` subcommands of ``ea-gym``, added through the
``ea_gym.commands`` entry points.

The library (``ea_gym``) never imports the agents; it finds these through the entry-point group
(pyproject.toml). torch and stable-baselines3 are imported inside the commands only, so ``ea-gym --help``
stays fast.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
from pathlib import Path
from typing import Any

from agents.conventions import AGENT_FILE, POLICY_FILE, SB3_MODEL_FILE, SB3_NORMALIZATION_FILE, SUMMARY_FILE, TRUST_PICKLE, refuse_pickle
from ea_gym.cli_args import Subcommands, env_option, fraction_below_one, non_negative_int, positive_int, system_option
from ea_gym.files import check_output_directory, staged_output

__all__ = ["add_train", "add_benchmark", "add_convert_agent", "default_agent", "BENCHMARK_POLICIES"]

#: ``--trust-pickle``'s help, the same on every command that loads an agent
TRUST_PICKLE_HELP = (
    f"also load stable-baselines3's own files ({SB3_MODEL_FILE}, {SB3_NORMALIZATION_FILE}, checkpoint .zip): they are "
    "unpickled, which runs any code they hold, so only for files you trust; without it they are refused"
)


def _env_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """The environment keywords of ``--env`` and ``--system`` (checked before anything heavy is imported)."""
    kwargs = dict(args.env)
    if args.system is not None:
        kwargs["system"] = system_option(args.system)
    from ea_gym.env.config import EnvConfig, env_config

    settings = {f.name for f in dataclasses.fields(EnvConfig)}
    env_config(**{key: value for key, value in kwargs.items() if key in settings})  # a bad value refused before --out is made
    return kwargs


def _continues_out(args: argparse.Namespace) -> bool:
    """Whether ``train`` continues its ``--out`` (``--resume`` is that directory or one of its checkpoints); another
    existing, non-empty ``--out`` is refused: a new run's files would mix with the old ones."""
    out = Path(args.out)
    if not out.is_dir() or not any(out.iterdir()):
        return False
    resume = None if args.resume is None else Path(args.resume).resolve()
    if resume is not None and (resume == out.resolve() or out.resolve() in resume.parents):
        return True
    raise ValueError(f"--out: {out} exists and is not empty; expected a new or empty directory, or the --resume agent's own "
                     "directory to continue it")


def _check_agent(path: Path | None) -> None:
    """An agent directory's agent.json checked before torch is imported: a bad one is refused at once (a directory without
    one, stable-baselines3's pickles, is refused by ``refuse_pickle``)."""
    if path is not None and path.is_dir() and os.path.lexists(path / AGENT_FILE):
        from agents.agent_document import read_agent_document

        read_agent_document(path)


def _train(args: argparse.Namespace) -> int:
    check_output_directory(args.out)
    continues = _continues_out(args)
    _check_agent(None if args.resume is None else Path(args.resume))
    env_kwargs = _env_kwargs(args)
    if args.backend == "rllib":
        return _train_rllib(args, env_kwargs)
    if args.resume is not None:
        refuse_pickle(Path(args.resume), args.trust_pickle)  # before torch is imported
    from agents.training import TrainingRun, train

    run = TrainingRun(
        algo=args.algo, timesteps=args.timesteps, obs_mode=args.obs_mode, n_envs=args.n_envs, seed=args.seed, env_kwargs=env_kwargs,
        vec_env=args.vec_env, eval_every=args.eval_every, eval_episodes=args.eval_episodes,
        teacher=args.teacher, teacher_parameter=args.teacher_parameter, teacher_steps=args.teacher_steps,
        dagger_rounds=args.dagger_rounds, wear_shaping=not args.no_wear_shaping, shaping_onset=args.shaping_onset,
        initial_carry_on=None if args.initial_carry_on == 0 else args.initial_carry_on,
    )
    resume = None if args.resume is None else Path(args.resume)
    # checkpoints land in the staging directory as the run goes; --out appears (or is replaced) only when it completes
    with staged_output(args.out, last=SUMMARY_FILE, carry_existing=continues) as staging:
        summary = train(run, staging, resume=resume, progress_bar=not args.no_progress, trust_pickle=args.trust_pickle)
    print(f"trained {args.algo} for {summary['steps']} steps in {summary['wall_time_s']} s ({summary['steps_per_s']} steps/s); wrote {args.out}")
    return 0


def _train_rllib(args: argparse.Namespace, env_kwargs: dict[str, Any]) -> int:
    sb3_only = [flag for flag, used in (("--algo", args.algo != "ppo"), ("--teacher", args.teacher is not None),
                                        ("--resume", args.resume is not None), ("--vec-env", args.vec_env != "batched"),
                                        ("--dagger-rounds", args.dagger_rounds > 0), ("--system", args.system is not None),
                                        ("--no-wear-shaping", args.no_wear_shaping), ("--shaping-onset", args.shaping_onset != 0.3),
                                        ("--initial-carry-on", args.initial_carry_on != 0.8)) if used]
    if sb3_only:
        raise ValueError(f"--backend rllib trains PPO from scratch on the spring-mass-damper's native vector env: drop {', '.join(sb3_only)}")
    from agents.ray_cluster import require_ray

    require_ray("--backend rllib")
    from agents.rllib_training import RLlibRun, train_rllib

    run = RLlibRun(timesteps=args.timesteps, obs_mode=args.obs_mode, num_env_runners=args.num_env_runners, envs_per_env_runner=args.n_envs,
                   seed=args.seed, env_kwargs=env_kwargs)
    with staged_output(args.out, last=SUMMARY_FILE) as staging:
        summary = train_rllib(run, staging, address=args.ray, say=(lambda line: None) if args.no_progress else print)
    print(f"trained ppo with RLlib for {summary['env_steps_sampled']} steps in {summary['wall_time_s']} s ({summary['steps_per_s']} steps/s, "
          f"episodes {summary['episodes']}); wrote {args.out}")
    return 0


def _benchmark(args: argparse.Namespace) -> int:
    check_output_directory(args.out)
    ppo = None if args.no_ppo else (Path(args.ppo) if args.ppo is not None else default_agent())
    _check_agent(ppo)
    env_kwargs = _env_kwargs(args)
    from agents.benchmark.run import run_benchmark

    result = run_benchmark(
        args.episodes, args.seed, Path(args.out), ppo, tune_episodes=args.tune_episodes, progress=not args.no_progress, tune=args.tune,
        tuned_file=None if args.tuned is None else Path(args.tuned), write_tuned_to=None if args.write_tuned is None else Path(args.write_tuned),
        allow_stale=args.allow_stale, trust_pickle=args.trust_pickle, env_kwargs=env_kwargs, ray=args.ray,
    )
    rows = result["policies"]
    ranking = ", ".join(f"{name} {rows[name]['mean_cost']:.0f}" for name in result["ranking"])
    skipped = "".join(f"; skipped {name}: {note}" for name, note in result["skipped"].items())
    print(f"mean episode cost: {ranking}{skipped}; wrote {args.out}/benchmark.md")
    return 0


def _convert_agent(args: argparse.Namespace) -> int:
    refuse_pickle(Path(args.source), args.trust_pickle)  # before torch is imported
    from agents.training import convert_agent

    convert_agent(Path(args.source), Path(args.destination), trust_pickle=args.trust_pickle)
    print(f"wrote {args.destination}/{AGENT_FILE} and {POLICY_FILE} from {args.source}")
    return 0


def _add_environment(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--system", metavar="MODEL", default=None,
        help="the machine: a built-in name (ea-gym models) or a model file (.yaml, .yml, .json); default spring_mass_damper",
    )
    parser.add_argument(
        "--env", type=env_option, action="append", default=[], metavar="KEY=VALUE",
        help="an environment keyword (ea_gym.env.EnvConfig's fields, e.g. horizon=600), VALUE read as JSON; repeatable",
    )


def default_agent() -> Path | None:
    """``agents/data/ppo_phm`` beside the installed package, if a policy was trained there."""
    directory = Path(__file__).parent / "data" / "ppo_phm"
    return directory if directory.is_dir() else None


def add_train(commands: Subcommands) -> None:
    """``ea-gym train``: train a maintenance policy with stable-baselines3."""
    train = commands.add_parser(
        "train",
        help="train a maintenance policy with stable-baselines3 on the batched environment",
        description=(
            "Train PPO, A2C or DQN on ea_gym/SpringMassDamper-v0 (BondGraphMaintenance-v0 with --system; "
            "continue_after_failure=True) with normalised "
            "observations and rewards. DIR becomes an agent directory: DIR/agent.json (algorithm, architecture, spaces, "
            "normalisation statistics as numbers), DIR/policy.safetensors and DIR/optimizer.safetensors (weights and "
            "optimizer state; loading them runs no code from the files): of the policies evaluated on held-out validation "
            "seeds (every --eval-every steps, each checkpointed in DIR/checkpoints/ALGO_STEPS_steps, and the last one, kept in "
            "DIR/last), the one with the best mean validation reward. DIR/training.json records the run, every evaluation's "
            "rewards and the step selected; with tensorboard installed, DIR/tensorboard holds the logs."
        ),
    )
    train.add_argument("--algo", choices=["ppo", "dqn", "a2c"], default="ppo", help="algorithm (default ppo)")
    train.add_argument("--timesteps", type=positive_int, default=200_000,
                       help="environment steps, exactly: a multiple of --n-envs (default 200000); a last rollout shorter than "
                            "the others takes what whole rollouts leave")
    train.add_argument("--obs-mode", choices=["phm", "sensors", "oracle"], default="phm", help="information regime (default phm)")
    train.add_argument("--out", required=True, metavar="DIR",
                       help="output directory, new or empty, or the --resume agent's own directory (or the one holding its "
                            "checkpoint) to continue it, earlier checkpoints kept; the run writes beside it and DIR appears, "
                            "or is replaced, only when the run completes")
    train.add_argument("--n-envs", type=positive_int, default=16, help="parallel environments (default 16)")
    train.add_argument("--vec-env", choices=["batched", "subproc"], default="batched",
                       help="the native batched VecEnv (default) or a SubprocVecEnv of single environments")
    train.add_argument("--seed", type=int, default=0, help="seed of the algorithm and of the training environments (default 0)")
    train.add_argument("--eval-every", type=positive_int, default=20_000,
                       help="steps between evaluations, each one checkpointed (default 20000)")
    train.add_argument("--eval-episodes", type=positive_int, default=32, help="validation episodes per evaluation (default 32)")
    train.add_argument(
        "--resume", metavar="AGENT", default=None,
        help="continue from an agent directory (an earlier --out or one of its checkpoints) with the same --algo, --obs-mode "
             "and environment: weights, optimizer state, normalisation statistics, hyperparameters and step count are "
             "restored; PPO's rollout and DQN's replay buffer start afresh. With --trust-pickle also a stable-baselines3 "
             "checkpoint .zip (its vecnormalize .pkl beside it)",
    )
    train.add_argument(TRUST_PICKLE, action="store_true", help=TRUST_PICKLE_HELP)
    teachers = ["rul_threshold", "corrective_band", "corrective_band_quiet", "oracle", "oracle_corrective", "periodic"]
    train.add_argument("--teacher", choices=teachers, default=None,
                       help="clone this rule policy into the actor-critic before learning (PPO, A2C; default none)")
    train.add_argument("--teacher-parameter", type=float, default=None,
                       help="the teacher's RUL threshold or period in s, or its band for every component (default: agents.training.TEACHERS)")
    train.add_argument("--teacher-steps", type=positive_int, default=100_000,
                       help="environment steps the teacher runs, and each DAgger round (default 100000)")
    train.add_argument("--dagger-rounds", type=non_negative_int, default=0,
                       help="DAgger rounds after the cloning: the learner acts, the teacher labels, the policy is refitted "
                            "on all labelled steps (default 0; needs --teacher)")
    train.add_argument("--initial-carry-on", type=fraction_below_one("a probability in (0, 1), or 0 for a uniform start"), default=0.8, metavar="P",
                       help="a new PPO or A2C policy carries on with probability P, the maintenance actions sharing the rest in "
                            "inverse proportion to their immediate cost (agents.initial_policy); 0: stable-baselines3's uniform "
                            "start (default 0.8)")
    train.add_argument("--no-wear-shaping", action="store_true",
                       help="train on the environment's own rewards, without the potential-based shaping by the parts' true "
                            "wear (agents.shaping; validation always uses the environment's rewards)")
    train.add_argument("--shaping-onset", type=fraction_below_one("a wear in [0, 1)"), default=0.3, metavar="W",
                       help="the wear (0 at nominal, 1 at the safe limit) from which the shaping charges a part's wear, "
                            "rising to the failure cost at the limit (agents.shaping; default 0.3; 0: from nominal on)")
    train.add_argument("--no-progress", action="store_true", help="no progress bar")
    _add_environment(train)
    rllib = train.add_argument_group("RLlib", "--backend rllib: PPO with Ray RLlib (the optional extra ea-gym[rllib]); --n-envs is per env runner")
    rllib.add_argument("--backend", choices=["sb3", "rllib"], default="sb3", help="stable-baselines3 (default) or Ray RLlib's PPO")
    rllib.add_argument("--num-env-runners", type=non_negative_int, default=2,
                       help="RLlib env runners, each a process stepping one native vector env of --n-envs systems (default 2)")
    rllib.add_argument("--ray", metavar="ADDRESS", default=None,
                       help="the Ray cluster to run on (the address `ray start --head` prints, or auto); default a local Ray")
    train.set_defaults(run=_train)


#: the policies ``ea-gym benchmark`` evaluates, in its order (agents.benchmark.evaluation.EVALUATION_ORDER)
BENCHMARK_POLICIES = (
    "oracle (Oracle on the true state, obs_mode oracle), ppo (the trained PPO agent, its own obs_mode), rul_threshold "
    "(RulThreshold on the PHM chain's diagnosis and RUL), corrective_band (CorrectiveBand on the PHM chain's estimates), "
    "periodic (Periodic block replacement, sensors), run_to_failure (RunToFailure, sensors)"
)


def add_benchmark(commands: Subcommands) -> None:
    """``ea-gym benchmark``: compare the maintenance policies on common seeds."""
    benchmark = commands.add_parser(
        "benchmark",
        help="compare the maintenance policies (oracle, ppo, rul_threshold, corrective_band, periodic, run_to_failure) on common seeds",
        description=(
            f"Evaluate every policy on the same N evaluation seeds (100000 + S * 10000 + i, disjoint from the training, "
            f"validation and tuning seeds) on ea_gym/SpringMassDamper-v0 (BondGraphMaintenance-v0 with --system) with "
            f"continue_after_failure=True: {BENCHMARK_POLICIES}. "
            "The rules' tuned settings (thresholds, actions, bands, period) are read from agents/data/benchmark/tuned_rules.json, "
            "which records the command, seeds and environment they were tuned on; a file tuned on another environment "
            "(another --system or --env, other PHM settings: its fingerprint differs) is refused. --tune grid-searches "
            "them again on tuning seeds 0..K-1 instead (at "
            "K = 300 about 7 minutes of CPU: 40 minutes on a shared 2-core machine). Writes DIR/benchmark.json (mean "
            "cost with its 95 % interval, failures, availability, maintenance actions and cost ratio to the oracle per "
            "policy), DIR/benchmark.md (the table "
            "sorted by mean cost, the tuned settings and where they came from, the command), DIR/cost_distribution.png "
            "and DIR/timelines.png (one episode per policy)."
        ),
    )
    benchmark.add_argument("--episodes", type=positive_int, default=100, metavar="N",
                           help="evaluation episodes per policy, for each of oracle, ppo, rul_threshold, corrective_band, periodic "
                                "and run_to_failure (default 100)")
    benchmark.add_argument("--seed", type=int, default=0, help="benchmark seed S: evaluation seeds 100000 + S * 10000 + i (default 0)")
    benchmark.add_argument("--out", required=True, metavar="DIR",
                           help="output directory (created); its files are written beside it and moved in together when the run completes")
    ppo_choice = benchmark.add_mutually_exclusive_group()
    ppo_choice.add_argument(
        "--ppo", metavar="DIR", default=None,
        help="trained agent directory (agent.json, policy.safetensors, training.json from ea-gym train); default "
        "agents/data/ppo_phm of the installed package when it exists; a directory without an agent is skipped with a note",
    )
    ppo_choice.add_argument("--no-ppo", action="store_true", help="evaluate no PPO agent (noted as skipped)")
    tuning = benchmark.add_mutually_exclusive_group()
    tuning.add_argument("--tune", action="store_true", help="tune the rules now on the tuning seeds instead of reading their tuned settings")
    tuning.add_argument("--tuned", metavar="PATH", default=None,
                        help="read the rules' tuned settings from PATH (default agents/data/benchmark/tuned_rules.json)")
    benchmark.add_argument("--tune-episodes", type=positive_int, default=None, metavar="K",
                           help="with --tune: tuning episodes per grid value, seeds 0..K-1 (default 300)")
    benchmark.add_argument("--write-tuned", metavar="PATH", default=None,
                           help="with --tune: write the tuned settings to PATH (e.g. agents/data/benchmark/tuned_rules.json), with the "
                                "outputs when the run completes")
    benchmark.add_argument("--allow-stale", action="store_true",
                           help="use tuned settings made on another environment instead of refusing them (the report says so)")
    benchmark.add_argument("--ray", nargs="?", const="local", default=None, metavar="ADDRESS",
                           help="run the tuning, evaluation and timeline episodes as Ray tasks (the same records; the optional extra ea-gym[rllib]): "
                                "on a local Ray, or on the cluster at ADDRESS (the address `ray start --head` prints, or auto)")
    benchmark.add_argument("--no-progress", action="store_true", help="no progress bars")
    benchmark.add_argument(TRUST_PICKLE, action="store_true", help=TRUST_PICKLE_HELP)
    _add_environment(benchmark)
    benchmark.set_defaults(run=_benchmark)


def add_convert_agent(commands: Subcommands) -> None:
    """``ea-gym convert-agent``: stable-baselines3's files of an agent as an agent directory without pickle."""
    convert = commands.add_parser(
        "convert-agent",
        help="write an agent saved as stable-baselines3's files (model.zip, vecnormalize.pkl) as an agent directory without pickle",
        description=(
            "Read SRC (model.zip, vecnormalize.pkl and training.json of an earlier ea-gym train) and write DST/agent.json, "
            "DST/policy.safetensors, DST/optimizer.safetensors and DST/training.json, which ea-gym train --resume and "
            "ea-gym benchmark --ppo load without unpickling anything. Reading SRC unpickles it, which runs any code it "
            f"holds: {TRUST_PICKLE} is required, for files you trust."
        ),
    )
    convert.add_argument("source", metavar="SRC", help="directory holding model.zip, vecnormalize.pkl and training.json")
    convert.add_argument("destination", metavar="DST", help="agent directory to write (created)")
    convert.add_argument(TRUST_PICKLE, action="store_true", help="unpickle SRC (required: the files may run code)")
    convert.set_defaults(run=_convert_agent)
