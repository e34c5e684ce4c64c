"""``ea-gym benchmark --ray``: the same records as the local run, and its wall time with 1 and 2 Ray workers.

What it measures
    One small benchmark (``--episodes`` evaluation episodes per policy, the rules tuned on
    ``--tune-episodes`` episodes per grid value over the default grids, no PPO agent) three times:
    in this process (``LocalRunner``), then as Ray tasks on a local Ray of 1 CPU and of 2 CPUs
    (``RayRunner``: the seeds split into a chunk per CPU at least). Each run's wall time (benchmark.json's
    ``timings_s.total``: tuning, evaluation, timelines and figures; with Ray, the workers' start too) and
    whether its records (every policy's per-episode records, the ranking, the tuning tables, the
    value of information) equal the local run's.

Run (in the virtual environment with the rllib extra; README, RLlib and Ray):
    nice /work/venv-rllib/bin/python experiments/ray_benchmark.py --out experiments/results/ray_benchmark
Writes OUT/summary.json (the benchmarks' own outputs go to a temporary directory).
"""

from __future__ import annotations

import argparse
import platform
import sys
import tempfile
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from agents.benchmark.run import run_benchmark
from agents.benchmark.runners import RayRunner
from ea_gym.files import write_json

RECORDS = ("policies", "ranking", "tuning", "value_of_information", "seeds")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("experiments/results/ray_benchmark"))
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--tune-episodes", type=int, default=4)
    args = parser.parse_args(argv)

    import ray

    runs: dict[str, dict] = {}
    results = {}
    with tempfile.TemporaryDirectory() as scratch:
        for name, cpus in (("local", None), ("ray_1_worker", 1), ("ray_2_workers", 2)):
            if cpus is not None:
                RayRunner(None, num_cpus=cpus)  # the local Ray that ray="local" joins
            result = run_benchmark(args.episodes, 0, Path(scratch) / name, None, tune_episodes=args.tune_episodes, progress=False, tune=True,
                                   ray=None if cpus is None else "local")
            if cpus is not None:
                ray.shutdown()
            results[name] = result
            runs[name] = {"wall_time_s": round(result["timings_s"]["total"], 1),
                          "records_equal_local": all(result[key] == results["local"][key] for key in RECORDS),
                          "stages_s": {stage: round(t, 1) for stage, t in result["timings_s"].items()}}
            print(name, runs[name], flush=True)
    local = runs["local"]["wall_time_s"]
    write_json(args.out / "summary.json", {
        "command": "nice python experiments/ray_benchmark.py " + " ".join(argv if argv is not None else sys.argv[1:]),
        "settings": {"episodes": args.episodes, "tune_episodes": args.tune_episodes, "grids": "default", "ppo": None},
        "runs": runs,
        "speedup_2_workers_over_1": round(runs["ray_1_worker"]["wall_time_s"] / runs["ray_2_workers"]["wall_time_s"], 2),
        "speedup_2_workers_over_local": round(local / runs["ray_2_workers"]["wall_time_s"], 2),
        "mean_costs": {name: row["mean_cost"] for name, row in results["local"]["policies"].items()},
        "machine": {"python": platform.python_version(), "platform": platform.platform(), "ray": ray.__version__},
    })
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
