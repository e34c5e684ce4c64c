"""Environment throughput in four regimes, side by side: healthy, in alarm, the shipped PPO agent's own, and v1's in alarm.

What it measures, in one run, on ``ea_gym/SpringMassDamper-v0`` (``ea_gym/SpringMassDamper-v1`` in the ``v1``
regime) with the full PHM chain (obs_mode "phm",
``continue_after_failure=True``), for N in ``--sizes`` (default 1, 16, 256, 1024): env-steps per second
of the native batched environment (``vectorization_mode="vector_entry_point"``; its compiled kernels' rows
on ``ea_gym.kernel_threads()`` threads, the cores available, and where that is more than one and N is
large enough to split, also on one thread beside it) and of Gymnasium's
``SyncVectorEnv`` of single environments (up to ``--sync-max``, default 256: beyond it a measurement
takes minutes), and at N = 1 of the single environment itself (``gym.make``). The regimes:

* ``healthy``: no fault arrives in the episode (every wear's arrival after the horizon), actions
  "carry on": the monitor and the tracking filters run, the isolation never does.
* ``alarm``: every fault arrives in the first second, no maintenance ("carry on"): after
  ``--alarm-warmup`` steps most systems are in alarm, so the isolation (features, network, balance
  evidence) and the prognosis run for them at every step.
* ``ppo``: the shipped agent ``agents/data/ppo_phm`` (read from its pickle-free files) chooses the
  actions in the environment it was trained in (its ``env_kwargs``); only ``step`` is timed.
* ``v1``: the v1 environment (every part ageing: background ageing from the start, parts within their
  tolerances, the joint filter and the model-fit test), every part's fault arriving in the first second,
  no maintenance: after ``--alarm-warmup`` steps most systems are in alarm, every part of every system
  degrading. Its figure beside the ``alarm`` regime's is v1's cost against v0's (issue 30 asks >= 0.8x at
  N = 256).

Each figure comes with the share of systems in alarm (mean over the timed steps), the CPU seconds
the process used per wall second (below 1 on a machine others load), the env-steps per CPU second
(less sensitive to that load than the wall rate) and the 1-minute load average when it was taken.
``--profile`` adds, per regime, a cProfile of the batched env at N = 256 on one kernel thread (cProfile
sees the calling thread only) summarised by stage.
Speed-ups between two commits are best stated with ``experiments/benchmarks/bench_against.py`` (alternating
fresh processes).

``--repeats K`` measures every row K times (a fresh env each time) and shows the median run with the range:
on two threads the figures of this VM vary by +-15 % from run to run, on one by a few per cent.

Run from a checkout's root: ``python experiments/benchmarks/bench_throughput.py [--sizes 1 16 256 1024]
[--regimes healthy alarm ppo v1] [--repeats K] [--profile] [--json PATH] [--smoke]``; the defaults take a few minutes
on an unloaded 2-core machine. v1 against v0 in alarm at N = 256 alone: ``--regimes alarm v1 --sizes 256 --sync-max 0``.
"""

from __future__ import annotations

import argparse
import cProfile
import os
import platform
import pstats
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import SyncVectorEnv

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))  # this checkout's ea_gym, agents and experiments.common, installed or not

from ea_gym.degradation import WearConfig
from ea_gym.env import ENV_ID, V1_ENV_IDS
from ea_gym.files import write_json
from ea_gym.models import get_model
from ea_gym.threads import MIN_ROWS_PER_THREAD, kernel_threads, set_kernel_threads, single_threaded_torch
from experiments.common import parse_with_smoke

REGIMES = ("healthy", "alarm", "ppo", "v1")
AGENT = ROOT / "agents" / "data" / "ppo_phm"
CARRY_ON = 0  # the action table's first entry
#: the shipped model's components, each worn by a fault of the given arrival window (s after reset)
COMPONENTS = tuple(get_model("spring_mass_damper").safe_limits)

#: the smoke run: every regime and kind of env on a few steps (N = 1 and 2, SyncVectorEnv included)
SMOKE = {"sizes": [1, 2], "steps": 2, "warmup": 1, "alarm_warmup": 2, "sync_max": 2}

Actor = Callable[[dict[str, np.ndarray], int], np.ndarray]


def regime_kwargs(regime: str) -> dict[str, Any]:
    """The environment's keywords in ``regime`` (the ``ppo`` regime's come from the agent's files)."""
    base: dict[str, Any] = {"obs_mode": "phm", "continue_after_failure": True}
    if regime == "healthy":  # the horizon is 500 s: no fault arrives
        return base | {"wear": {name: WearConfig(arrival=(1e6, 2e6)) for name in COMPONENTS}}
    if regime in ("alarm", "v1"):  # v1: every part's fault, on top of its background ageing
        return base | {"wear": {name: WearConfig(arrival=(0.0, 1.0)) for name in COMPONENTS}}
    if regime == "ppo":
        from agents.agent_files import read_agent

        environment = read_agent(AGENT).environment
        return base | {"obs_mode": environment.obs_mode, **environment.env_kwargs}
    raise ValueError(f"regime must be one of {REGIMES}, got {regime!r}")


def regime_actor(regime: str) -> Actor:
    """The actions of ``regime``: "carry on", or the shipped agent's (deterministic) choice."""
    if regime != "ppo":
        return lambda observation, n: np.full(n, CARRY_ON)
    from agents.training import load_policy

    policy = load_policy(AGENT)

    def act(observation: dict[str, np.ndarray], n: int) -> np.ndarray:
        with single_threaded_torch():
            return np.asarray(policy.predict(observation, deterministic=True)[0]).reshape(n)

    return act


def regime_env_id(regime: str) -> str:
    """The environment ``regime`` runs: v1's spring-mass-damper in the ``v1`` regime, v0's in the others."""
    return V1_ENV_IDS[0] if regime == "v1" else ENV_ID


def make_env(kind: str, n: int, kwargs: dict[str, Any], env_id: str = ENV_ID) -> gym.vector.VectorEnv:
    """``kind``: "batched" (the native vector env), "sync" (SyncVectorEnv of single envs) or "single" (N = 1,
    ``gym.make`` behind a batch-of-one adapter), of ``env_id``."""
    if kind == "batched":
        return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    if kind == "sync":
        return SyncVectorEnv([lambda: gym.make(env_id, **kwargs) for _ in range(n)])
    if kind == "single":
        return _Single(gym.make(env_id, **kwargs))
    raise ValueError(f"kind must be batched, sync or single, got {kind!r}")


class _Single:
    """The single environment behind the vector interface this script drives (observations with a leading axis of 1)."""

    def __init__(self, env: gym.Env):
        self.env = env

    def reset(self, seed: int) -> tuple[dict[str, np.ndarray], dict]:
        observation, info = self.env.reset(seed=seed)
        return {key: np.asarray(value)[None] for key, value in observation.items()}, info

    def step(self, actions: np.ndarray) -> tuple[Any, ...]:
        observation, *rest = self.env.step(int(actions[0]))
        return ({key: np.asarray(value)[None] for key, value in observation.items()}, *rest)

    def close(self) -> None:
        self.env.close()


def alarm_share(env: Any) -> float:
    """The share of the systems whose alarm is raised."""
    if isinstance(env, _Single):
        return float(env.env.unwrapped.core.chain.detector.state.alarm[0])
    if isinstance(env, SyncVectorEnv):
        return float(np.mean([e.unwrapped.core.chain.detector.state.alarm[0] for e in env.envs]))
    return float(env.unwrapped.core.chain.detector.state.alarm.mean())


def measure(
    kind: str, n: int, regime: str, steps: int, warmup: int, seed: int, actor: Actor, profile: cProfile.Profile | None = None,
    threads: int | None = None,
) -> dict:
    """env-steps/s of ``kind`` at N = ``n`` in ``regime`` over ``steps`` batch steps after ``warmup``, the
    kernels on ``threads`` threads (None: as set)."""
    previous = kernel_threads()
    if threads is not None:
        set_kernel_threads(threads)
    try:
        return measured(kind, n, regime, steps, warmup, seed, actor, profile) | {"kernel_threads": kernel_threads()}
    finally:
        set_kernel_threads(previous)


def measured(kind: str, n: int, regime: str, steps: int, warmup: int, seed: int, actor: Actor, profile: cProfile.Profile | None) -> dict:
    """``measure`` on the kernel threads as set."""
    env = make_env(kind, n, regime_kwargs(regime), regime_env_id(regime))
    observation, _ = env.reset(seed=seed)
    for _ in range(warmup):
        observation = env.step(actor(observation, n))[0]
    wall = cpu = 0.0
    shares = []
    for _ in range(steps):
        actions = actor(observation, n)  # the agent's decision is not the env's time
        started, used = time.perf_counter(), time.process_time()
        if profile is not None:
            profile.enable()
        observation = env.step(actions)[0]
        if profile is not None:
            profile.disable()
        wall += time.perf_counter() - started
        cpu += time.process_time() - used
        shares.append(alarm_share(env))
    env.close()
    return {
        "env_steps_per_s": n * steps / wall, "env_steps_per_cpu_s": n * steps / max(cpu, 1e-9), "cpu_share": cpu / wall,
        "alarm_share": float(np.mean(shares)), "batch_steps": steps, "warmup": warmup, "load_1min": os.getloadavg()[0],
    }


def median_run(runs: list[dict]) -> dict:
    """The run of median env-steps/s among ``runs`` (the upper one of an even count), with every run's
    env-steps/s under "runs"."""
    rates = [run["env_steps_per_s"] for run in runs]
    return runs[int(np.argsort(rates)[len(rates) // 2])] | {"runs": rates}


#: where a step's time goes: the first stage whose marker is in a function's file path takes its own time
STAGES = (
    ("tracking filters", ("_kernels/tracking", "phm/tracking")),
    ("joint filter and model fit", ("_kernels/joint", "phm/joint", "phm/fit")),
    ("isolation network", ("torch/", "diagnosis/classifier", "_kernels/network")),
    ("isolation features", ("diagnosis/features", "_kernels/features", "_kernels/summation", "scipy/signal", "scipy/fft")),
    ("balance evidence and fusion", ("phm/isolation", "_kernels/isolation")),
    ("monitor (EA, detection)", (
        "_kernels/monitor", "diagnosis/monitor", "_kernels/activity", "_kernels/smoothing", "phm/detection", "phm/history", "_kernels/detection",
        "_kernels/history",
    )),
    # the plant's simulation (expm, propagation: with the default tracking estimator, the plant's alone) and its sensors' draws (normal)
    ("plant and wear", (
        "_kernels/expm", "bondgraph/", "env/operation", "degradation", "_kernels/multisine", "loads", "_kernels/wear", "_kernels/propagation",
        "_kernels/normal", "ea_gym/sensors",
    )),
    ("prognosis", ("phm/prognosis", "_kernels/prognosis")),
)


def stage_times(profile: cProfile.Profile, batch_steps: int) -> dict[str, float]:
    """Each stage's own time per batch step (ms), from a profile of ``batch_steps`` steps; the rest is "other"."""
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
    times = dict.fromkeys([name for name, _ in STAGES] + ["other (Python glue, numpy)"], 0.0)
    for (filename, _, _), (_, _, own, _, _) in stats.items():
        path = filename.replace(os.sep, "/")
        stage = next((name for name, markers in STAGES if any(m in path for m in markers)), "other (Python glue, numpy)")
        times[stage] += own
    return {name: 1e3 * value / batch_steps for name, value in times.items()}


def run(args: argparse.Namespace) -> dict:
    results: dict[str, Any] = {
        "machine": {"processor": platform.processor(), "cores": os.cpu_count(), "python": platform.python_version()},
        "regimes": {}, "profiles": {},
    }
    print(f"machine: {os.cpu_count()} cores, python {platform.python_version()}, load {os.getloadavg()[0]:.1f}")
    header = (f"{'regime':>8} {'N':>5} {'env':>8} {'threads':>7} {'steps/s':>9} {'per CPU-s':>10} {'CPU share':>9} {'alarm':>6} {'load':>5} "
              f"{'vs sync':>8}" + ("  steps/s range" if args.repeats > 1 else ""))
    print(header)
    threads = kernel_threads()
    for regime in args.regimes:
        actor = regime_actor(regime)
        warmup = args.alarm_warmup if regime in ("alarm", "v1") else args.warmup
        rows: dict[str, Any] = {}
        for n in args.sizes:
            # (key, env, kernel threads): the batched env also on one thread where it would split its rows
            kinds = (
                [("batched", "batched", threads)] + ([("batched_one_thread", "batched", 1)] if threads > 1 and n >= 2 * MIN_ROWS_PER_THREAD else [])
                + ([("sync", "sync", 1)] if n <= args.sync_max else []) + ([("single", "single", 1)] if n == 1 else [])
            )
            row = {}
            for key, kind, kind_threads in kinds:
                steps = args.steps if kind != "sync" or n <= 16 else max(2, args.steps // 4)
                row[key] = r = median_run([
                    measure(kind, n, regime, steps, warmup, args.seed, actor, threads=kind_threads) for _ in range(args.repeats)
                ])
                ratio = f"{row['batched']['env_steps_per_s'] / r['env_steps_per_s']:.1f}x" if kind == "sync" else ""
                spread = f" {min(r['runs']):>7.0f}-{max(r['runs']):<7.0f}" if args.repeats > 1 else ""
                print(f"{regime:>8} {n:>5} {kind:>8} {kind_threads:>7} {r['env_steps_per_s']:>9.0f} {r['env_steps_per_cpu_s']:>10.0f} "
                      f"{r['cpu_share']:>9.2f} {r['alarm_share']:>6.0%} {r['load_1min']:>5.1f} {ratio:>8}{spread}", flush=True)
            rows[str(n)] = row
        results["regimes"][regime] = rows
        if args.profile:
            profile = cProfile.Profile()
            measure("batched", 256, regime, args.steps, warmup, args.seed, actor, profile, threads=1)
            results["profiles"][regime] = stage_times(profile, args.steps)
    ratios = v1_over_alarm(results["regimes"])
    if ratios:
        results["v1_over_alarm"] = ratios
        print("\nv1 / v0 in alarm, batched env-steps/s: " + ", ".join(f"N = {n}: {r:.2f}x" for n, r in ratios.items()))
    if args.profile:
        print("\nwhere a batched step's time goes at N = 256 on one kernel thread (ms per step, own time under cProfile):")
        print(f"{'stage':>30} " + " ".join(f"{regime:>8}" for regime in results["profiles"]))
        for stage in next(iter(results["profiles"].values()), {}):
            print(f"{stage:>30} " + " ".join(f"{p[stage]:>8.1f}" for p in results["profiles"].values()))
    return results


def v1_over_alarm(regimes: dict[str, Any]) -> dict[str, float]:
    """The batched env's env-steps/s in the ``v1`` regime over the ``alarm`` regime's, for each N measured in both."""
    v1, v0 = regimes.get("v1", {}), regimes.get("alarm", {})
    return {n: v1[n]["batched"]["env_steps_per_s"] / v0[n]["batched"]["env_steps_per_s"] for n in v1 if n in v0}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 16, 256, 1024], help="numbers of environments N")
    parser.add_argument("--regimes", nargs="+", choices=REGIMES, default=list(REGIMES), help="the regimes to run")
    parser.add_argument("--steps", type=int, default=10, help="timed batch steps per measurement (SyncVectorEnv: fewer)")
    parser.add_argument("--warmup", type=int, default=5, help="batch steps before timing (healthy and ppo regimes)")
    parser.add_argument("--alarm-warmup", type=int, default=20, help="batch steps before timing in alarm (the alarms rise)")
    parser.add_argument("--sync-max", type=int, default=256, help="largest N for the SyncVectorEnv (it is slow)")
    parser.add_argument("--profile", action="store_true", help="also profile the batched env at N = 256 in each regime")
    parser.add_argument("--repeats", type=int, default=1, help="measurements of each row, each in a fresh env: the median's row is shown")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, default=None, help="also write the numbers as JSON")
    args = parse_with_smoke(parser, argv, SMOKE)
    for name in ("steps", "repeats", "warmup", "alarm_warmup", "sync_max"):
        if getattr(args, name) < (1 if name in ("steps", "repeats") else 0):
            parser.error(f"--{name.replace('_', '-')} must be >= {1 if name in ('steps', 'repeats') else 0}, got {getattr(args, name)}")
    if any(n < 1 for n in args.sizes):
        parser.error(f"--sizes must be >= 1, got {args.sizes}")
    results = run(args)
    if args.json:
        write_json(args.json, results)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
