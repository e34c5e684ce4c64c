"""Throughput of this checkout against another commit, side by side in one run.

What it measures: env-steps per second of the native batched environment (``bench_throughput.time_vector``:
``ea_gym/SpringMassDamper-v0``, full PHM chain, random actions, ``--warmup`` batch steps before
``--steps`` timed ones) at N = ``--size``, for this checkout and for ``--ref`` (default the previous
commit, checked out into a temporary git worktree), in alternating fresh processes, ``--rounds``
times each: a machine whose load drifts affects both alike. Each side runs its own
``experiments/bench_throughput.py``, so the regime is the one that commit defines.

Run: ``python experiments/bench_against.py [--ref HEAD~1] [--size 256] [--rounds 3]``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# runs in the checkout under test: its own ea_gym and its own bench_throughput
_MEASURE = """
import json, sys
sys.path[:0] = [{root!r}, {root!r} + '/experiments']
import ea_gym
assert ea_gym.__file__.startswith({root!r}), ea_gym.__file__
from bench_throughput import time_vector
print(json.dumps(time_vector('vector_entry_point', {size}, {steps}, {warmup}, {seed})))
"""


def measure(root: Path, size: int, steps: int, warmup: int, seed: int) -> dict:
    """One fresh process timing the batched env of the checkout at ``root``."""
    code = _MEASURE.format(root=str(root), size=size, steps=steps, warmup=warmup, seed=seed)
    env = {**os.environ, "PYTHONPATH": str(root)}
    done = subprocess.run([sys.executable, "-c", code], cwd=root, env=env, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"bench_against: error: the run in {root} failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--ref", default="HEAD~1", help="the commit to compare with")
    parser.add_argument("--size", type=int, default=256, help="number of environments N")
    parser.add_argument("--steps", type=int, default=20, help="timed batch steps per measurement")
    parser.add_argument("--warmup", type=int, default=120, help="batch steps before timing (faults arrive)")
    parser.add_argument("--rounds", type=int, default=3, help="measurements of each side, alternating")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as scratch:
        other = Path(scratch) / "ref"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "--quiet", str(other), args.ref], check=True)
        try:
            sides = {"this checkout": ROOT, args.ref: other}
            rates: dict[str, list[float]] = {name: [] for name in sides}
            for round_ in range(args.rounds):
                for name, root in sides.items():
                    result = measure(root, args.size, args.steps, args.warmup, args.seed)
                    rates[name].append(result["env_steps_per_s"])
                    rate, alarm = result["env_steps_per_s"], result["alarm_share"]
                    print(f"round {round_ + 1}, {name}: {rate:.0f} env-steps/s (alarm share {alarm:.0%})", flush=True)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(other)], check=False)
    for name, values in rates.items():
        print(f"{name}: median {statistics.median(values):.0f} env-steps/s over {len(values)} runs at N = {args.size}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
