"""Benchmark: ea_gym's exact-discretization simulator against scipy's solve_ivp.

What it measures
    The spring-mass-damper of ``ea_gym.models.spring_mass_damper`` (m = 10 kg, b = 0.5 N s/m) with a
    drifting stiffness k(t) = 100 - 14 t / duration N/m (100 -> 86 N/m over the run, inside the safe
    range 85..105 N/m; with the default 1000 s this is k(t) = 100 - 0.014 t), driven from rest by the
    persistently exciting load F(t) = 10 + 5 sin(2 pi 0.3 t) N, sampled at ``--rate`` Hz.

    * ea_gym: wall time of ``ea_gym.plant.run_model``, which returns the states AND every element's
      effort, flow and power. One warm-up call (numba cache load / JIT, model set-up) is reported
      separately as "first call"; then the best and median of ``--repeats`` calls.
    * scipy: wall time of ``scipy.integrate.solve_ivp(method="RK45", rtol=1e-8, atol=1e-10 * scale)``
      on the same ODE with k(t) continuous in time (dp/dt = F - k q - b p / m, dq/dt = p / m) and
      ``t_eval`` at the same samples, plus the computation of each element's effort, flow and power
      from its solution, so that both sides deliver the same outputs. Its right-hand side is plain
      scalar Python (math.sin), the fastest honest form for solve_ivp. Median of min(3, repeats).
    * accuracy: max |difference| of the position q and of the momentum p, relative to each signal's
      amplitude (max |.|), between the two simulators, and of each against a tight DOP853
      (rtol = atol = 1e-12) reference, to show which side carries the error.

    Verdict: PASS when solve_ivp time / ea_gym time (medians) >= 20 and the largest relative
    difference (q and p, ea_gym vs RK45) <= 1e-6; MISS otherwise.

How to run (from the repository root)
    python experiments/benchmarks/bench_simulation.py [--duration 1000] [--rate 100] [--repeats 5] [--json PATH] [--smoke]

The machine and library versions are printed with the results; timings depend on machine load.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's ea_gym and experiments.common, installed or not

from ea_gym.files import write_json
from ea_gym.loads import Sine, SinesLoad
from ea_gym.models import SystemModel, spring_mass_damper
from ea_gym.plant import run_model
from experiments.common import machine_info, parse_with_smoke

#: Targets of the verdict line.
TARGET_RATIO = 20.0
TARGET_REL_DIFF = 1e-6

# Scenario (SI units).
K_START = 100.0  # N/m at t = 0
K_DRIFT = 14.0  # N/m lost over the whole run (100 -> 86 N/m)
F_OFFSET = 10.0  # N
F_AMPLITUDE = 5.0  # N
F_FREQUENCY = 0.3  # Hz

# solve_ivp settings under test and for the reference.
RK45_RTOL = 1e-8
RK45_ATOL_FACTOR = 1e-10
REF_TOL = 1e-12
#: the smoke run: 20 s of signal, one timed call
SMOKE = {"duration": 20.0, "repeats": 1}


class Scenario:
    """The benchmark scenario: the model, the sample times, the load and the stiffness drift."""

    def __init__(self, duration: float, rate: float) -> None:
        self.duration = float(duration)
        self.rate = float(rate)
        n_steps = int(round(self.duration * self.rate))
        self.t = np.linspace(0.0, n_steps / self.rate, n_steps + 1)
        self.model: SystemModel = spring_mass_damper()
        self.load = SinesLoad(offset=F_OFFSET, sines=(Sine(amplitude=F_AMPLITUDE, frequency=F_FREQUENCY),))
        self.nominal = self.model.parameter_vector()
        names = self.model.parameter_names
        self.i_m, self.i_k, self.i_b = names.index("m"), names.index("k"), names.index("b")
        self.mass = float(self.nominal[self.i_m])
        self.damping = float(self.nominal[self.i_b])
        self.k_rate = K_DRIFT / self.duration  # N/m per s
        # state order of the model: p of the mass, q of the spring
        self.i_p, self.i_q = self.model.state_names.index("m"), self.model.state_names.index("k")

    def stiffness(self, t: np.ndarray | float) -> np.ndarray | float:
        return K_START - self.k_rate * t

    def parameters(self, t: np.ndarray) -> np.ndarray:
        """Component values (len(t), P) in ``model.parameter_names`` order, k drifting linearly."""
        theta = np.repeat(self.nominal[None, :], len(t), axis=0)
        theta[:, self.i_k] = self.stiffness(t)
        return theta

    def state_scale(self) -> np.ndarray:
        """A priori magnitude of (p, q) for solve_ivp's atol: static deflection under the peak load."""
        q_scale = (F_OFFSET + F_AMPLITUDE) / (K_START - K_DRIFT)  # m
        p_scale = q_scale * math.sqrt(K_START * self.mass)  # kg m/s (m * omega_n * q)
        return np.array([p_scale, q_scale])


def run_ea_gym(sc: Scenario) -> dict[str, np.ndarray]:
    trajectory = run_model(sc.model, sc.t, sc.load, parameters=sc.parameters, initial_state=np.zeros(2))
    return {
        "p": trajectory.states[:, sc.i_p],
        "q": trajectory.states[:, sc.i_q],
        "power": trajectory.power,
    }


def run_scipy(sc: Scenario, method: str, rtol: float, atol: float | np.ndarray) -> dict[str, Any]:
    """Integrate the ODE with solve_ivp and derive every element's effort, flow and power."""
    m, b, k0, k_rate = sc.mass, sc.damping, K_START, sc.k_rate
    omega = 2.0 * math.pi * F_FREQUENCY
    sin = math.sin

    def rhs(t: float, x: np.ndarray) -> list[float]:
        p, q = x[0], x[1]
        force = F_OFFSET + F_AMPLITUDE * sin(omega * t)
        return [force - (k0 - k_rate * t) * q - b * p / m, p / m]

    t = sc.t
    sol = solve_ivp(rhs, (float(t[0]), float(t[-1])), [0.0, 0.0], method=method, t_eval=t, rtol=rtol, atol=atol)
    if not sol.success:
        raise RuntimeError(f"solve_ivp({method}) failed: {sol.message}")
    p, q = sol.y
    v = p / m  # common flow of the 1-junction (m/s)
    force = sc.load.value(t)
    k = sc.stiffness(t)
    effort = {"F": force, "k": k * q, "b": b * v}
    effort["m"] = force - effort["k"] - effort["b"]
    power = {name: e * v for name, e in effort.items()}
    return {"p": p, "q": q, "power": power, "nfev": int(sol.nfev)}


def time_calls(fn: Callable[[], Any], repeats: int) -> tuple[list[float], Any]:
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return times, result


def rel_diff(a: np.ndarray, b: np.ndarray, scale: np.ndarray) -> float:
    """max |a - b| relative to max |scale| (the signal's amplitude)."""
    return float(np.max(np.abs(a - b)) / np.max(np.abs(scale)))


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description=(
            "Time ea_gym.plant.run_model (states + every element's effort, flow and power) against "
            "scipy solve_ivp(RK45, rtol=1e-8) on a spring-mass-damper with drifting stiffness "
            "k(t) = 100 -> 86 N/m and load F(t) = 10 + 5 sin(2 pi 0.3 t) N, and compare their accuracy "
            "with a DOP853 (rtol=atol=1e-12) reference."
        ),
        epilog=f"Verdict targets: speed ratio >= {TARGET_RATIO:g}x and max relative difference <= {TARGET_REL_DIFF:g}.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--duration", type=float, default=1000.0, help="simulated time span (s)")
    parser.add_argument("--rate", type=float, default=100.0, help="sample rate (Hz)")
    parser.add_argument(
        "--repeats", type=int, default=5, help="timed ea_gym calls after the warm-up; solve_ivp runs min(3, repeats)"
    )
    parser.add_argument("--json", type=Path, default=None, metavar="PATH", help="also write the numbers as JSON to PATH (atomic)")
    args = parse_with_smoke(parser, argv, SMOKE)
    if not (math.isfinite(args.duration) and args.duration > 0):
        parser.error(f"--duration must be a finite number > 0 s, got {args.duration}")
    if not (math.isfinite(args.rate) and args.rate > 0):
        parser.error(f"--rate must be a finite number > 0 Hz, got {args.rate}")
    if int(round(args.duration * args.rate)) < 2:
        parser.error("--duration * --rate must give at least 2 sample intervals")
    if args.repeats < 1:
        parser.error(f"--repeats must be >= 1, got {args.repeats}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    sc = Scenario(args.duration, args.rate)
    info = machine_info()
    n_samples = len(sc.t)

    print("ea_gym simulation benchmark: spring-mass-damper, drifting stiffness")
    print(
        f"  machine: processor={info['processor']!r} cpu_count={info['cpu_count']} | python {info['python']} | "
        f"numpy {info['numpy']} | scipy {info['scipy']} | numba {info['numba']}"
    )
    threads = ", ".join(f"{k}={v if v is not None else 'unset'}" for k, v in info["blas_threads_env"].items())
    load = info["load_average"]
    print(f"  load average (1/5/15 min): {'n/a' if load is None else ' '.join(f'{x:.2f}' for x in load)} | {threads}")
    print(
        f"  scenario: {sc.t[-1]:g} s at {sc.rate:g} Hz ({n_samples} samples), k(t) = {K_START:g} - {sc.k_rate:g} t N/m "
        f"({K_START:g} -> {float(sc.stiffness(sc.t[-1])):g}), F(t) = {F_OFFSET:g} + {F_AMPLITUDE:g} sin(2 pi {F_FREQUENCY:g} t) N, "
        "from rest"
    )
    print()

    # ea_gym: warm-up (numba cache load / JIT, model matrices set-up), then the timed calls
    start = time.perf_counter()
    run_ea_gym(sc)
    ea_first = time.perf_counter() - start
    ea_times, ea = time_calls(lambda: run_ea_gym(sc), args.repeats)

    # scipy RK45 under test
    atol = RK45_ATOL_FACTOR * sc.state_scale()
    ivp_repeats = min(3, args.repeats)
    ivp_times, ivp = time_calls(lambda: run_scipy(sc, "RK45", RK45_RTOL, atol), ivp_repeats)

    # tight reference (timed once, for information)
    start = time.perf_counter()
    ref = run_scipy(sc, "DOP853", REF_TOL, REF_TOL)
    ref_time = time.perf_counter() - start

    ea_median, ea_best = statistics.median(ea_times), min(ea_times)
    ivp_median, ivp_best = statistics.median(ivp_times), min(ivp_times)
    ratio = ivp_median / ea_median

    def diffs(a: dict[str, Any], b: dict[str, Any]) -> dict[str, float]:
        out = {key: rel_diff(a[key], b[key], ref[key]) for key in ("q", "p")}
        out["power"] = max(rel_diff(a["power"][n], b["power"][n], ref["power"][n]) for n in ref["power"])
        return out

    ea_vs_ivp, ea_vs_ref, ivp_vs_ref = diffs(ea, ivp), diffs(ea, ref), diffs(ivp, ref)
    amplitude = {key: float(np.max(np.abs(ref[key]))) for key in ("q", "p")}
    worst = max(ea_vs_ivp["q"], ea_vs_ivp["p"])

    print(f"{'simulator':<44}{'first (s)':>11}{'best (s)':>11}{'median (s)':>12}{'calls':>7}")
    print(f"{'ea_gym run_model (states+effort/flow/power)':<44}{ea_first:>11.4f}{ea_best:>11.4f}{ea_median:>12.4f}{args.repeats:>7d}")
    print(
        f"{'solve_ivp RK45 rtol=1e-8 + element power':<44}{'':>11}{ivp_best:>11.4f}{ivp_median:>12.4f}{ivp_repeats:>7d}"
        f"   ({ivp['nfev']} RHS evaluations)"
    )
    print(f"{'solve_ivp DOP853 rtol=atol=1e-12 (reference)':<44}{'':>11}{ref_time:>11.4f}{ref_time:>12.4f}{1:>7d}   ({ref['nfev']} RHS evaluations)")
    print(f"speed ratio (solve_ivp RK45 median / ea_gym median): {ratio:.1f}x")
    print()
    print(f"max |difference| / amplitude  (amplitude: q {amplitude['q']:.4g} m, p {amplitude['p']:.4g} kg m/s)")
    print(f"{'pair':<28}{'q':>12}{'p':>12}{'power*':>12}")
    for label, d in (("ea_gym vs RK45", ea_vs_ivp), ("ea_gym vs DOP853 ref", ea_vs_ref), ("RK45 vs DOP853 ref", ivp_vs_ref)):
        print(f"{label:<28}{d['q']:>12.3e}{d['p']:>12.3e}{d['power']:>12.3e}")
    print("  * power: worst element (F, m, k, b), relative to that element's max |power| in the reference")
    print()

    ok_ratio, ok_diff = ratio >= TARGET_RATIO, worst <= TARGET_REL_DIFF
    verdict = "PASS" if (ok_ratio and ok_diff) else "MISS"
    print(
        f"VERDICT: {verdict} - speed ratio {ratio:.1f}x (target >= {TARGET_RATIO:g}x: {'ok' if ok_ratio else 'miss'}), "
        f"max relative difference {worst:.2e} (target <= {TARGET_REL_DIFF:g}: {'ok' if ok_diff else 'miss'})"
    )

    if args.json is not None:
        result = {
            "machine": info,
            "scenario": {
                "duration_s": float(sc.t[-1]),
                "rate_hz": sc.rate,
                "samples": n_samples,
                "k_start_n_per_m": K_START,
                "k_rate_n_per_m_per_s": sc.k_rate,
                "load": {"offset_n": F_OFFSET, "amplitude_n": F_AMPLITUDE, "frequency_hz": F_FREQUENCY},
                "initial_state": [0.0, 0.0],
            },
            "ea_gym": {"first_call_s": ea_first, "best_s": ea_best, "median_s": ea_median, "times_s": ea_times},
            "solve_ivp_rk45": {
                "rtol": RK45_RTOL,
                "atol": atol.tolist(),
                "best_s": ivp_best,
                "median_s": ivp_median,
                "times_s": ivp_times,
                "nfev": ivp["nfev"],
            },
            "reference_dop853": {"rtol": REF_TOL, "atol": REF_TOL, "time_s": ref_time, "nfev": ref["nfev"]},
            "ratio": ratio,
            "amplitude": amplitude,
            "rel_diff": {"ea_gym_vs_rk45": ea_vs_ivp, "ea_gym_vs_reference": ea_vs_ref, "rk45_vs_reference": ivp_vs_ref},
            "targets": {"ratio": TARGET_RATIO, "rel_diff": TARGET_REL_DIFF},
            "verdict": verdict,
        }
        write_json(args.json, result)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
