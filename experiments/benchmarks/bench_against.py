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

``--stages`` times the single environment (``gym.make``, N = 1) instead, stage by stage: each PHM stage's
method is wrapped with a timer (about 0.3 us a call; cProfile's own cost per call is as large as these
stages' glue, so it overstates them) and the table gives each side's median microseconds per step, the rest
of the step (the environment's bookkeeping, observation, info and gymnasium's wrappers) as "other".

Run from a checkout's root: ``python experiments/benchmarks/bench_against.py [--ref HEAD~1] [--regime alarm] [--size 256]
[--rounds 3]``, or ``python experiments/benchmarks/bench_against.py --ref HEAD~1 --stages --steps 300 --warmup 30 --rounds 5``.
``--smoke`` times this checkout against itself (no other commit checked out, whose kernels would compile) on a few steps.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))  # this checkout's experiments.common, installed or not

from experiments.common import parse_with_smoke

#: the smoke run's sizes: this checkout on both sides
SMOKE = {"ref": None, "size": 2, "steps": 2, "warmup": 2, "rounds": 1}

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

# runs in the checkout under test: the single env's step and its stages' methods, each wrapped with a timer
_STAGES = """
import collections, json, os, sys, time
sys.path.insert(0, {root!r})
import gymnasium as gym, numpy as np
import ea_gym
assert ea_gym.__file__.startswith({root!r}), ea_gym.__file__
from ea_gym.degradation import WearConfig
from ea_gym.models import get_model
arrival = {{"alarm": (0.0, 1.0), "healthy": (1e6, 2e6)}}.get({regime!r})
kwargs = {{"wear": {{name: WearConfig(arrival=arrival) for name in get_model("spring_mass_damper").safe_limits}}}} if arrival else {{}}
env = gym.make("ea_gym/SpringMassDamper-v0", obs_mode="phm", continue_after_failure=True, **kwargs)
core = env.unwrapped.core
chain = core.chain
spent = collections.Counter()

def timed(owner, name, stage):
    method = getattr(owner, name)
    def wrapper(*args, **kwargs):
        started = time.perf_counter()
        try:
            return method(*args, **kwargs)
        finally:
            spent[stage] += time.perf_counter() - started
    setattr(owner, name, wrapper)

for path, names, stage in {stages!r}:
    head, attribute = path.split(".")
    for name in names:
        timed(getattr({{"core": core, "chain": chain}}[head], attribute), name, stage)
env.reset(seed={seed})
rng = np.random.default_rng({seed})
action = (lambda: int(rng.integers(0, 7))) if {regime!r} == "random" else (lambda: 0)
for _ in range({warmup}):
    env.step(action())
spent.clear()
started = time.perf_counter()
for _ in range({steps}):
    env.step(action())
per_step = {{stage: seconds * 1e6 / {steps} for stage, seconds in spent.items()}}
step = (time.perf_counter() - started) * 1e6 / {steps}
print(json.dumps({{"step_us": step, "stages_us": per_step | {{"other": step - sum(per_step.values())}},
                  "env_steps_per_s": 1e6 / step, "load_1min": os.getloadavg()[0]}}))
"""

REGIMES = ("alarm", "healthy", "random")
#: the single env's stages: (owner, its methods, the stage they count in); the owners are read in the run
STAGES = (
    ("core.operation", ("run",), "plant (simulation, loads, sensors)"),
    ("core.degradation", ("advance",), "wear"),
    ("chain.monitor", ("update",), "monitor"),
    ("chain.history", ("record",), "monitor history"),
    ("chain.detector", ("update",), "detection"),
    ("chain.isolation", ("classify", "balance_evidence", "fuse", "suspects", "counted"), "isolation"),
    ("chain.estimator", ("update", "restart"), "tracking filters"),
    ("chain.prognosis", ("update",), "prognosis"),
)


def measure(root: Path, regime: str, size: int, steps: int, warmup: int, seed: int, stages: bool = False) -> dict:
    """One fresh process timing the batched env of the checkout at ``root`` (``stages``: its single env, stage by stage)."""
    template = _STAGES if stages else _MEASURE
    code = template.format(root=str(root), regime=regime, size=size, steps=steps, warmup=warmup, seed=seed, stages=STAGES)
    env = {**os.environ, "PYTHONPATH": str(root)}
    done = subprocess.run([sys.executable, "-c", code], cwd=root, env=env, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"bench_against: error: the run in {root} failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--ref", default="HEAD~1", help="the commit to compare with")
    parser.add_argument("--regime", choices=REGIMES, default="alarm", help="what the systems go through (see above)")
    parser.add_argument("--size", type=int, default=256, help="number of environments N (not with --stages)")
    parser.add_argument("--steps", type=int, default=10, help="timed batch steps per measurement")
    parser.add_argument("--warmup", type=int, default=20, help="batch steps before timing (the alarms rise)")
    parser.add_argument("--rounds", type=int, default=3, help="measurements of each side, alternating")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--stages", action="store_true", help="time the single env (N = 1) stage by stage instead")
    args = parse_with_smoke(parser, argv, SMOKE)
    if args.stages and args.size != parser.get_default("size"):
        parser.error(f"--size: --stages times the single env (N = 1), got --size {args.size}")
    size = 1 if args.stages else args.size
    with checkout(args.ref) as other:
        sides = {"this checkout": ROOT, args.ref or "this checkout again": other}
        runs: dict[str, list[dict]] = {name: [] for name in sides}
        for round_ in range(args.rounds):
            # the order alternates too (ABBA...): whichever side runs first in a round has been seen to run slower
            for name, root in list(sides.items())[:: -1 if round_ % 2 else 1]:
                result = measure(root, args.regime, size, args.steps, args.warmup, args.seed, args.stages)
                runs[name].append(result)
                rate = f"round {round_ + 1}, {name}: {result['env_steps_per_s']:.0f} env-steps/s"
                if not args.stages:
                    rate += f", {result['env_steps_per_cpu_s']:.0f} per CPU-s, alarm share {result['alarm_share']:.0%}"
                print(f"{rate}, load {result['load_1min']:.1f}", flush=True)
    if args.stages:
        print_stages(runs)
    else:
        for name, measured in runs.items():
            print(f"{name}: median {median(measured, 'env_steps_per_s'):.0f} env-steps/s, {median(measured, 'env_steps_per_cpu_s'):.0f} per CPU-s "
                  f"over {len(measured)} runs at N = {size} ({args.regime})")
    this, ref = runs.values()
    if not args.stages:
        print(f"speed-up per CPU second: {median(this, 'env_steps_per_cpu_s') / median(ref, 'env_steps_per_cpu_s'):.2f}x; ", end="")
    print(f"wall: {median(this, 'env_steps_per_s') / median(ref, 'env_steps_per_s'):.2f}x")
    return 0


@contextmanager
def checkout(ref: str | None) -> Iterator[Path]:
    """The root of ``ref`` checked out into a temporary git worktree, removed afterwards (None: this checkout)."""
    if ref is None:
        yield ROOT
        return
    with tempfile.TemporaryDirectory() as scratch:
        other = Path(scratch) / "ref"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "--quiet", str(other), ref], check=True)
        try:
            yield other
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(other)], check=False)


def median(runs: list[dict], key: str) -> float:
    """The median of ``key`` over ``runs``."""
    return statistics.median(run[key] for run in runs)


def print_stages(runs: dict[str, list[dict]]) -> None:
    """Each side's median microseconds per step, stage by stage, and of the whole step."""
    names = list(runs)
    print(f"{'us per step (median)':>36} " + " ".join(f"{name:>14}" for name in names))
    stages = [stage for *_, stage in STAGES] + ["other"]
    for stage in stages:
        print(f"{stage:>36} " + " ".join(f"{statistics.median(run['stages_us'].get(stage, 0.0) for run in runs[name]):>14.1f}" for name in names))
    print(f"{'whole step':>36} " + " ".join(f"{median(runs[name], 'step_us'):>14.1f}" for name in names))


if __name__ == "__main__":
    raise SystemExit(main())
