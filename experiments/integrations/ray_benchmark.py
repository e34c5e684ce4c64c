"""``ea-gym benchmark --ray``: the same outputs as the local run, and its wall time with 1 and 2 Ray workers.

What it measures
    The benchmark as ``ea-gym benchmark --episodes N`` runs it (the committed tuned settings, the
    committed PPO agent ``agents/data/ppo_phm``; with ``--tune-episodes K`` the rules re-tuned on K
    episodes per grid value first) in this process (``LocalRunner``), then as Ray tasks on a local Ray
    of 1 CPU and of 2 CPUs (``RayRunner``: the seeds split into a chunk per CPU, so with 2 CPUs each
    batch holds N/2 seeds of every policy of one obs_mode; the timeline episodes one task each),
    ``--repeats`` times in turn. Per run: the wall time of ``run_benchmark`` (benchmark.json's
    ``timings_s.total``: evaluation, timelines, figures, the agent's loading; with Ray, the workers'
    start-up too, but not Ray's own start, given apart), its stages, the load average (``uptime``'s)
    before and after, and whether its records (every policy's per-episode records, the ranking, the
    tuning tables, the value of information, the seeds) and its ``timelines.json`` equal the local run's.

Run from a checkout's root, in the virtual environment with the rllib extra (``bash scripts/test_ray.sh`` makes one),
on a quiet machine:
    .venv-rllib/bin/python experiments/integrations/ray_benchmark.py --out experiments/results/ray_benchmark [--smoke]
Writes OUT/summary.json (the benchmarks' own outputs go to a temporary directory).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's ea_gym, agents and experiments.common, installed or not

from agents.benchmark.run import run_benchmark
from agents.benchmark.runners import RayRunner
from ea_gym.files import write_json
from experiments.common import parse_with_smoke

RECORDS = ("policies", "ranking", "tuning", "value_of_information", "seeds")
AGENT = Path(__file__).resolve().parents[2] / "agents" / "data" / "ppo_phm"
#: the runs: name -> the local Ray's CPUs (None: this process, no Ray)
RUNS = {"local": None, "ray_1_cpu": 1, "ray_2_cpus": 2}
#: the smoke run: every run once on two episodes
SMOKE = {"episodes": 2, "repeats": 1}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "results" / "ray_benchmark")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--tune-episodes", type=int, default=None, help="re-tune the rules on K episodes per grid value first (default: no tuning)")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--no-ppo", action="store_true")
    args = parse_with_smoke(parser, argv, SMOKE)

    import ray

    runs: dict[str, list[dict[str, Any]]] = {name: [] for name in RUNS}
    reference: dict[str, Any] = {}
    tuning = {} if args.tune_episodes is None else {"tune": True, "tune_episodes": args.tune_episodes}
    with tempfile.TemporaryDirectory() as scratch:
        for repeat in range(args.repeats):
            for name, cpus in RUNS.items():
                out = Path(scratch) / f"{name}_{repeat}"
                load_before = os.getloadavg()
                ray_start = None
                if cpus is not None:
                    started = time.perf_counter()
                    RayRunner(None, num_cpus=cpus)  # the local Ray that ray="local" joins
                    ray_start = time.perf_counter() - started
                result = run_benchmark(args.episodes, 0, out, None if args.no_ppo else AGENT, progress=False,
                                       ray=None if cpus is None else "local", **tuning)
                if cpus is not None:
                    ray.shutdown()
                timelines = json.loads((out / "timelines.json").read_text())
                if not reference:
                    reference = {"result": result, "timelines": timelines}
                run = {"wall_time_s": round(result["timings_s"]["total"], 1),
                       "ray_start_s": None if ray_start is None else round(ray_start, 1),
                       "load_before": [round(x, 2) for x in load_before], "load_after": [round(x, 2) for x in os.getloadavg()],
                       "records_equal_local": all(result[key] == reference["result"][key] for key in RECORDS),
                       "timelines_equal_local": timelines == reference["timelines"],
                       "stages_s": {stage: round(t, 1) for stage, t in result["timings_s"].items()}}
                runs[name].append(run)
                print(name, repeat, json.dumps(run), flush=True)
    best = {name: min(r["wall_time_s"] for r in done) for name, done in runs.items()}
    median = {name: statistics.median(r["wall_time_s"] for r in done) for name, done in runs.items()}
    write_json(args.out / "summary.json", {
        "command": ".venv-rllib/bin/python experiments/integrations/ray_benchmark.py " + " ".join(argv if argv is not None else sys.argv[1:]),
        "settings": {"episodes": args.episodes, "tune_episodes": args.tune_episodes, "repeats": args.repeats,
                     "ppo": None if args.no_ppo else "agents/data/ppo_phm", "tuned": "re-tuned" if tuning else "committed"},
        "runs": runs,
        "wall_time_s_best": best,
        "wall_time_s_median": median,
        "speedup_2_cpus_over_1": round(best["ray_1_cpu"] / best["ray_2_cpus"], 2),
        "speedup_2_cpus_over_local": round(best["local"] / best["ray_2_cpus"], 2),
        "all_equal_local": all(r["records_equal_local"] and r["timelines_equal_local"] for done in runs.values() for r in done),
        "mean_costs": {name: row["mean_cost"] for name, row in reference["result"]["policies"].items()},
        "machine": {"python": platform.python_version(), "platform": platform.platform(), "cpus": os.cpu_count(), "ray": ray.__version__},
    })
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
