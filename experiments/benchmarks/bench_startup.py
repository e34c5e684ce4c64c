"""Start-up time: a fresh process's first ``gym.make`` + ``reset`` + ``step``, with a cold and a warm cache.

Each measurement is a new Python process that imports gymnasium and ea_gym, makes an environment,
resets and steps it once, and reports the wall time of each stage (the total also counts the
interpreter's own start). "cold" runs against an empty ``EA_GYM_CACHE_DIR`` (a new temporary
directory each time), "warm" against one a previous run filled. Cases:

* ``default``: ``SpringMassDamper-v0`` as made: its network and thresholds ship with the package, so
  even a cold cache computes nothing;
* ``noise 0.02``: the same environment at a sensor noise whose thresholds are not shipped: a cold cache
  calibrates them (fault-free runs simulated), a warm one reads them;
* ``rlc_circuit``: ``BondGraphMaintenance-v0`` on the RLC circuit (shipped network and thresholds).

numba's compiled kernels are cached beside their sources (``cache=True``) and reused by every process;
``--numba-cold`` also measures one run with an empty ``NUMBA_CACHE_DIR`` (everything compiled: tens of
seconds). The machine's load average is printed with the numbers: on a shared machine it moves them.

How to run (from the repository root; about a minute)
    python experiments/benchmarks/bench_startup.py [--repeats 5] [--cases default ...] [--numba-cold] [--smoke]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))  # this checkout's experiments.common, installed or not

from experiments.common import parse_with_smoke

STAGES = ("import", "make", "reset", "step")
CASES = {
    "default": ("ea_gym/SpringMassDamper-v0", {}),
    "noise 0.02": ("ea_gym/SpringMassDamper-v0", {"noise": 0.02}),
    "rlc_circuit": ("ea_gym/BondGraphMaintenance-v0", {"system": "rlc_circuit"}),
}
#: the smoke run: one process per cache state of the default case
SMOKE = {"repeats": 1, "cases": ["default"]}
# what the child process runs: the stages' wall times as one JSON line
CHILD = """
import json, sys, time
start = time.perf_counter()
import gymnasium as gym
import ea_gym
imported = time.perf_counter()
env = gym.make(sys.argv[1], **json.loads(sys.argv[2]))
made = time.perf_counter()
env.reset(seed=0)
reset = time.perf_counter()
env.step(0)
stepped = time.perf_counter()
print(json.dumps({"import": imported - start, "make": made - imported, "reset": reset - made, "step": stepped - reset,
                  "torch": "torch" in sys.modules}))
"""


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def measure(env_id: str, kwargs: dict, cache: Path, numba_cache: Path | None = None) -> dict[str, float]:
    """One fresh process: the stages' seconds, the process's whole wall time ("total") and its CPU time, user + system
    ("cpu": what the wall time would be on an idle machine, the start being single-threaded, less waits on the disk)."""
    environment = {**os.environ, "EA_GYM_CACHE_DIR": str(cache), "PYTHONPATH": str(ROOT)}
    if numba_cache is not None:
        environment["NUMBA_CACHE_DIR"] = str(numba_cache)
    start, cpu = time.perf_counter(), _children_cpu()
    result = subprocess.run([sys.executable, "-c", CHILD, env_id, json.dumps(kwargs)], capture_output=True, text=True, env=environment)
    total, cpu = time.perf_counter() - start, _children_cpu() - cpu
    if result.returncode != 0:
        raise RuntimeError(f"{env_id} {kwargs}: {result.stderr.strip().splitlines()[-1]}")
    return {**json.loads(result.stdout.strip().splitlines()[-1]), "total": total, "cpu": cpu}


def summary(label: str, runs: list[dict[str, float]]) -> str:
    """One table row: the median of every stage, the median, min and max total, the median CPU time."""
    totals = [run["total"] for run in runs]
    stages = " ".join(f"{statistics.median(run[s] for run in runs):6.2f}" for s in STAGES)
    cpu = statistics.median(run["cpu"] for run in runs)
    torch = "yes" if any(run["torch"] for run in runs) else "no"
    return f"{label:<26} {len(runs):>2} {stages}  {statistics.median(totals):6.2f} {min(totals):6.2f} {max(totals):6.2f} {cpu:6.2f}  {torch}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5, help="processes per case and cache state (default 5)")
    parser.add_argument("--cases", nargs="+", choices=list(CASES), default=list(CASES), help="the cases to measure (default all)")
    parser.add_argument("--numba-cold", action="store_true", help="also one run with numba's cache empty (slow)")
    args = parse_with_smoke(parser, argv, SMOKE)
    if args.repeats < 1:
        parser.error("--repeats: expected a positive integer")
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
    print(f"{'case, cache':<26} {'n':>2} {'import':>6} {'make':>6} {'reset':>6} {'step':>6}  {'total':>6} {'min':>6} {'max':>6} {'cpu':>6}  torch")
    with tempfile.TemporaryDirectory(prefix="ea-gym-bench-") as scratch:
        for name in args.cases:
            env_id, kwargs = CASES[name]
            measure(env_id, kwargs, Path(scratch) / "warm-up")  # numba's cache and the OS's file cache, as a user's second start
            cold = [measure(env_id, kwargs, Path(scratch) / f"{name}-cold-{k}") for k in range(args.repeats)]
            warm_cache = Path(scratch) / f"{name}-warm"
            measure(env_id, kwargs, warm_cache)  # fills it
            warm = [measure(env_id, kwargs, warm_cache) for _ in range(args.repeats)]
            print(summary(f"{name}, cold", cold), flush=True)
            print(summary(f"{name}, warm", warm), flush=True)
        if args.numba_cold:
            run = measure(*CASES["default"], Path(scratch) / "numba-cold", numba_cache=Path(scratch) / "numba")
            print(summary("default, numba cold", [run]), flush=True)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
