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
    the sampling throughput (environment steps of all env runners per second of the driver's
    sampling timer, the first iteration, with the env runners' start, left out) and the wall time.

Run (in the virtual environment with the rllib extra; README, RLlib and Ray):
    nice /work/venv-rllib/bin/python experiments/rllib_ppo.py --out experiments/results/rllib
Writes OUT/summary.json and OUT/<mode>/training.json (every iteration's figures); no checkpoints.
"""

from __future__ import annotations

import argparse
import platform
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from agents.rllib_training import EPISODE_COUNTS, VECTORIZE_MODES, RLlibRun, train_rllib
from ea_gym.files import write_json


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("experiments/results/rllib"))
    parser.add_argument("--timesteps", type=int, default=20_000)
    parser.add_argument("--env-runners", type=int, default=2)
    parser.add_argument("--envs-per-runner", type=int, default=4)
    parser.add_argument("--num-cpus", type=int, default=2, help="the local Ray's CPUs")
    parser.add_argument("--modes", nargs="+", choices=VECTORIZE_MODES, default=list(VECTORIZE_MODES))
    args = parser.parse_args(argv)

    import ray

    runs = {}
    for mode in args.modes:
        run = RLlibRun(timesteps=args.timesteps, num_env_runners=args.env_runners, envs_per_env_runner=args.envs_per_runner, vectorize=mode)
        print(f"== {mode}", flush=True)
        summary = train_rllib(run, args.out / mode, num_cpus=args.num_cpus, checkpoint=False, say=lambda line: print(line, flush=True))
        episodes = summary["episodes"]
        runs[mode] = {
            "env_steps_sampled": summary["env_steps_sampled"],
            "wall_time_s": summary["wall_time_s"],
            "sampling_steps_per_s": summary["sampling_steps_per_s"],
            "episodes": episodes,
            "every_unfailed_episode_at_horizon": episodes[EPISODE_COUNTS[2]] == 0 and episodes[EPISODE_COUNTS[0]] > 0,
            "episode_len_min": min(it["episode_len_min"] for it in summary["iterations"] if it["episode_len_min"] is not None),
            "episode_len_max": max(it["episode_len_max"] for it in summary["iterations"] if it["episode_len_max"] is not None),
            "last_episode_return_mean": summary["iterations"][-1]["episode_return_mean"],
        }
        print(f"{mode}: {runs[mode]}", flush=True)
    ray.shutdown()
    write_json(args.out / "summary.json", {
        "command": "nice python experiments/rllib_ppo.py " + " ".join(argv if argv is not None else sys.argv[1:]),
        "settings": {"timesteps": args.timesteps, "env_runners": args.env_runners, "envs_per_runner": args.envs_per_runner,
                     "num_cpus": args.num_cpus, "obs_mode": "phm", "continue_after_failure": True},
        "runs": runs,
        "machine": {"python": platform.python_version(), "platform": platform.platform(), "ray": ray.__version__},
    })
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
