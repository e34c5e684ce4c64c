"""Every script under experiments/ runs end to end with ``--smoke`` (tiny sizes, its outputs in a temporary
folder), so nothing the documentation cites can rot; where it is cheap, what the run wrote is checked too.

A script that needs an optional extra skips where the extra is missing: progpy (compare_progpy.py), torchrl
(torchrl_check.py) and rl-zoo3 (rl_zoo3_check.py), which the ``dev`` extra installs, so CI runs them; Ray RLlib
(rllib_ppo.py, ray_benchmark.py), which pins an older gymnasium: ``bash scripts/test_ray.sh`` runs those two in its
own virtual environment.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENTS = ROOT / "experiments"
sys.path.insert(0, str(ROOT))

from experiments.common import parse_with_smoke  # noqa: E402

#: modules the scripts import, not scripts
HELPERS = {"common.py", "studies/part_tracks.py", "studies/records.py"}
SCRIPTS = sorted(name for name in (path.relative_to(EXPERIMENTS).as_posix() for path in EXPERIMENTS.rglob("*.py")) if name not in HELPERS)
#: the scripts that need an optional extra: the module that tells whether it is installed
EXTRAS = {
    "studies/compare_progpy.py": "progpy",
    "studies/joint_filter.py": "progpy",
    "integrations/torchrl_check.py": "torchrl",
    "integrations/rllib_ppo.py": "ray.rllib",
    "integrations/ray_benchmark.py": "ray.rllib",
    "integrations/rl_zoo3_check.py": "rl_zoo3",
}
#: what a smoke run must leave as it is: the committed results and what the packages ship
KEPT = (EXPERIMENTS / "results", ROOT / "ea_gym" / "data", ROOT / "agents" / "data")


def snapshot() -> dict[Path, int]:
    """Every kept file's modification time (ns)."""
    return {path: path.stat().st_mtime_ns for folder in KEPT for path in folder.rglob("*") if path.is_file()}


def read_json(path: Path) -> dict:
    return json.loads(path.read_text())


def check_train_isolation(out: Path, stdout: str) -> None:
    names = {p.name for p in out.iterdir()}
    assert {"isolation.json", "isolation.md", "fig8_peaks.png", "confusion.png", "accuracy_vs_magnitude.png"} <= names
    assert not any(name.startswith(".") for name in names)  # no temporary files left behind
    report = read_json(out / "isolation.json")
    assert report["shipped"] == []
    assert report["database"]["frames"] == sum(report["database"]["split_frames"].values())
    assert set(report["evaluation"]["variants"]) == {"paper", "strong"}
    assert report["evaluation"]["noise_levels"] == [0.0, 0.05]
    text = (out / "isolation.md").read_text()
    assert "python experiments/build/train_isolation.py --smoke" in text
    assert "STFT" in text and "energy balance" in text


def check_ship_builtins(out: Path, stdout: str) -> None:
    assert (out / "rlc_circuit_strong.safetensors").stat().st_size > 0
    entries = read_json(out / "thresholds.json")["entries"]
    assert [entry["model"] for entry in entries.values()] == ["rlc_circuit"]


def check_estimates_in_env(out: Path, stdout: str) -> None:
    import numpy as np

    result = read_json(out / "results.json")
    assert set(result["faults"]) == {"k", "m", "b"}
    for fault, m in result["faults"].items():
        # linear wear at 1.5 % of the way per s from 0 s: past half-way at the ends of steps 34..66, failure at 67 s
        assert (m["episodes"], m["steps"]) == (1, 33)
        assert 0.0 <= m["coverage"] <= 1.0 and m["median_relative_error"] >= 0.0
        truth = np.array(result["steps"][fault]["rul_true"])
        np.testing.assert_allclose(truth, 1.0 / 0.015 - np.arange(34, 67), atol=1e-3)  # kept to the millisecond
    assert result["pooled"]["steps"] == 99 and -1.0 <= result["pooled"]["spearman"] <= 1.0
    assert (out / "table.md").read_text().count("\n| ") == 5 and (out / "rul.png").stat().st_size > 0


def check_builtin_systems(out: Path, stdout: str) -> None:
    spring = read_json(out / "results.json")["systems"]["spring_mass_damper"]
    assert set(spring["parameters"]) == {"k", "m", "b"}
    for m in spring["parameters"].values():
        # every ramp reaches its safe limit 30 s after onset: far past the detection thresholds
        assert m["runs"] == 2 and m["detected"] == 1.0
        assert 0.0 <= m["isolated"] <= 1.0 and 0.0 <= m["wrong_belief"] <= 1.0 and m["estimate_error"] >= 0.0
    assert spring["fault_free"]["runs"] == 2
    assert "| spring_mass_damper | fault-free |" in (out / "table.md").read_text()


def check_benchmark_policies(out: Path, stdout: str) -> None:
    result = read_json(out / "benchmark.json")
    assert {"ppo", "rul_threshold", "periodic", "run_to_failure", "oracle"} <= set(result["policies"])
    assert all(len(row["costs"]) == 2 for row in result["policies"].values() if "costs" in row)
    assert (out / "benchmark.md").is_file() and (out / "timelines.png").stat().st_size > 0


def check_bench_throughput(out: Path, stdout: str) -> None:
    result = read_json(out / "throughput.json")
    regimes = result["regimes"]
    assert set(regimes) == {"healthy", "alarm", "ppo", "v1"}
    for rows in regimes.values():
        assert set(rows) == {"1", "2"} and {"batched", "sync", "single"} <= set(rows["1"])
        assert all(run["env_steps_per_s"] > 0 for row in rows.values() for run in row.values())
    ratios = result["v1_over_alarm"]  # v1 beside v0 in alarm, the comparison
    rate = {regime: regimes[regime]["2"]["batched"]["env_steps_per_s"] for regime in ("v1", "alarm")}
    assert set(ratios) == {"1", "2"} and ratios["2"] == rate["v1"] / rate["alarm"]


def check_bench_simulation(out: Path, stdout: str) -> None:
    result = read_json(out / "simulation.json")
    assert result["verdict"] in ("PASS", "MISS") and result["scenario"]["duration_s"] == 20.0
    assert result["rel_diff"]["ea_gym_vs_rk45"]["q"] < 1e-3  # the two simulators agree on the same run


def check_env_fingerprint(out: Path, stdout: str) -> None:
    assert re.search(r"^final [0-9a-f]{64}$", stdout, re.M)
    assert [line.split()[:2] for line in stdout.splitlines()[:-1]] == [[mode, kind] for mode in ("phm", "sensors", "oracle")
                                                                       for kind in ("single", "vector")]


def check_cleanrl_ppo(out: Path, stdout: str) -> None:
    report = read_json(out / "cleanrl_ppo.json")
    assert [row["env_steps"] for row in report["updates"]] == [32, 64]
    assert len(report["evaluation"]["ppo_greedy_costs"]) == len(report["evaluation"]["carry_on_costs"]) == 1


def check_env_decision(out: Path, stdout: str) -> None:
    result = read_json(out / "decision.json")
    assert result["seeds"] == {"tuning": [0, 0], "evaluation": [10_000, 10_001]}
    assert {"run_to_failure", "periodic", "rul_threshold", "oracle"} <= set(result["policies"])


def check_from_scratch_diagnosis(out: Path, stdout: str) -> None:
    result = read_json(out / "diagnosis.json")
    assert len(result) == 2 and any(name.startswith("rul_threshold") for name in result)
    for policy in result.values():  # the episodes grouped by their first fault, and all of them
        rows = policy["by_first_fault"]
        assert rows["all"]["episodes"] == sum(row["episodes"] for fault, row in rows.items() if fault != "all") == 2


def check_torchrl(out: Path, stdout: str) -> None:
    result = read_json(out / "torchrl_check.json")
    assert all(mode["rollout_equals_sync_vector_env"] and mode["truncated_lengths_all_equal_horizon"] for mode in result["modes"])


def check_compare_progpy(out: Path, stdout: str) -> None:
    result = read_json(out / "results.json")
    assert result["seeds"] == [0] and list(result["runs"]) == ["mass_m_ramp"]
    (case, rows), = result["real_cases"].items()
    assert case == "off-nominal" and set(rows) == {"ea-gym chain (per-part outputs)", "ProgPy UKF, all three parameters as states"}
    assert all(set(row["error_median"]) == {"k", "m", "b"} and set(row["alpha_lambda"]) == {"k", "b"} for row in rows.values())
    assert "| off-nominal | b | yes |" in (out / "table.md").read_text()


def check_real_machines(out: Path, stdout: str) -> None:
    import importlib.util

    rows = read_json(out / "results.json")["criteria"]
    criteria = [row["criterion"].split(":")[0] for row in rows]
    # every criterion measured on the one system: (a) 4 rows, (b) 4, (c) 4 and the pooled one, (d) a row per misfit
    assert criteria.count("a. 2-3 parts wearing") == 4 and criteria.count("c. 1 % load noise") == 5 and len(rows) == 1 + 4 + 4 + 5 + 3
    assert all(row["verdict"] in ("pass", "miss") for row in rows if "UKF" not in row["criterion"] or importlib.util.find_spec("progpy"))
    # the records agree with ea-gym's simulation; every misfit is said so, nothing named or predicted
    assert all(row["verdict"] == "pass" for row in rows if row["criterion"].startswith(("records", "d. misfit")))
    text = (out / "table.md").read_text()
    assert all(f"| {row['criterion']} | {row['system']} | {row['measured']} |" in text for row in rows)
    assert (out / "estimates.png").stat().st_size > 0


def check_joint_filter(out: Path, stdout: str) -> None:
    result = read_json(out / "results.json")
    summary = result["summary"]["k+b"]
    assert list(result["cases"]) == ["k+b"] and set(summary) == {"joint filter", "ProgPy UKF (all parameters)"}
    assert all(set(row["error_median"]) == {"k", "m", "b"} and row["ms_per_step"] > 0 for row in summary.values())
    assert "| k+b | b | yes |" in (out / "table.md").read_text()


def check_model_fit(out: Path, stdout: str) -> None:
    result = read_json(out / "results.json")
    assert [run["case"] for run in result["runs"]] == ["healthy", "unit", "time_base", "form"]
    assert all(run["passed"] for run in result["runs"])  # the healthy record fits, each misfit is said so
    assert [row["scenario"] for row in result["scenarios"]] == ["mass_m_ramp"] and result["scenarios"][0]["on"]["ok"] is True
    assert (out / "table.md").is_file()


def check_v1_rul(out: Path, stdout: str) -> None:
    result = read_json(out / "results.json")
    assert result["env"] == "ea_gym/SpringMassDamper-v1" and list(result["faults"]) == ["k", "m", "b"]
    # the smoke's faults arrive at once in every part: each is counted past half-way in both episodes
    assert all(m["episodes"] == 2 and m["steps"] > 0 for m in result["faults"].values())
    assert result["pooled"]["steps"] == sum(m["steps"] for m in result["faults"].values())
    assert "| pooled |" in (out / "table.md").read_text() and (out / "rul.png").is_file()


def check_rllib_ppo(out: Path, stdout: str) -> None:
    runs = read_json(out / "summary.json")["runs"]
    assert set(runs) == {"vector_entry_point", "sync"} and all(run["episodes"]["episodes_other_length"] == 0 for run in runs.values())


def check_ray_benchmark(out: Path, stdout: str) -> None:
    assert read_json(out / "summary.json")["all_equal_local"]


def load_script(script: str):
    """An experiments script as a module (its functions; ``main`` is not run)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(Path(script).stem, EXPERIMENTS / script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def check_rl_zoo3(out: Path, stdout: str) -> None:
    summary = read_json(out / "summary.json")
    assert summary["train"]["last_table"] and "Loading running average" in summary["enjoy"]["output"]  # the smoke ends no episode
    assert (out / "summary.md").read_text() == load_script("integrations/rl_zoo3_check.py").render(summary)


def test_the_figures_the_docs_show_are_the_committed_outputs_of_their_scripts():
    """docs/results.md includes rl-zoo3's summary.md and CleanRL's JSON as their scripts wrote them: summary.md is
    the rendering of the committed summary.json (figures such as fps come from the run, none typed by hand), and
    CleanRL's mean costs are the means of its episodes' costs, with the command of its script."""
    results = EXPERIMENTS / "results"
    page = (ROOT / "docs" / "results.md").read_text()
    assert "{include} ../experiments/results/rl_zoo3/summary.md" in page
    assert "{literalinclude} ../experiments/results/cleanrl_ppo/cleanrl_ppo.json" in page
    zoo = read_json(results / "rl_zoo3" / "summary.json")
    assert (results / "rl_zoo3" / "summary.md").read_text() == load_script("integrations/rl_zoo3_check.py").render(zoo)
    assert dict(zoo["train"]["last_table"])["fps"] in (results / "rl_zoo3" / "summary.md").read_text()
    cleanrl = read_json(results / "cleanrl_ppo" / "cleanrl_ppo.json")
    assert cleanrl["command"] == "python experiments/integrations/cleanrl_ppo.py"  # the default run, as committed
    evaluation = cleanrl["evaluation"]
    for policy in ("ppo_greedy", "carry_on"):
        costs = evaluation[f"{policy}_costs"]
        assert evaluation[f"{policy}_mean_cost"] == sum(costs) / len(costs)


def printed(*texts: str) -> Callable[[Path, str], None]:
    """A check that the run printed ``texts``."""

    def check(out: Path, stdout: str) -> None:
        assert all(text in stdout for text in texts), stdout[-2000:]

    return check


#: per script: the arguments beside --smoke (OUT: a fresh folder) and the check of what the run wrote or printed
RUNS: dict[str, tuple[tuple[str, ...], Callable[[Path, str], None]]] = {
    "benchmarks/bench_against.py": ((), printed("this checkout again: median", "wall: ")),
    "benchmarks/bench_refusals.py": ((), printed("measurements: 60,000 columns: ", "exit 2: ea-gym phm: error: ", "slowest refusal: ")),
    "benchmarks/bench_simulation.py": (("--json", "OUT/simulation.json"), check_bench_simulation),
    "benchmarks/bench_startup.py": ((), printed("default, cold", "default, warm")),
    "benchmarks/bench_throughput.py": (("--json", "OUT/throughput.json"), check_bench_throughput),
    "benchmarks/benchmark_policies.py": (("--out", "OUT"), check_benchmark_policies),
    "benchmarks/env_fingerprint.py": ((), check_env_fingerprint),
    "build/ship_builtins.py": (("--out", "OUT"), check_ship_builtins),
    "build/train_isolation.py": (("--out", "OUT"), check_train_isolation),
    "integrations/cleanrl_ppo.py": (("--out", "OUT"), check_cleanrl_ppo),
    "integrations/ray_benchmark.py": (("--out", "OUT"), check_ray_benchmark),
    "integrations/rllib_ppo.py": (("--out", "OUT"), check_rllib_ppo),
    "integrations/rl_zoo3_check.py": (("--out", "OUT"), check_rl_zoo3),
    "integrations/torchrl_check.py": (("--out", "OUT"), check_torchrl),
    "studies/builtin_systems.py": (("--out", "OUT"), check_builtin_systems),
    "studies/compare_progpy.py": (("--out", "OUT"), check_compare_progpy),
    "studies/env_decision.py": (("--out", "OUT"), check_env_decision),
    "studies/estimates_in_env.py": (("--out", "OUT"), check_estimates_in_env),
    "studies/from_scratch_diagnosis.py": (("--out", "OUT/diagnosis.json"), check_from_scratch_diagnosis),
    "studies/joint_filter.py": (("--out", "OUT"), check_joint_filter),
    "studies/model_fit.py": (("--out", "OUT"), check_model_fit),
    "studies/real_machines.py": (("--out", "OUT"), check_real_machines),
    "studies/tracking_accuracy.py": ((), printed("N =   1 systems", "N =   4 systems")),
    "studies/v1_rul.py": (("--out", "OUT"), check_v1_rul),
}


def test_every_script_is_named_here():
    """A new script is smoke-run with a check of its own (helper modules are listed in HELPERS)."""
    assert set(SCRIPTS) == set(RUNS)


@pytest.mark.parametrize("script", SCRIPTS)
def test_smoke_run(script: str, tmp_path: Path) -> None:
    if script in EXTRAS:
        pytest.importorskip(EXTRAS[script], reason=f"{script} needs {EXTRAS[script]} (an optional extra)")
    source = (EXPERIMENTS / script).read_text()
    assert "parse_with_smoke(" in source, f"{script} has no --smoke (experiments.common.parse_with_smoke)"
    out = tmp_path / "out"
    out.mkdir()
    arguments, check = RUNS[script]
    kept = snapshot()
    done = subprocess.run([sys.executable, str(EXPERIMENTS / script), "--smoke", *(a.replace("OUT", str(out)) for a in arguments)],
                          cwd=ROOT, capture_output=True, text=True, env={**os.environ, "MPLBACKEND": "Agg"}, timeout=900)
    assert done.returncode == 0, f"{script} --smoke exited with {done.returncode}:\n{done.stderr[-4000:]}"
    assert snapshot() == kept, "a smoke run wrote over the committed results or the shipped data"
    check(out, done.stdout)


def test_smoke_sizes_replace_the_defaults_but_not_the_options_given():
    def parser() -> argparse.ArgumentParser:
        made = argparse.ArgumentParser()
        made.add_argument("--episodes", type=int, default=100)
        made.add_argument("--seed", type=int, default=0)
        made.add_argument("--out", type=Path, default=EXPERIMENTS / "results" / "somewhere")
        return made

    smoke = {"episodes": 2, "seed": 5}
    assert vars(parse_with_smoke(parser(), [], smoke)) == {"episodes": 100, "seed": 0, "out": EXPERIMENTS / "results" / "somewhere", "smoke": False}
    args = parse_with_smoke(parser(), ["--smoke", "--seed", "3"], smoke)
    assert (args.episodes, args.seed, args.smoke) == (2, 3, True)
    # the committed results are never the smoke run's folder: a fresh temporary one is
    assert args.out.is_dir() and not any(args.out.iterdir()) and EXPERIMENTS not in args.out.parents
    args.out.rmdir()
    assert parse_with_smoke(parser(), ["--smoke", "--out", "elsewhere"], smoke).out == Path("elsewhere")
