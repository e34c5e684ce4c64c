"""Benchmark of the maintenance policies: regenerates experiments/results/benchmark/.

What it measures
    ``agents.benchmark.run_benchmark`` on the default ``ea_gym/SpringMassDamper-v0`` (horizon 500 steps of
    1 s, default costs and wear, ``continue_after_failure=True``): the Oracle (true state; replacement or
    corrective action and threshold tuned), the trained PPO agent ``agents/data/ppo_phm`` (when it
    exists), RulThreshold on the PHM chain (action and threshold tuned), CorrectiveBand on the PHM chain
    (band tuned), Periodic (period tuned) and RunToFailure, all on the same evaluation seeds
    100000 + seed * 10000 + i. For the value of information it also evaluates, when present, the PPO
    agents trained on the other information regimes, ``agents/data/ppo_sensors`` and
    ``agents/data/ppo_oracle`` (missing ones are listed as skipped).

    The rules' tuned settings are read from ``agents/data/benchmark/tuned_rules.json`` (the grid winners
    on tuning seeds 0..299, with the command that tuned them and the fingerprint of the environment they
    were tuned on: a file tuned on another environment is refused). ``--tune`` tunes them again (300
    episodes per grid value: a PHM policy's cost is decided by rare failures, a few in a hundred
    episodes, 480 each, which 30 episodes mostly miss); ``--tune --write-tuned PATH`` writes them.

How to run (from the repository root)
    .venv/bin/python experiments/benchmarks/benchmark_policies.py [--episodes 100] [--seed 0]
        [--tune [--tune-episodes 300] [--write-tuned PATH] | --tuned PATH [--allow-stale]]
        [--ppo DIR | --no-ppo] [--out DIR] [--no-progress] [--trust-pickle] [--smoke]

    Writes DIR/benchmark.json, benchmark.md, cost_distribution.png, timelines.png and timelines.json
    (default DIR: experiments/results/benchmark), atomically, with the exact command in the markdown.
    The policies of one obs_mode (and, tuning, a grid's values) run side by side on one batched
    environment (its episodes equal the single environment's bit for bit); only the timelines step
    one environment.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))  # this checkout's agents and experiments.common, installed or not

from agents.benchmark.run import TUNE_EPISODES, run_benchmark
from experiments.common import parse_with_smoke

DATA = ROOT / "agents" / "data"
DEFAULT_OUT = ROOT / "experiments" / "results" / "benchmark"
EXTRA_PPO = ("ppo_sensors", "ppo_oracle")
#: the smoke run: two evaluation episodes per policy, the committed tuned settings
SMOKE = {"episodes": 2, "no_progress": True}


def _relative(path: Path) -> str:
    try:
        return str(Path(path).resolve().relative_to(ROOT))
    except ValueError:
        return str(path)


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=100, help="evaluation episodes per policy (default 100)")
    parser.add_argument("--seed", type=int, default=0, help="benchmark seed: evaluation seeds 100000 + seed * 10000 + i (default 0)")
    tuning = parser.add_mutually_exclusive_group()
    tuning.add_argument("--tune", action="store_true", help="tune the rules now instead of reading their tuned settings")
    tuning.add_argument("--tuned", type=Path, default=None, help="tuned settings to read (default agents/data/benchmark/tuned_rules.json)")
    parser.add_argument("--tune-episodes", type=int, default=None, help="with --tune: tuning episodes per grid value (default 300)")
    parser.add_argument("--write-tuned", type=Path, default=None, help="with --tune: write the tuned settings there")
    parser.add_argument("--allow-stale", action="store_true", help="use tuned settings made on another environment")
    ppo = parser.add_mutually_exclusive_group()
    ppo.add_argument("--ppo", type=Path, default=None, help="trained agent directory (default agents/data/ppo_phm when it exists)")
    ppo.add_argument("--no-ppo", action="store_true", help="evaluate no PPO agent")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder (default experiments/results/benchmark)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    parser.add_argument("--trust-pickle", action="store_true",
                        help="also load agents saved as stable-baselines3's files (model.zip, vecnormalize.pkl), which run any code they hold")
    args = parse_with_smoke(parser, argv, SMOKE)
    if args.episodes < 2 or (args.tune_episodes is not None and args.tune_episodes < 1):
        parser.error("--episodes must be >= 2 and --tune-episodes >= 1")
    if not args.tune and (args.tune_episodes is not None or args.write_tuned is not None):
        parser.error("--tune-episodes and --write-tuned apply to tuning only: add --tune")

    default_ppo = DATA / "ppo_phm"
    main_ppo = None if args.no_ppo else (args.ppo if args.ppo is not None else (default_ppo if default_ppo.is_dir() else None))
    extra = {name: DATA / name for name in EXTRA_PPO}
    words = [".venv/bin/python", "experiments/benchmarks/benchmark_policies.py", *(sys.argv[1:] if argv is None else argv)]
    command = shlex.join(words)
    cli = ["ea-gym", "benchmark", "--episodes", str(args.episodes), "--seed", str(args.seed), "--out", _relative(args.out)]
    if args.tune:
        cli += ["--tune", "--tune-episodes", str(args.tune_episodes or TUNE_EPISODES)]
        cli += ["--write-tuned", _relative(args.write_tuned)] if args.write_tuned is not None else []
    else:
        cli += ["--tuned", _relative(args.tuned)] if args.tuned is not None else []
        cli += ["--allow-stale"] if args.allow_stale else []
    cli += ["--ppo", _relative(main_ppo)] if main_ppo is not None else ["--no-ppo"]
    note = (
        f"Run from the repository root. The main table without the extra PPO agents ({', '.join(EXTRA_PPO)}) is also "
        f"`{shlex.join(cli)}`. PPO agents: {', '.join(f'{n} = {_relative(p)}' for n, p in {'ppo': main_ppo, **extra}.items() if p is not None)}."
    )

    started = time.perf_counter()
    result = run_benchmark(
        args.episodes, args.seed, args.out, main_ppo, tune_episodes=args.tune_episodes, progress=not args.no_progress,
        tune=args.tune, tuned_file=args.tuned, write_tuned_to=args.write_tuned, allow_stale=args.allow_stale,
        ppo_policies=extra, command=command, command_note=note, trust_pickle=args.trust_pickle,
    )
    wall = time.perf_counter() - started
    print((args.out / "benchmark.md").read_text())
    print(f"wall time {wall:.0f} s ({wall / 60:.1f} min); wrote {args.out}")
    return result


if __name__ == "__main__":
    main()
