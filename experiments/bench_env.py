"""Benchmark: throughput, time per stage and a long soak of the maintenance environment.

What it measures
    The single Gymnasium environment ``gymnasium.make("ea_gym/SpringMassDamper-v0",
    window_seconds=1.0, continue_after_failure=True, horizon=10**9)`` (100 Hz, so 100 samples of
    plant and reference simulation, denoising and EA per step), on ONE core: the process's threads
    are pinned to one CPU with ``os.sched_setaffinity`` where available (``--no-pin`` to skip), BLAS
    and OpenMP pools are limited to one thread with threadpoolctl and torch to one intra-op thread
    (the environment itself enters single-threaded BLAS/torch contexts around its hot calls).

    1. Throughput: env-steps per second (``env.step`` of the ``gym.make`` env, wrappers included)
       over ``--steps`` steps after ``--warmup`` steps, fresh environment, ``reset(seed=--seed)``.
       * per ``obs_mode`` ("phm", "sensors", "oracle"), random actions drawn from
         ``np.random.default_rng(--seed)`` and the default wear (a random component fails);
       * phm mode in two regimes, both with action 0 (carry on) at every step:
         "healthy": every component's fault arrives at 1e9 s (never), so no alarm, and the chain's
         EA inversion (which runs only after an alarm) never runs;
         "faulty": the spring k drifts down from t = 0 at 0.1 %/s of its nominal-to-limit distance
         (``WearConfig(direction=-1, rate=(0.001, 0.001), arrival=(0, 0))``): the alarm comes after
         ~15 steps, then the EA inversion runs at every step; it reaches the limit after 1000 s, is
         replaced (20 steps down, chain reset) and the same fault starts again.
       Each run reports steps/s (steps / total time, the number the verdict uses) and 1 / median step
       time (less sensitive to preemption by other processes on a shared machine), and the share of
       steps with a full isolation frame (the isolation network runs; 20 steps after every chain
       reset), with the alarm raised and with the EA inversion running; for the faulty regime also
       the rate over the inversion-running steps alone. With random actions, replacements (3 of the
       7 actions) reset the chain so often that isolation and inversion rarely run.
    2. Time per stage (phm mode, healthy and faulty regimes, ``--stage-steps`` steps each, fresh
       environments): the library's methods and the module functions it calls are wrapped at run
       time (instance attributes / module globals, restored afterwards) with timers that accumulate
       wall time per call path; a stage's time is its inclusive time minus that of the wrapped calls
       inside it, so the rows add up to the measured ``env.step`` time. Rows: load signal, plant +
       reference simulation (``ea_gym.env.core.simulate_measured``), measurement gains, sensor noise,
       EA monitor (``Monitor.update``), detection (``PHMChain._statistic``), isolation network
       (``_classify``: frame, features, torch), isolation belief (``_isolate``), EA inversion
       (``_estimate``), EoL extrapolation
       (``_prognose``), chain bookkeeping, observation (``MaintenanceCore._observe``), the rest of the
       core step, the env's own ``step`` and Gymnasium's wrappers (``env.step`` minus
       ``env.unwrapped.step``). A detailed call tree follows. The timers add about 0.5 us per wrapped
       call; the instrumented steps/s is printed next to the plain one.
    3. Soak: ``--soak-steps`` random-action steps in phm mode (``continue_after_failure=True``), every
       observation and reward checked for NaN/inf (exit code 1 if any, or if a step raises), memory
       sampled every ``--soak-sample-every`` steps: tracemalloc's current and peak traced memory
       (tracing started after the warm-up; it slows the steps about 3x) and the process RSS (VmRSS).
       Its actions come from ``default_rng(--seed + 1)`` and it resets with ``seed=--seed + 1``. Uniform
       random actions replace a component 3 times in 7, so the chain is reset too often to ever fill an
       isolation frame; ``--soak-carry-on 0.99`` (action 0 with that probability) soaks the whole chain:
       detection, isolation, EA inversion, failures and forced replacements.
    4. Verdict against the target ">= 2000 env-steps/s single env with the full PHM chain,
       window_seconds=1, one core": PASS only if phm mode with random actions, the healthy and the
       faulty regime all reach it; MISS otherwise. A MISS does not change the exit code.

How to run (from the repository root)
    .venv/bin/python experiments/bench_env.py [--steps 3000] [--warmup 50] [--stage-steps 3000]
        [--soak-steps 100000] [--soak-carry-on P] [--seed 0] [--core N | --no-pin] [--json PATH]

    ``--soak-steps 0`` skips the soak. Timings depend on the machine and on its load (printed).
"""

from __future__ import annotations

import argparse
import functools
import math
import os
import resource
import sys
import time
import tracemalloc
from collections import defaultdict
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

try:  # runnable as ``python experiments/bench_env.py`` from a checkout without installing
    import ea_gym
except ImportError:  # pragma: no cover - depends on how the script is started
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import ea_gym  # noqa: F401

import gymnasium as gym
import torch
from gymnasium import spaces
from machine import machine_info  # noqa: E402 - experiments/machine.py
from threadpoolctl import threadpool_limits

import ea_gym.env.operation as operation_module
import ea_gym.phm.inversion as inversion_module
import ea_gym.phm.isolation as isolation_module
import ea_gym.phm.prognosis as prognosis_module
from ea_gym.degradation import WearConfig
from ea_gym.diagnosis.database import classes_of
from ea_gym.env import ENV_ID
from ea_gym.env.core import MaintenanceCore
from ea_gym.env.maintenance import BondGraphMaintenanceEnv
from ea_gym.files import write_json
from ea_gym.models import get_model
from ea_gym.threads import single_threaded_blas, single_threaded_torch

SYSTEM = "spring_mass_damper"
OBS_MODES = ("phm", "sensors", "oracle")
#: Target of the verdict line (env-steps/s, single env, full PHM chain, window_seconds=1, one core).
TARGET_STEPS_PER_S = 2000.0
#: The slowly drifting fault of the "faulty" regime (on k only).
FAULT_COMPONENT = "k"
FAULT = WearConfig(direction=-1, rate=(0.001, 0.001), arrival=(0.0, 0.0))
NEVER = 1e9  # s: arrival of the "healthy" regime's faults


# -- machine, threads, core ---------------------------------------------------------------------


def pin_to_one_core(core: int) -> list[int] | None:
    """Pin every thread of this process (those alive now; new ones inherit) to CPU ``core``.

    Returns the CPU set of the main thread afterwards, or None where affinity is not supported.
    """
    if not hasattr(os, "sched_setaffinity"):
        return None
    tasks = Path("/proc/self/task")
    tids = [int(p.name) for p in tasks.iterdir()] if tasks.is_dir() else [0]
    for tid in tids:
        try:
            os.sched_setaffinity(tid, {core})
        except OSError:  # a thread that ended meanwhile
            pass
    return sorted(os.sched_getaffinity(0))


def rss_mib() -> float:
    """Current resident set size (MiB): VmRSS, else the peak from getrusage."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux, bytes on macOS
    return peak / (1024.0 * 1024.0) if sys.platform == "darwin" else peak / 1024.0


def context_costs(repeats: int = 2000) -> dict[str, float]:
    """Cost (us) of entering and leaving the library's single-threaded BLAS and torch contexts once."""
    out = {}
    for name, make in (("single_threaded_blas", single_threaded_blas), ("single_threaded_torch", single_threaded_torch)):
        for _ in range(50):
            with make():
                pass
        start = time.perf_counter()
        for _ in range(repeats):
            with make():
                pass
        out[name] = (time.perf_counter() - start) / repeats * 1e6
    return out


# -- environments and runs ------------------------------------------------------------------


def make_env(obs_mode: str, window: float, wear: dict[str, WearConfig] | None = None) -> tuple[gym.Env, float]:
    """A fresh ``gym.make`` environment and its construction time (s)."""
    start = time.perf_counter()
    kwargs: dict[str, Any] = {"obs_mode": obs_mode, "window_seconds": window, "continue_after_failure": True, "horizon": 10**9}
    if wear is not None:
        kwargs["wear"] = wear
    env = gym.make(ENV_ID, **kwargs)
    return env, time.perf_counter() - start


def core_of(env: gym.Env) -> MaintenanceCore:
    """The batched core behind a ``gym.make`` environment."""
    unwrapped = env.unwrapped
    assert isinstance(unwrapped, BondGraphMaintenanceEnv)
    return unwrapped.core


def n_actions_of(env: gym.Env) -> int:
    """The number of discrete actions of ``env``."""
    assert isinstance(env.action_space, spaces.Discrete)
    return int(env.action_space.n)


def regime_wear(regime: str) -> dict[str, WearConfig] | None:
    if regime == "random":
        return None
    if regime == "healthy":
        return {c: WearConfig(arrival=(NEVER, NEVER)) for c in classes_of(get_model(SYSTEM))[1:]}
    if regime == "faulty":
        return {FAULT_COMPONENT: FAULT}
    raise ValueError(regime)


def run(
    env: gym.Env, steps: int, warmup: int, seed: int, random_actions: bool, after_warmup: Callable[[], None] | None = None
) -> dict[str, Any]:
    """Reset, ``warmup`` untimed steps, then ``steps`` timed ``env.step`` calls; per-step statistics."""
    rng = np.random.default_rng(seed)
    n_actions = n_actions_of(env)
    env.reset(seed=seed)
    chain = core_of(env).chain

    def act() -> int:
        return int(rng.integers(n_actions)) if random_actions else 0

    for _ in range(warmup):
        env.step(act())
    if after_warmup is not None:
        after_warmup()
    durations = np.empty(steps)
    alarm = np.zeros(steps, dtype=bool)
    estimating = np.zeros(steps, dtype=bool)
    isolating = np.zeros(steps, dtype=bool)
    failures = 0
    perf = time.perf_counter
    step = env.step
    for i in range(steps):
        action = act()
        t0 = perf()
        _, _, terminated, truncated, info = step(action)
        durations[i] = perf() - t0
        failures += info["failed"]
        if chain is not None:
            alarm[i] = chain.detector.state.alarm[0]
            estimating[i] = alarm[i] and chain.history.steps[0] >= chain.estimate_steps
            isolating[i] = chain.history.steps[0] >= chain.frame_steps
        if terminated or truncated:  # not expected with continue_after_failure and horizon 1e9
            env.reset()
    total = float(durations.sum())
    out: dict[str, Any] = {
        "steps": steps,
        "warmup": warmup,
        "seconds": total,
        "steps_per_s": steps / total,
        "mean_ms": 1e3 * total / steps,
        "median_ms": 1e3 * float(np.median(durations)),
        "steps_per_s_from_median": 1.0 / float(np.median(durations)),
        "p95_ms": 1e3 * float(np.percentile(durations, 95)),
        "max_ms": 1e3 * float(durations.max()),
        "failures": int(failures),
    }
    if chain is not None:
        out["alarm_fraction"] = float(alarm.mean())
        out["estimating_fraction"] = float(estimating.mean())
        out["isolating_fraction"] = float(isolating.mean())
        for label, mask in (("estimating", estimating), ("not_estimating", ~estimating)):
            out[f"{label}_steps_per_s"] = float(mask.sum() / durations[mask].sum()) if mask.any() else None
    return out


# -- time per stage -------------------------------------------------------------------------


class Profiler:
    """Accumulates inclusive wall time and calls per call path (a tuple of wrapped names)."""

    def __init__(self) -> None:
        self.stack: list[str] = []
        self.total: dict[tuple[str, ...], float] = defaultdict(float)
        self.calls: dict[tuple[str, ...], int] = defaultdict(int)

    def wrap(self, name: str, fn: Callable) -> Callable:
        stack, total, calls, perf = self.stack, self.total, self.calls, time.perf_counter

        @functools.wraps(fn)
        def timed(*args, **kwargs):
            stack.append(name)
            key = tuple(stack)
            start = perf()
            try:
                return fn(*args, **kwargs)
            finally:
                total[key] += perf() - start
                calls[key] += 1
                stack.pop()

        return timed

    def inclusive(self, *path: str) -> float:
        return self.total.get(path, 0.0)

    def self_time(self, *path: str) -> float:
        children = sum(t for key, t in self.total.items() if len(key) == len(path) + 1 and key[:-1] == path)
        return self.inclusive(*path) - children


@contextmanager
def instrumented(env: gym.Env, profiler: Profiler) -> Iterator[None]:
    """Wrap the environment's stages with ``profiler``'s timers; restore everything on exit."""
    unwrapped = env.unwrapped
    core = core_of(env)
    chain = core.chain
    monitor = core.monitor
    # (object, attribute, timer name); instance attributes shadow the class's methods
    targets: list[tuple[Any, str, str]] = [
        (unwrapped, "step", "unwrapped.step"),
        (core, "step", "core.step"),
        (core, "operate", "operate"),
        (core.operation, "run", "operation.run"),
        (core.operation, "load", "load"),
        (core, "observe", "observe"),
        (core, "true_rul", "true_rul"),
        (core.degradation, "advance", "degradation.advance"),
        (operation_module, "simulate_measured", "simulate_measured"),
        (core.operation, "sensor_noise", "sensor_noise"),
        (monitor, "measurement_gain", "measurement_gain"),
        (monitor, "update", "monitor.update"),
        (monitor, "powers", "monitor.powers"),
    ]
    if chain is not None:
        targets += [
            (chain, "update", "chain.update"),
            (chain.detector, "update", "detector.update"),
            (chain.isolation, "classify", "isolation.classify"),
            (chain.isolation, "fuse", "isolation.fuse"),
            (chain.isolation, "balance_evidence", "isolation.balance_evidence"),
            (chain.estimator, "update", "estimator.update"),
            (chain.prognosis, "update", "prognosis.update"),
            (monitor, "frame_of", "monitor.frame_of"),
            (monitor, "state_filter", "monitor.state_filter"),
            (isolation_module, "frame_features", "frame_features"),
            (prognosis_module, "predict_end_of_life", "predict_end_of_life"),
            (chain.classifier, "predict_proba", "classifier.predict_proba"),
            (chain.estimator.inversion, "estimate", "inversion.estimate"),
            (chain.estimator.inversion, "candidate_signature", "inversion.candidate_signature"),
            (inversion_module, "simulate_measured", "simulate_measured (candidates)"),
        ]
    saved: list[tuple[Any, str, bool, Any]] = []
    try:
        for obj, attr, name in targets:
            original = getattr(obj, attr)
            # module globals and instance data (state_filter) are put back; a method wrapped as an
            # instance attribute is deleted so that the class's method shows through again
            had_own = attr in vars(obj)
            saved.append((obj, attr, had_own, original))
            setattr(obj, attr, profiler.wrap(name, original))
        yield
    finally:
        for obj, attr, had_own, original in reversed(saved):
            if had_own:
                setattr(obj, attr, original)
            else:
                delattr(obj, attr)


def stage_rows(p: Profiler, steps: int, step_total: float) -> list[tuple[str, float]]:
    """(label, seconds) rows adding up to ``step_total``: the flat stage table."""
    in_env = ("unwrapped.step",)
    in_core = in_env + ("core.step",)
    in_operate = in_core + ("operate",)
    in_run = in_operate + ("operation.run",)
    in_chain = in_operate + ("chain.update",)
    observe = p.inclusive(*in_core, "observe")
    rows = [
        ("load signal (Operation.load)", p.inclusive(*in_run, "load")),
        ("plant + reference simulation (simulate_measured)", p.inclusive(*in_run, "simulate_measured")),
        ("measurement gains and products (Operation.run rest)", p.self_time(*in_run) + p.inclusive(*in_run, "measurement_gain")),
        ("measurement noise (Operation.sensor_noise)", p.inclusive(*in_run, "sensor_noise")),
        ("EA monitor (Monitor.update)", p.inclusive(*in_chain, "monitor.update")),
        ("detection (Detector.update)", p.inclusive(*in_chain, "detector.update")),
        ("isolation network (Isolation.classify: frame, features, torch)", p.inclusive(*in_chain, "isolation.classify")),
        ("isolation belief (Isolation.fuse + balance_evidence: network x EA fits x balance)",
         p.inclusive(*in_chain, "isolation.fuse") + p.inclusive(*in_chain, "isolation.balance_evidence")),
        ("estimation: EA inversion (estimator.update)", p.inclusive(*in_chain, "estimator.update")),
        ("prognosis: EoL extrapolation (prognosis.update)", p.inclusive(*in_chain, "prognosis.update")),
        ("chain bookkeeping (PHMChain.update rest)", p.self_time(*in_chain)),
        ("step outputs (MaintenanceCore.operate rest)", p.self_time(*in_operate)),
        ("observation (MaintenanceCore.observe)", observe),
        (
            "core step rest (actions, wear, costs, RUL)",
            p.self_time(*in_core) + p.inclusive(*in_core, "degradation.advance") + p.inclusive(*in_core, "true_rul"),
        ),
        ("env.unwrapped.step rest (info, history)", p.self_time(*in_env)),
        ("Gymnasium wrappers (env.step - unwrapped.step)", step_total - p.inclusive(*in_env)),
    ]
    return rows


def profile_regime(regime: str, args: argparse.Namespace) -> dict[str, Any]:
    env, _ = make_env("phm", args.window, regime_wear(regime))
    profiler = Profiler()

    def forget_warmup() -> None:
        profiler.total.clear()
        profiler.calls.clear()

    with instrumented(env, profiler):
        stats = run(env, args.stage_steps, args.warmup, args.seed, random_actions=False, after_warmup=forget_warmup)
    env.close()
    steps = args.stage_steps
    total = stats["seconds"]
    rows = stage_rows(profiler, steps, total)
    tree = {
        " > ".join(key): {"ms_per_step": 1e3 * t / steps, "calls_per_step": profiler.calls[key] / steps}
        for key, t in profiler.total.items()
    }
    return {
        "run": stats,
        "stages": [{"stage": label, "ms_per_step": 1e3 * t / steps, "share": t / total} for label, t in rows],
        "tree": tree,
    }


# -- soak -------------------------------------------------------------------------------------


def _finite_step(i: int, obs: dict[str, np.ndarray], reward: float, bad: list[str]) -> bool:
    """Whether step i's observation and reward are finite; the first five problems are noted in ``bad``."""
    finite = math.isfinite(reward)
    for key, value in obs.items():
        if not np.all(np.isfinite(value)):
            finite = False
            if len(bad) < 5:
                bad.append(f"step {i}: obs[{key!r}] = {value!r}")
    if not math.isfinite(reward) and len(bad) < 5:
        bad.append(f"step {i}: reward = {reward!r}")
    return finite


def soak(args: argparse.Namespace) -> dict[str, Any]:
    from tqdm import tqdm

    env, _ = make_env("phm", args.window)
    rng = np.random.default_rng(args.seed + 1)
    n_actions = n_actions_of(env)
    carry_on = args.soak_carry_on

    def act() -> int:
        if carry_on is not None and rng.random() < carry_on:
            return 0
        return int(rng.integers(n_actions))

    env.reset(seed=args.seed + 1)
    for _ in range(args.warmup):
        env.step(act())
    tracemalloc.start()
    samples: list[dict[str, float]] = []
    bad: list[str] = []
    n_bad = 0
    outside = 0
    failures = 0
    resets = 0
    alarm_steps = 0
    estimating_steps = 0
    isolating_steps = 0
    chain = core_of(env).chain
    error = None
    start = time.perf_counter()

    def sample(step: int) -> None:
        current, peak = tracemalloc.get_traced_memory()
        samples.append({
            "step": step, "elapsed_s": time.perf_counter() - start,
            "traced_mib": current / 2**20, "traced_peak_mib": peak / 2**20, "rss_mib": rss_mib(),
        })

    sample(0)
    space = env.observation_space
    steps_done = 0
    with tqdm(total=args.soak_steps, desc="soak (phm, random actions)", unit="step", mininterval=2.0, file=sys.stderr) as bar:
        for i in range(1, args.soak_steps + 1):
            try:
                obs, reward, terminated, truncated, info = env.step(act())
            except Exception as exc:  # noqa: BLE001 - a crash is a soak failure: report it
                error = f"step {i}: {type(exc).__name__}: {exc}"
                break
            steps_done = i
            if not _finite_step(i, obs, float(reward), bad):
                n_bad += 1
            elif not space.contains(obs):
                outside += 1
            failures += info["failed"]
            alarm = bool(chain.detector.state.alarm[0])
            alarm_steps += alarm
            estimating_steps += alarm and chain.history.steps[0] >= chain.estimate_steps
            isolating_steps += chain.history.steps[0] >= chain.frame_steps
            if terminated or truncated:
                resets += 1
                env.reset()
            if i % args.soak_sample_every == 0:
                sample(i)
            if i % 500 == 0:
                bar.update(500)
        bar.update(steps_done - bar.n)
    if not samples or samples[-1]["step"] != steps_done:
        sample(steps_done)
    elapsed = time.perf_counter() - start
    tracemalloc.stop()
    env.close()
    first, last = samples[0], samples[-1]
    settled = samples[1] if len(samples) > 2 else first
    return {
        "steps": steps_done,
        "requested_steps": args.soak_steps,
        "seconds": elapsed,
        "steps_per_s_with_tracemalloc": steps_done / elapsed if elapsed > 0 else None,
        "non_finite_steps": n_bad,
        "non_finite_examples": bad,
        "outside_observation_space": outside,
        "failures": int(failures),
        "resets": resets,
        "alarm_fraction": alarm_steps / steps_done if steps_done else None,
        "estimating_fraction": estimating_steps / steps_done if steps_done else None,
        "isolating_fraction": isolating_steps / steps_done if steps_done else None,
        "error": error,
        "samples": samples,
        "traced_growth_mib": last["traced_mib"] - first["traced_mib"],
        "traced_growth_after_first_sample_mib": last["traced_mib"] - settled["traced_mib"],
        "rss_growth_mib": last["rss_mib"] - first["rss_mib"],
        "rss_growth_after_first_sample_mib": last["rss_mib"] - settled["rss_mib"],
    }


# -- output -----------------------------------------------------------------------------------


def finite_or_none(value: Any) -> Any:
    """The structure with non-finite floats replaced by None (JSON has no NaN/inf)."""
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def fmt(value: float | None, spec: str = ".1f") -> str:
    return "n/a" if value is None else format(value, spec)


def print_throughput(rows: list[tuple[str, dict[str, Any], float | None]]) -> None:
    print(
        f"{'run':<34}{'steps/s':>9}{'1/median':>9}{'mean ms':>9}{'median':>8}{'p95':>8}{'max':>8}"
        f"{'iso.':>6}{'alarm':>7}{'inv.':>6}{'fail':>5}{'make s':>8}"
    )
    for label, r, make_s in rows:
        alarm = fmt(100 * r["alarm_fraction"], ".0f") + "%" if "alarm_fraction" in r else "-"
        iso = fmt(100 * r["isolating_fraction"], ".0f") + "%" if "isolating_fraction" in r else "-"
        inv = fmt(100 * r["estimating_fraction"], ".0f") + "%" if "estimating_fraction" in r else "-"
        print(
            f"{label:<34}{r['steps_per_s']:>9.1f}{r['steps_per_s_from_median']:>9.1f}{r['mean_ms']:>9.3f}{r['median_ms']:>8.3f}{r['p95_ms']:>8.3f}"
            f"{r['max_ms']:>8.2f}{iso:>6}{alarm:>7}{inv:>6}{r['failures']:>5d}{fmt(make_s, '.2f'):>8}"
        )


def print_stages(profiles: dict[str, dict[str, Any]]) -> None:
    names = list(profiles)
    header = f"{'stage':<50}" + "".join(f"{n + ' ms/step':>17}{'share':>8}" for n in names)
    print(header)
    labels = [row["stage"] for row in profiles[names[0]]["stages"]]
    for i, label in enumerate(labels):
        line = f"{label:<50}"
        for n in names:
            row = profiles[n]["stages"][i]
            line += f"{row['ms_per_step']:>17.3f}{100 * row['share']:>7.1f}%"
        print(line)
    line = f"{'total (env.step)':<50}"
    for n in names:
        line += f"{profiles[n]['run']['mean_ms']:>17.3f}{100.0:>7.1f}%"
    print(line)
    line = f"{'  instrumented steps/s':<50}"
    for n in names:
        line += f"{profiles[n]['run']['steps_per_s']:>17.1f}{'':>8}"
    print(line)


def print_tree(profiles: dict[str, dict[str, Any]]) -> None:
    names = list(profiles)
    keys: list[str] = []
    for n in reversed(names):  # the faulty regime calls everything
        keys += [k for k in profiles[n]["tree"] if k not in keys]
    keys = sorted(keys, key=lambda k: _order(keys, k))
    print(f"{'call path (inclusive)':<58}" + "".join(f"{n + ' ms':>13}{'calls':>7}" for n in names))
    for key in keys:
        depth = key.count(" > ")
        label = "  " * depth + key.rsplit(" > ", 1)[-1]
        line = f"{label:<58}"
        for n in names:
            entry = profiles[n]["tree"].get(key)
            line += f"{entry['ms_per_step']:>13.3f}{entry['calls_per_step']:>7.2f}" if entry else f"{'-':>13}{'-':>7}"
        print(line)


def _order(keys: list[str], key: str) -> list[int]:
    """Sort key placing every path after its parent, siblings in the order they were first recorded."""
    parts = key.split(" > ")
    prefixes = (" > ".join(parts[: i + 1]) for i in range(len(parts)))
    return [keys.index(p) if p in keys else -1 for p in prefixes]


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description=(
            f"Throughput, time per stage and a soak of {ENV_ID} (window_seconds=1, continue_after_failure, "
            "horizon 1e9) on one core."
        ),
        epilog=f"Verdict target: >= {TARGET_STEPS_PER_S:g} env-steps/s, single env, full PHM chain, one core.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--steps", type=int, default=3000, help="timed steps per throughput run")
    parser.add_argument("--warmup", type=int, default=50, help="untimed steps before each timed run")
    parser.add_argument("--stage-steps", type=int, default=None, help="steps per stage-timing run; None: as many as --steps (default: %(default)s)")
    parser.add_argument("--soak-steps", type=int, default=100_000, help="soak steps (0: skip the soak)")
    parser.add_argument(
        "--soak-carry-on", type=float, default=None, metavar="P",
        help="soak policy: action 0 (carry on) with probability P, else a uniform random action "
        "(None: uniform random actions, whose frequent replacements keep the chain from isolating) (default: %(default)s)",
    )
    parser.add_argument("--soak-sample-every", type=int, default=10_000, help="memory sample period of the soak (steps)")
    parser.add_argument("--window", type=float, default=1.0, help="window_seconds of the environment")
    parser.add_argument("--seed", type=int, default=0, help="seed of resets and random actions")
    parser.add_argument("--core", type=int, default=None, help="CPU to pin to; None: the lowest allowed one (default: %(default)s)")
    parser.add_argument("--no-pin", action="store_true", help="do not pin the process to one CPU")
    parser.add_argument("--json", type=Path, default=None, metavar="PATH", help="also write the numbers as JSON to PATH (atomic)")
    args = parser.parse_args(argv)
    if args.stage_steps is None:
        args.stage_steps = args.steps
    for name in ("steps", "stage_steps", "soak_sample_every"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
    for name in ("warmup", "soak_steps"):
        if getattr(args, name) < 0:
            parser.error(f"--{name.replace('_', '-')} must be >= 0, got {getattr(args, name)}")
    if args.soak_carry_on is not None and not 0.0 <= args.soak_carry_on <= 1.0:
        parser.error(f"--soak-carry-on must be a probability in [0, 1], got {args.soak_carry_on}")
    if not (math.isfinite(args.window) and args.window > 0):
        parser.error(f"--window must be a positive number of seconds, got {args.window}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    info = machine_info()
    # one thread everywhere: BLAS/OpenMP pools, torch intra- and inter-op
    limits = threadpool_limits(limits=1)  # noqa: F841 - kept alive for the whole run
    torch.set_num_threads(1)
    try:
        torch.set_num_interop_threads(1)
    except RuntimeError:  # only settable before torch's first parallel work
        pass
    pinned = None
    if not args.no_pin and hasattr(os, "sched_getaffinity"):
        core = args.core if args.core is not None else min(os.sched_getaffinity(0))
        pinned = pin_to_one_core(core)

    def repin() -> None:  # threads started since (torch, BLAS) inherit; re-pin the stragglers anyway
        if pinned is not None:
            pin_to_one_core(pinned[0])

    print(f"ea_gym environment benchmark: {ENV_ID}, window_seconds={args.window:g}, continue_after_failure=True, horizon=1e9")
    print(
        f"  machine: processor={info['processor']!r} cpu_count={info['cpu_count']} | python {info['python']} | "
        f"numpy {info['numpy']} | torch {info['torch']} | gymnasium {info['gymnasium']}"
    )
    load = info["load_average"]
    print(
        f"  load average (1/5/15 min): {'n/a' if load is None else ' '.join(f'{x:.2f}' for x in load)} | "
        f"CPU affinity: {pinned if pinned is not None else 'not pinned'} | BLAS/OpenMP threads 1 | "
        f"torch threads {torch.get_num_threads()} (inter-op {torch.get_num_interop_threads()})"
    )
    contexts = context_costs()
    print(
        "  library thread-limit contexts, per entry: "
        + ", ".join(f"{k} {v:.1f} us" for k, v in contexts.items())
    )
    print()

    # 1. throughput
    print(f"1. Throughput ({args.steps} timed steps after {args.warmup} warm-up steps, seed {args.seed}; "
          "alarm / inv. = share of steps with the alarm raised / the EA inversion running)")
    throughput: dict[str, Any] = {}
    rows: list[tuple[str, dict[str, Any], float | None]] = []
    for mode in OBS_MODES:
        env, make_s = make_env(mode, args.window)
        repin()
        r = run(env, args.steps, args.warmup, args.seed, random_actions=True)
        env.close()
        r["construction_s"] = make_s
        throughput[mode] = r
        rows.append((f"obs_mode={mode}, random actions", r, make_s))
    regimes: dict[str, Any] = {}
    for regime in ("healthy", "faulty"):
        env, make_s = make_env("phm", args.window, regime_wear(regime))
        repin()
        r = run(env, args.steps, args.warmup, args.seed, random_actions=False)
        env.close()
        r["construction_s"] = make_s
        regimes[regime] = r
        rows.append((f"phm {regime}, action 0", r, make_s))
    print_throughput(rows)
    f = regimes["faulty"]
    print(
        f"  faulty regime, steps with the EA inversion running: {fmt(f['estimating_steps_per_s'])} steps/s; "
        f"the others: {fmt(f['not_estimating_steps_per_s'])} steps/s"
    )
    print()

    # 2. time per stage
    print(f"2. Time per stage, phm mode, action 0 ({args.stage_steps} steps per regime after {args.warmup} warm-up steps; "
          "rows add up to the env.step time)")
    profiles = {}
    for regime in ("healthy", "faulty"):
        repin()
        profiles[regime] = profile_regime(regime, args)
    print_stages(profiles)
    print()
    print_tree(profiles)
    print()

    # 3. soak
    soak_result = None
    status = 0
    if args.soak_steps > 0:
        policy = (
            "uniform random actions" if args.soak_carry_on is None
            else f"carry on with probability {args.soak_carry_on:g}, else a uniform random action"
        )
        print(f"3. Soak: {args.soak_steps} steps, {policy}, phm mode, continue_after_failure=True, tracemalloc on")
        repin()
        soak_result = soak(args)
        s = soak_result
        print(f"{'step':>8}{'elapsed s':>11}{'traced MiB':>12}{'traced peak':>13}{'RSS MiB':>10}")
        for row in s["samples"]:
            print(f"{row['step']:>8d}{row['elapsed_s']:>11.1f}{row['traced_mib']:>12.3f}{row['traced_peak_mib']:>13.3f}{row['rss_mib']:>10.1f}")
        print(
            f"  {s['steps']} steps in {s['seconds']:.1f} s ({fmt(s['steps_per_s_with_tracemalloc'])} steps/s with tracemalloc), "
            f"{s['failures']} failures, {s['resets']} resets; share of steps with a full isolation frame "
            f"{100 * (s['isolating_fraction'] or 0):.0f}%, alarm raised {100 * (s['alarm_fraction'] or 0):.1f}%, "
            f"EA inversion running {100 * (s['estimating_fraction'] or 0):.1f}%"
        )
        print(
            f"  memory growth first -> last sample: traced {s['traced_growth_mib']:+.3f} MiB, RSS {s['rss_growth_mib']:+.1f} MiB; "
            f"from the second sample: traced {s['traced_growth_after_first_sample_mib']:+.3f} MiB, "
            f"RSS {s['rss_growth_after_first_sample_mib']:+.1f} MiB"
        )
        print(f"  steps with NaN/inf in observation or reward: {s['non_finite_steps']}; "
              f"finite observations outside observation_space: {s['outside_observation_space']}")
        for example in s["non_finite_examples"]:
            print(f"    {example}")
        if s["error"]:
            print(f"  ERROR: {s['error']}")
        if s["non_finite_steps"] or s["error"]:
            status = 1
        print(f"  soak: {'FAIL' if status else 'ok'}")
        print()

    # 4. verdict
    measured = {
        "phm random actions": throughput["phm"]["steps_per_s"],
        "phm healthy": regimes["healthy"]["steps_per_s"],
        "phm faulty": regimes["faulty"]["steps_per_s"],
    }
    worst = min(measured.values())
    verdict = "PASS" if worst >= TARGET_STEPS_PER_S else "MISS"
    from_median = {
        "phm random actions": throughput["phm"]["steps_per_s_from_median"],
        "phm healthy": regimes["healthy"]["steps_per_s_from_median"],
        "phm faulty": regimes["faulty"]["steps_per_s_from_median"],
    }
    print(
        f"VERDICT: {verdict} - full PHM chain, window_seconds={args.window:g}, one core: "
        + ", ".join(f"{k} {v:.0f} steps/s" for k, v in measured.items())
        + f" (target >= {TARGET_STEPS_PER_S:g}; worst {worst:.0f} = {100 * worst / TARGET_STEPS_PER_S:.0f}% of it); "
        + "from the median step time: "
        + ", ".join(f"{k} {v:.0f}" for k, v in from_median.items())
    )

    if args.json is not None:
        result = {
            "machine": info,
            "settings": {
                "env_id": ENV_ID, "window_seconds": args.window, "steps": args.steps, "warmup": args.warmup,
                "stage_steps": args.stage_steps, "soak_steps": args.soak_steps,
                "soak_sample_every": args.soak_sample_every, "soak_carry_on": args.soak_carry_on, "seed": args.seed,
                "cpu_affinity": pinned,
                "torch_threads": torch.get_num_threads(),
                "faulty_regime": {
                    "component": FAULT_COMPONENT, "direction": FAULT.direction, "rate": list(FAULT.rate), "arrival": list(FAULT.arrival),
                },
                "healthy_regime_arrival_s": NEVER,
            },
            "context_costs_us": contexts,
            "throughput": throughput,
            "regimes": regimes,
            "stages": profiles,
            "soak": soak_result,
            "target_steps_per_s": TARGET_STEPS_PER_S,
            "measured_steps_per_s": measured,
            "steps_per_s_from_median": from_median,
            "verdict": verdict,
            "exit_status": status,
        }
        write_json(args.json, finite_or_none(result))
        print(f"wrote {args.json}")
    return status


if __name__ == "__main__":
    raise SystemExit(main())
