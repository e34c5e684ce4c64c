"""Environment throughput: single env, Gymnasium's SyncVectorEnv of it, and the native batched env; PPO wall time.

What it measures, in one run, on ``ea_gym/SpringMassDamper-v0`` with the full PHM chain (obs_mode "phm"),
``continue_after_failure=True`` and random actions from a seeded generator:

1. env-steps per second of the single environment, of ``gymnasium.make_vec(..., vectorization_mode="sync")``
   and of the native batched environment (``vectorization_mode="vector_entry_point"``), for N in
   ``--sizes`` (default 1, 16, 256, 1024). Each is timed over ``--steps`` batch steps after ``--warmup``
   batch steps; the warm-up lets faults arrive, so that the chain's fault stages (EA inversion,
   isolation) run in the timed part, as in training. The share of systems with a raised alarm is
   reported beside each number, since the EA inversion dominates once a fault is detected.
2. PPO training wall time for ``--ppo-steps`` steps with 16 environments: on the batched
   ``MaintenanceVecEnv`` and on stable-baselines3's ``SubprocVecEnv`` of single environments, same
   hyperparameters.
3. The batched environment at N = 256 in alarm: every fault arriving in the first second, no
   maintenance, the EA inversion and the tracking filter (``PHMConfig.estimator_kind``) side by side,
   timed in alternating blocks; the alarm share beside each (``--alarm-only`` runs this alone).
4. A cProfile of the batched environment at N = 256: where the time goes.

Run: ``python experiments/bench_throughput.py [--sizes 1 16 256 1024] [--json PATH]``.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import os
import platform
import pstats
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

try:
    import ea_gym  # noqa: F401
except ImportError:  # run from a checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import ea_gym  # noqa: F401

from ea_gym.env import ENV_ID
from ea_gym.env.maintenance import BondGraphMaintenanceEnv
from ea_gym.files import write_json
from ea_gym.threads import single_threaded_torch

KWARGS: dict[str, Any] = {"obs_mode": "phm", "continue_after_failure": True}
ALARM_WARMUP = 12  # env steps (5 s each) before the in-alarm regime is timed: faults past their detection


def _alarm_share(env) -> float:
    unwrapped = env.unwrapped if hasattr(env, "unwrapped") else env
    if hasattr(unwrapped, "core"):
        return float(unwrapped.core.chain.detector.state.alarm.mean())
    cores = [e.unwrapped.core for e in unwrapped.envs]
    return float(np.mean([c.chain.detector.state.alarm[0] for c in cores]))


def _action_index(env, kind) -> int:
    """The index of the batched environment's first action of ``kind`` (an ``ActionKind``)."""
    return next(i for i, action in enumerate(env.unwrapped.actions) if action.kind is kind)


def time_vector(kind: str, n: int, steps: int, warmup: int, seed: int) -> dict:
    env = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode=kind, **KWARGS)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    assert isinstance(env.single_action_space, spaces.Discrete)
    n_actions = int(env.single_action_space.n)
    actions = lambda: rng.integers(0, n_actions, n)  # noqa: E731
    for _ in range(warmup):
        env.step(actions())
    alarm = _alarm_share(env)
    started = time.perf_counter()
    for _ in range(steps):
        env.step(actions())
    wall = time.perf_counter() - started
    env.close()
    return {"env_steps_per_s": n * steps / wall, "batch_steps": steps, "wall_s": wall, "alarm_share": alarm}


def time_single(steps: int, warmup: int, seed: int) -> dict:
    env = gym.make(ENV_ID, **KWARGS)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    assert isinstance(env.action_space, spaces.Discrete) and isinstance(env.unwrapped, BondGraphMaintenanceEnv)
    n_actions, chain = int(env.action_space.n), env.unwrapped.core.chain
    for _ in range(warmup):
        env.step(int(rng.integers(n_actions)))
    assert chain is not None  # phm mode
    alarm = float(chain.detector.state.alarm[0])
    started = time.perf_counter()
    for _ in range(steps):
        env.step(int(rng.integers(n_actions)))
    wall = time.perf_counter() - started
    return {"env_steps_per_s": steps / wall, "batch_steps": steps, "wall_s": wall, "alarm_share": alarm}


def time_in_alarm(n: int, steps: int, warmup: int, seed: int, kinds: Sequence[str], rounds: int = 3) -> dict:
    """The batched environment at N with every system's fault arriving in its first second and no
    maintenance (always carry on): most systems are in alarm, the chain's fault stages run everywhere.

    One environment per estimator kind (``PHMConfig.estimator_kind``), the same seed; after ``warmup``
    steps each, ``rounds`` blocks of ``steps`` steps alternate between them, so that a machine whose
    load changes slows them alike. Returns per kind: env-steps/s over all its blocks and the alarm share.
    """
    from ea_gym.degradation import WearConfig
    from ea_gym.env.events import ActionKind
    from ea_gym.models import get_model
    from ea_gym.phm import PHMConfig

    wear = {name: WearConfig(arrival=(0.0, 1.0)) for name in get_model("spring_mass_damper").safe_limits}
    envs = {kind: gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", obs_mode="phm",
                               continue_after_failure=True, wear=wear, phm=PHMConfig(estimator_kind=kind)) for kind in kinds}
    walls = dict.fromkeys(kinds, 0.0)
    carry_on = np.full(n, _action_index(next(iter(envs.values())), ActionKind.CARRY_ON))
    for env in envs.values():
        env.reset(seed=seed)
        for _ in range(warmup):
            env.step(carry_on)
    for _ in range(rounds):
        for kind, env in envs.items():
            started = time.perf_counter()
            for _ in range(steps):
                env.step(carry_on)
            walls[kind] += time.perf_counter() - started
    results = {kind: {"env_steps_per_s": n * steps * rounds / walls[kind], "alarm_share": _alarm_share(env)} for kind, env in envs.items()}
    for env in envs.values():
        env.close()
    return results


def time_ppo(kind: str, steps: int, seed: int) -> float:
    from stable_baselines3 import PPO

    from agents.training import TrainingRun, default_hyperparameters, make_vec_env

    run = TrainingRun(n_envs=16, vec_env=kind)
    env = make_vec_env(run, 16, seed)
    model = PPO("MultiInputPolicy", env, seed=seed, verbose=0, **default_hyperparameters("ppo", 16))
    started = time.perf_counter()
    with single_threaded_torch():  # as agents.training does, for both kinds
        model.learn(total_timesteps=steps)
    wall = time.perf_counter() - started
    env.close()
    return wall


def profile_batched(n: int, steps: int, warmup: int, seed: int, top: int = 12) -> str:
    env = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", **KWARGS)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for _ in range(warmup):
        env.step(rng.integers(0, 7, n))
    profiler = cProfile.Profile()
    profiler.enable()
    for _ in range(steps):
        env.step(rng.integers(0, 7, n))
    profiler.disable()
    text = io.StringIO()
    pstats.Stats(profiler, stream=text).sort_stats("tottime").print_stats(top)
    return text.getvalue()


def in_alarm(steps: int, seed: int) -> dict:
    """The in-alarm regime at N = 256, both estimator kinds side by side; printed."""
    results = time_in_alarm(256, steps, ALARM_WARMUP, seed, ("ea_inversion", "tracking"))
    print(f"\nbatched env, N = 256, faults from the first second, no maintenance ({ALARM_WARMUP} steps in; old figure 1550 env-steps/s):")
    for kind, r in results.items():
        print(f"  {kind:>13}: {r['env_steps_per_s']:.0f} env-steps/s, alarm raised in {r['alarm_share']:.0%}")
    return results


def print_in_alarm(steps: int, seed: int, path: Path | None) -> int:
    results = in_alarm(steps, seed)
    if path:
        write_json(path, {"in_alarm_n256": results})
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 16, 256, 1024], help="numbers of environments N")
    parser.add_argument("--steps", type=int, default=20, help="timed batch steps per measurement")
    parser.add_argument("--warmup", type=int, default=120, help="batch steps before timing (faults arrive)")
    parser.add_argument("--sync-max", type=int, default=256, help="largest N for the SyncVectorEnv (it is slow)")
    parser.add_argument("--ppo-steps", type=int, default=16_384, help="PPO steps for the wall-time comparison (0: skip)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, default=None, help="also write the numbers as JSON")
    parser.add_argument("--alarm-steps", type=int, default=10, help="timed batch steps per block of the in-alarm regime (0: skip)")
    parser.add_argument("--alarm-only", action="store_true", help="only the in-alarm regime at N = 256")
    args = parser.parse_args(argv)
    if args.alarm_only:
        return print_in_alarm(args.alarm_steps, args.seed, args.json)

    print(f"machine: {platform.processor()!r}, {os.cpu_count()} cores, python {platform.python_version()}")
    results: dict = {"single": time_single(args.steps * 10, args.warmup, args.seed), "sync": {}, "batched": {}}
    print(f"single env: {results['single']['env_steps_per_s']:.0f} env-steps/s (alarm raised: {results['single']['alarm_share']:.0%})")
    print(f"\n{'N':>6} {'SyncVectorEnv':>15} {'batched':>12} {'speed-up':>9} {'alarm share':>12}")
    for n in args.sizes:
        batched = time_vector("vector_entry_point", n, args.steps, args.warmup, args.seed)
        results["batched"][n] = batched
        sync = time_vector("sync", n, max(args.steps // 4, 2), args.warmup // 4, args.seed) if n <= args.sync_max else None
        results["sync"][n] = sync
        ratio = f"{batched['env_steps_per_s'] / sync['env_steps_per_s']:.1f}x" if sync else "-"
        sync_text = f"{sync['env_steps_per_s']:.0f}" if sync else "skipped"
        print(f"{n:>6} {sync_text:>15} {batched['env_steps_per_s']:>12.0f} {ratio:>9} {batched['alarm_share']:>12.0%}")
    if args.ppo_steps:
        results["ppo"] = {kind: time_ppo(kind, args.ppo_steps, args.seed) for kind in ("batched", "subproc")}
        speedup = results["ppo"]["subproc"] / results["ppo"]["batched"]
        print(f"\nPPO, {args.ppo_steps} steps, 16 envs: batched {results['ppo']['batched']:.1f} s, "
              f"SubprocVecEnv {results['ppo']['subproc']:.1f} s ({speedup:.2f}x)")
    if args.alarm_steps:
        results["in_alarm_n256"] = in_alarm(args.alarm_steps, args.seed)
    profile = profile_batched(256, 5, args.warmup, args.seed)
    results["profile_n256"] = profile
    print("\nbatched env, N = 256, 5 steps, by own time:\n" + profile)
    best_256 = results["batched"].get(256, {}).get("env_steps_per_s")
    sync_256 = (results["sync"].get(256) or {}).get("env_steps_per_s")
    if best_256:
        verdict = "PASS" if best_256 >= 30_000 and sync_256 and best_256 >= 10 * sync_256 else "MISS"
        print(f"VERDICT {verdict}: batched N=256 {best_256:.0f} env-steps/s (target >= 30000, >= 10x SyncVectorEnv "
              f"{sync_256 and f'{sync_256:.0f}'})")
    if args.json:
        write_json(args.json, results)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
