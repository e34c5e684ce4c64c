"""Throughput of this checkout against another commit, side by side in one run.

What it measures: env-steps per second (wall and per CPU second) of the native batched environment
(``ea_gym/SpringMassDamper-v0``, full PHM chain, ``continue_after_failure=True``) at N = ``--size`` in a
``--regime``: "alarm" (every fault arriving in the first second, no maintenance: most systems in alarm
after the warm-up), "healthy" (no fault arrives; "carry on") or "random" (default wear, random actions
from a seeded generator), ``--steps`` timed batch steps after ``--warmup`` ones, for this checkout and
for ``--ref`` (default the previous commit, checked out into a temporary git worktree), in alternating
fresh processes, ``--rounds`` times each, each round in the other order than the last: a machine whose
load drifts affects both alike. The measurement uses the environment's public interface only, so any
commit with these keywords runs it.

Run: ``python experiments/bench_against.py [--ref HEAD~1] [--regime alarm] [--size 256] [--rounds 3]``.
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

# runs in the checkout under test, through its own ea_gym's public interface
_MEASURE = """
import json, os, sys, time
sys.path.insert(0, {root!r})
import gymnasium as gym, numpy as np
import ea_gym
assert ea_gym.__file__.startswith({root!r}), ea_gym.__file__
from ea_gym.degradation import WearConfig
from ea_gym.models import get_model
arrival = {{"alarm": (0.0, 1.0), "healthy": (1e6, 2e6)}}.get({regime!r})
kwargs = {{"wear": {{name: WearConfig(arrival=arrival) for name in get_model("spring_mass_damper").safe_limits}}}} if arrival else {{}}
env = gym.make_vec("ea_gym/SpringMassDamper-v0", num_envs={size}, vectorization_mode="vector_entry_point", obs_mode="phm",
                   continue_after_failure=True, **kwargs)
env.reset(seed={seed})
rng = np.random.default_rng({seed})
actions = (lambda: rng.integers(0, 7, {size})) if {regime!r} == "random" else (lambda: np.zeros({size}, dtype=int))
for _ in range({warmup}):
    env.step(actions())
started, used = time.perf_counter(), time.process_time()
for _ in range({steps}):
    env.step(actions())
wall, cpu = time.perf_counter() - started, time.process_time() - used
alarm = float(env.unwrapped.core.chain.detector.state.alarm.mean())
print(json.dumps({{"env_steps_per_s": {size} * {steps} / wall, "env_steps_per_cpu_s": {size} * {steps} / cpu, "alarm_share": alarm,
                  "load_1min": os.getloadavg()[0]}}))
"""

REGIMES = ("alarm", "healthy", "random")


def measure(root: Path, regime: str, size: int, steps: int, warmup: int, seed: int) -> dict:
    """One fresh process timing the batched env of the checkout at ``root``."""
    code = _MEASURE.format(root=str(root), regime=regime, size=size, steps=steps, warmup=warmup, seed=seed)
    env = {**os.environ, "PYTHONPATH": str(root)}
    done = subprocess.run([sys.executable, "-c", code], cwd=root, env=env, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"bench_against: error: the run in {root} failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--ref", default="HEAD~1", help="the commit to compare with")
    parser.add_argument("--regime", choices=REGIMES, default="alarm", help="what the systems go through (see above)")
    parser.add_argument("--size", type=int, default=256, help="number of environments N")
    parser.add_argument("--steps", type=int, default=10, help="timed batch steps per measurement")
    parser.add_argument("--warmup", type=int, default=20, help="batch steps before timing (the alarms rise)")
    parser.add_argument("--rounds", type=int, default=3, help="measurements of each side, alternating")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as scratch:
        other = Path(scratch) / "ref"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "--quiet", str(other), args.ref], check=True)
        try:
            sides = {"this checkout": ROOT, args.ref: other}
            rates: dict[str, list[float]] = {name: [] for name in sides}
            cpu_rates: dict[str, list[float]] = {name: [] for name in sides}
            for round_ in range(args.rounds):
                # the order alternates too (ABBA...): whichever side runs first in a round has been seen to run slower
                for name, root in list(sides.items())[:: -1 if round_ % 2 else 1]:
                    result = measure(root, args.regime, args.size, args.steps, args.warmup, args.seed)
                    rates[name].append(result["env_steps_per_s"])
                    cpu_rates[name].append(result["env_steps_per_cpu_s"])
                    print(f"round {round_ + 1}, {name}: {result['env_steps_per_s']:.0f} env-steps/s, {result['env_steps_per_cpu_s']:.0f} "
                          f"per CPU-s (alarm share {result['alarm_share']:.0%}, load {result['load_1min']:.1f})", flush=True)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(other)], check=False)
    for name, values in rates.items():
        print(f"{name}: median {statistics.median(values):.0f} env-steps/s, {statistics.median(cpu_rates[name]):.0f} per CPU-s "
              f"over {len(values)} runs at N = {args.size} ({args.regime})")
    this, ref = (statistics.median(cpu_rates[name]) for name in sides)
    print(f"speed-up per CPU second: {this / ref:.2f}x; wall: {statistics.median(rates['this checkout']) / statistics.median(rates[args.ref]):.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
