"""RLlib PPO (new API stack) on the native vector environment, beside gymnasium's SyncVectorEnv.

What it measures
    Two PPO runs of ``--timesteps`` environment steps each on a local Ray of ``--num-cpus`` CPUs, with
    ``--env-runners`` env runners of ``--envs-per-runner`` environments (obs_mode phm,
    continue_after_failure=True, 500-step episodes), through ``agents.rllib_training``:

    1. ``vector_entry_point``: each env runner steps one native vector environment (RLlib calls the
       registered env creator with ``num_envs``);
    2. ``sync``: RLlib's default, gymnasium's ``SyncVectorEnv`` of single environments.

    For each: every finished episode counted by its end (RLlib's ``on_episode_end`` callback): at the
    horizon (500 steps), failed (terminated), or of any other length (wrong episode boundaries: an
    autoreset mode RLlib does not expect gives 499-step episodes); RLlib's episode length min/max;
    the training's wall time; then the sampling throughput: every env runner samples
    ``--sampling-steps`` steps at once with the trained policy exploring (``foreach_env_runner``), the
    steps of all of them over the driver's wall time of that call (``--rounds`` rounds, the median).

Run from a checkout's root, in the virtual environment with the rllib extra (``bash scripts/test_ray.sh`` makes one):
    nice .venv-rllib/bin/python experiments/integrations/rllib_ppo.py --out experiments/results/rllib [--smoke]
Writes OUT/summary.json (every iteration's figures too); no checkpoints.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's ea_gym, agents and experiments.common, installed or not

from agents.rllib_training import EPISODE_COUNTS, VECTORIZE_MODES, RLlibRun, build_algorithm, train_iterations
from ea_gym.files import write_json
from experiments.common import parse_with_smoke

#: the smoke run: one short iteration per mode on one env runner of two environments, one small sampling round
SMOKE = {"timesteps": 200, "env_runners": 1, "envs_per_runner": 2, "sampling_steps": 50, "rounds": 1}


def sampling_throughput(algorithm: Any, steps_per_runner: int) -> float:
    """Environment steps per second of every remote env runner sampling ``steps_per_runner`` steps at once."""
    started = time.perf_counter()
    steps = algorithm.env_runner_group.foreach_env_runner(
        lambda runner: sum(len(episode) for episode in runner.sample(num_timesteps=steps_per_runner, explore=True)), local_env_runner=False)
    return sum(steps) / (time.perf_counter() - started)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "results" / "rllib")
    parser.add_argument("--timesteps", type=int, default=20_000)
    parser.add_argument("--env-runners", type=int, default=2)
    parser.add_argument("--envs-per-runner", type=int, default=4)
    parser.add_argument("--num-cpus", type=int, default=2, help="the local Ray's CPUs")
    parser.add_argument("--sampling-steps", type=int, default=2000, help="steps per env runner in one timed sampling round")
    parser.add_argument("--rounds", type=int, default=3, help="timed sampling rounds")
    parser.add_argument("--modes", nargs="+", choices=VECTORIZE_MODES, default=list(VECTORIZE_MODES))
    args = parse_with_smoke(parser, argv, SMOKE)

    import ray

    runs = {}
    for mode in args.modes:
        run = RLlibRun(timesteps=args.timesteps, num_env_runners=args.env_runners, envs_per_env_runner=args.envs_per_runner, vectorize=mode)
        print(f"== {mode}", flush=True)
        algorithm = build_algorithm(run, num_cpus=args.num_cpus)
        started = time.perf_counter()
        iterations = train_iterations(algorithm, run.timesteps, say=lambda line: print(line, flush=True))
        wall = time.perf_counter() - started
        rates = [sampling_throughput(algorithm, args.sampling_steps) for _ in range(args.rounds)]
        algorithm.stop()
        last = iterations[-1]
        episodes = {kind: last[kind] for kind in EPISODE_COUNTS}
        runs[mode] = {
            "env_steps_sampled": last["env_steps_sampled"],
            "training_wall_time_s": round(wall, 1),
            "episodes": episodes,
            "every_unfailed_episode_at_horizon": episodes[EPISODE_COUNTS[2]] == 0 and episodes[EPISODE_COUNTS[0]] > 0,
            "episode_len_min": min(it["episode_len_min"] for it in iterations if it["episode_len_min"] is not None),
            "episode_len_max": max(it["episode_len_max"] for it in iterations if it["episode_len_max"] is not None),
            "sampling_steps_per_s": round(statistics.median(rates), 1),
            "sampling_rounds_steps_per_s": [round(rate, 1) for rate in rates],
            "iterations": iterations,
        }
        print(f"{mode}: " + ", ".join(f"{k} {v}" for k, v in runs[mode].items() if k != "iterations"), flush=True)
    ray.shutdown()
    write_json(args.out / "summary.json", {
        "command": "nice python experiments/integrations/rllib_ppo.py " + " ".join(argv if argv is not None else sys.argv[1:]),
        "settings": {"timesteps": args.timesteps, "env_runners": args.env_runners, "envs_per_runner": args.envs_per_runner,
                     "num_cpus": args.num_cpus, "obs_mode": "phm", "continue_after_failure": True,
                     "sampling_steps_per_runner": args.sampling_steps, "rounds": args.rounds},
        "runs": runs,
        "machine": {"python": platform.python_version(), "platform": platform.platform(), "ray": ray.__version__},
    })
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
