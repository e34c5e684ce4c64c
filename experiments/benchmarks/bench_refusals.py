"""Refusal time: how long ``ea-gym`` takes, from a fresh process, to refuse each kind of bad input with its one line.

Every case is a new ``ea-gym`` process (the interpreter's start counted, as a user waits for it) on a bad input the
script writes into a temporary directory: a scenario, a model file, a measurement CSV, an agent directory whose
agent.json is wrong. Each prints its median wall time over ``--repeats`` runs (and its CPU time), its exit code (2 for every refusal) and
the refusal's first characters. Refusals should come within 1 s: validation runs before torch, numba and scipy are
imported. The machine's load average is printed with the numbers: on a shared machine it moves them.

How to run (from the repository root; about half a minute)
    python experiments/benchmarks/bench_refusals.py [--repeats 3] [--smoke]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))  # this checkout's experiments.common, installed or not

from experiments.common import parse_with_smoke

SCENARIO = {"system": "spring_mass_damper", "load": {"kind": "constant", "value": 10.0}, "duration": 10.0, "sample_rate": 100.0}
MODEL = {
    "name": "smd", "elements": {"F": {"kind": "Se"}, "v": {"kind": "1"}, "m": {"kind": "I", "value": 10.0},
                                "k": {"kind": "C", "form": "stiffness", "value": 100.0}, "b": {"kind": "R", "value": 0.5}},
    "bonds": [["v", "m"], ["v", "k"], ["v", "b"], ["F", "v"]], "load": {"source": "F", "nominal": 10.0, "bandwidth": 2.0},
}
AGENT = ROOT / "agents" / "data" / "ppo_oracle"


def _file(tmp: Path, name: str, content: object) -> Path:
    (tmp / name).write_text(content if isinstance(content, str) else json.dumps(content))
    return tmp / name


def _agent(tmp: Path, edit: Callable[[dict], object]) -> Path:
    shutil.copytree(AGENT, tmp / "agent")
    data = json.loads((tmp / "agent" / "agent.json").read_text())
    edit(data)
    _file(tmp / "agent", "agent.json", data)
    return tmp / "agent"


def _csv(tmp: Path, content: str) -> list[str]:
    return ["phm", "--system", "spring_mass_damper", "--measurements", str(_file(tmp, "data.csv", content)), "--out", str(tmp / "out")]


#: each case: its name and a function writing its files in a directory and returning ea-gym's arguments
CASES: dict[str, Callable[[Path], list[str]]] = {
    "scenario: duration 1e9": lambda tmp: ["simulate", str(_file(tmp, "s.json", {**SCENARIO, "duration": 1e9})), "--out", str(tmp / "out")],
    "scenario: 24,000 sines": lambda tmp: ["simulate", str(_file(tmp, "s.json", {
        **SCENARIO, "load": {"kind": "sines", "sines": [{"amplitude": 1.0, "frequency": 1.0}] * 24_000}})), "--out", str(tmp / "out")],
    "model file: an element named t": lambda tmp: ["model", str(_file(tmp, "m.json", json.dumps(MODEL).replace('"k"', '"t"')))],
    "model file: 15,000 unbonded junctions": lambda tmp: ["model", str(_file(tmp, "m.json", {
        **MODEL, "elements": {**MODEL["elements"], **{f"j{i}": {"kind": "0"} for i in range(15_000)}}}))],
    "measurements: a cell not a number": lambda tmp: _csv(tmp, "t,F,m,k\n0,10,0,0\n0.01,x,0,0\n"),
    "measurements: 60,000 columns": lambda tmp: _csv(tmp, ",".join(f"c{i}" for i in range(60_000)) + "\n"),
    "measurements: t around 1e12 s": lambda tmp: _csv(tmp, "t,F,m,k\n" + "".join(f"{1e12 + i / 100:.2f},10,0,0\n" for i in range(300))),
    "agent: net_arch [30000, 30000]": lambda tmp: ["benchmark", "--ppo", str(_agent(tmp, lambda d: d["policy"]["kwargs"].update(
        net_arch=[30_000, 30_000]))), "--episodes", "1", "--out", str(tmp / "out")],
    "agent: learning_rate 'fast'": lambda tmp: ["train", "--resume", str(_agent(tmp, lambda d: d["hyperparameters"].update(
        learning_rate="fast"))), "--out", str(tmp / "out")],
    "agent: n_steps 1e8": lambda tmp: ["train", "--resume", str(_agent(tmp, lambda d: d["hyperparameters"].update(
        n_steps=10**8))), "--out", str(tmp / "out")],
}


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def measure(setup: Callable[[Path], list[str]], timeout: float) -> tuple[float, float, int | None, str]:
    """One fresh ``ea-gym`` process on the case's files: (wall time in s, its CPU time in s, exit code, first line of
    stderr); a process still running after ``timeout`` s (an input accepted, or refused only after it allocated) is
    stopped: exit code None. The CPU time moves less with the machine's load than the wall time."""
    with tempfile.TemporaryDirectory() as tmp:
        argv = setup(Path(tmp))
        cpu = _children_cpu()
        start = time.perf_counter()
        try:
            result = subprocess.run([sys.executable, "-m", "ea_gym.cli", *argv], capture_output=True, text=True, timeout=timeout,
                                    env={**os.environ, "PYTHONPATH": str(ROOT)})
        except subprocess.TimeoutExpired:
            return time.perf_counter() - start, math.nan, None, f"still running after {timeout:g} s: stopped"
        wall = time.perf_counter() - start
    return wall, _children_cpu() - cpu, result.returncode, (result.stderr.splitlines() or [""])[0]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="runs per case (the median is printed)")
    parser.add_argument("--timeout", type=float, default=60.0, help="seconds after which a case's process is stopped")
    args = parse_with_smoke(parser, argv, {"repeats": 1})
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    slowest = 0.0
    for name, setup in CASES.items():
        runs = [measure(setup, args.timeout) for _ in range(args.repeats)]
        wall, cpu = statistics.median(run[0] for run in runs), statistics.median(run[1] for run in runs)
        slowest = max(slowest, wall)
        print(f"{name}: {wall:.2f} s ({cpu:.2f} s CPU), exit {runs[0][2]}: {runs[0][3][:110]}")
    print(f"slowest refusal: {slowest:.2f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
