"""The policy benchmark (agents.benchmark): well-formed outputs on a tiny run, seeds, the CLI."""

import json
from pathlib import Path

import pytest

from agents.benchmark import run as benchmark_run
from agents.benchmark.run import run_benchmark
from agents.benchmark.settings import evaluation_seeds, tuning_seeds
from ea_gym.cli import main

PNG = b"\x89PNG\r\n\x1a\n"
GRIDS = {"oracle": [5, 20], "rul_threshold": [5], "corrective_band": [{"k": 0.8, "m": 0.8, "b": 0.4}], "periodic": [60]}
REQUIRED = ("mean_cost", "ci95", "failures", "availability", "maintenance_actions", "cost_ratio_to_oracle", "obs_mode")
RULES = ("oracle", "rul_threshold", "corrective_band", "periodic", "run_to_failure")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """2 episodes of 100 steps, 1 tuning episode, small grids, no PPO (about 15 s)."""
    out = tmp_path_factory.mktemp("benchmark")
    result = run_benchmark(2, 0, out, None, tune_episodes=1, progress=False, grids=GRIDS, env_kwargs={"horizon": 100},
                           ppo_policies={"ppo_sensors": out / "no_such_agent"})
    return out, result


def test_benchmark_json_has_every_policy_with_the_required_keys(tiny):
    out, result = tiny
    data = json.loads((out / "benchmark.json").read_text())
    assert data == result
    assert set(data["policies"]) == set(RULES)
    oracle = data["policies"]["oracle"]["mean_cost"]
    assert oracle > 0  # on these seeds the oracle replaces once; a zero oracle cost gives ratios of None
    for name, row in data["policies"].items():
        for key in REQUIRED:
            assert key in row, (name, key)
        low, high = row["ci95"]
        assert low <= row["mean_cost"] <= high
        assert row["cost_ratio_to_oracle"] == pytest.approx(row["mean_cost"] / oracle)
        assert 0.0 <= row["availability"] <= 1.0 and row["failures"] >= 0 and row["maintenance_actions"] >= 0
        assert row["episodes"] == 2 and row["seeds"] == [100_000, 100_001]
        assert len(row["per_episode"]["cost"]) == 2
    assert {n: data["policies"][n]["obs_mode"] for n in RULES} == {
        "oracle": "oracle", "rul_threshold": "phm", "corrective_band": "phm", "periodic": "sensors", "run_to_failure": "sensors"}
    assert data["policies"]["oracle"]["parameter"] in GRIDS["oracle"]
    assert data["policies"]["rul_threshold"]["parameter"] == 5 and data["policies"]["periodic"]["parameter"] == 60
    assert data["policies"]["corrective_band"]["parameter"] == {"k": 0.8, "m": 0.8, "b": 0.4}
    # the oracle and RulThreshold are tuned over both actions: every (action, threshold) pair has its row
    for name in ("oracle", "rul_threshold"):
        tuning = data["tuning"][name]
        assert [(r["action"], r["parameter"]) for r in tuning["table"]] == [(a, v) for a in ("replace", "corrective") for v in GRIDS[name]]
        best = min(tuning["table"], key=lambda r: r["mean_cost"])  # the first of equal costs, as the tuning picks
        assert (tuning["action"], tuning["best"]) == (best["action"], best["parameter"])
        assert data["policies"][name]["action"] == tuning["action"]
    assert data["policies"]["run_to_failure"]["parameter"] is None
    costs = [data["policies"][n]["mean_cost"] for n in data["ranking"]]
    assert costs == sorted(costs) and sorted(data["ranking"]) == sorted(RULES)
    assert [data["policies"][n]["rank"] for n in data["ranking"]] == [1, 2, 3, 4, 5]
    assert data["seeds"]["evaluation"] == [100_000, 100_001] and data["seeds"]["tuning"] == [0, 0]
    assert data["environment"]["horizon"] == 100


def test_missing_ppo_is_skipped_with_a_note(tiny):
    out, result = tiny
    assert "ppo" not in result["policies"] and "ppo_sensors" not in result["policies"]
    assert "no PPO directory given" in result["skipped"]["ppo"]
    assert "no_such_agent" in result["skipped"]["ppo_sensors"]
    text = (out / "benchmark.md").read_text()
    assert "Skipped" in text and "no PPO directory given" in text


def test_markdown_has_the_table_sorted_by_cost_and_the_command(tiny):
    out, result = tiny
    text = (out / "benchmark.md").read_text()
    assert "| rank | policy | obs_mode | tuned parameter | cost [95 % CI] | ×oracle |" in text
    table = [line for line in text.splitlines() if line.startswith("| ") and line.split("|")[1].strip().isdigit()]
    assert [line.split("**")[1] for line in table[:5]] == result["ranking"]
    assert result["commands"]["reproduce"] in text
    assert result["commands"]["reproduce"].startswith("ea-gym benchmark --episodes 2 --seed 0 ")
    assert "--no-ppo" in result["commands"]["reproduce"] and "env_kwargs" in result["commands"]["note"]
    assert "threshold = 5 s" in text and "period = 60 s" in text and "band = k 0.8, m 0.8, b 0.4" in text


def test_figures_are_pngs_and_the_timelines_share_one_seed(tiny):
    out, result = tiny
    for name in ("cost_distribution.png", "timelines.png"):
        assert (out / name).read_bytes()[:8] == PNG
    timelines = json.loads((out / "timelines.json").read_text())
    assert set(timelines) == set(RULES)
    assert {tl["seed"] for tl in timelines.values()} == {result["seeds"]["timeline"]} == {100_000}
    for name, tl in timelines.items():
        assert len(tl["t"]) == len(tl["true_position"]) == len(tl["estimated_position"]) == len(tl["rul"]) == 101
        # the timeline is one of the evaluation episodes: its cost is that episode's
        assert tl["cost"] == pytest.approx(result["policies"][name]["per_episode"]["cost"][0])
    assert timelines["run_to_failure"]["actions"] == []


def test_evaluation_seeds_never_meet_training_validation_or_tuning_seeds():
    from agents.conventions import TRAINING_SEED, VALIDATION_SEED

    tuning = set(tuning_seeds(1000))
    for seed in (0, 1, 7):
        seeds = evaluation_seeds(seed, 10_000)
        assert seeds.start >= 100_000 > VALIDATION_SEED > TRAINING_SEED and not tuning & set(seeds)
    assert set(evaluation_seeds(0, 10_000)).isdisjoint(evaluation_seeds(1, 10_000))
    assert max(tuning) < TRAINING_SEED
    for bad in ((-1, 5), (0, 0), (0, 10_001)):
        with pytest.raises(ValueError):
            evaluation_seeds(*bad)
    with pytest.raises(ValueError, match="tune_episodes"):
        tuning_seeds(0)


def test_bad_arguments_are_refused_before_any_work(tmp_path):
    with pytest.raises(ValueError, match="unknown policies"):
        run_benchmark(2, 0, tmp_path, None, grids={"ppo": [1]}, progress=False)
    with pytest.raises(ValueError, match="obs_mode"):
        run_benchmark(2, 0, tmp_path, None, env_kwargs={"obs_mode": "phm"}, progress=False)
    with pytest.raises(ValueError, match="taken"):
        run_benchmark(2, 0, tmp_path, None, ppo_policies={"oracle": tmp_path}, progress=False)
    assert not any(tmp_path.iterdir())


def test_cli_benchmark_passes_its_arguments(tmp_path, monkeypatch, capsys):
    import inspect

    calls = []
    # the command line's default is the library's
    library_default = inspect.signature(benchmark_run.run_benchmark).parameters["tune_episodes"].default

    def fake(episodes, seed, out, ppo, tune_episodes=10, progress=True, trust_pickle=False, env_kwargs=None):
        calls.append((episodes, seed, out, ppo, tune_episodes, progress, trust_pickle, env_kwargs))
        return {"policies": {"oracle": {"mean_cost": 1.0}}, "ranking": ["oracle"], "skipped": {"ppo": "none"}}

    monkeypatch.setattr(benchmark_run, "run_benchmark", fake)
    assert main(["benchmark", "--episodes", "4", "--seed", "2", "--out", str(tmp_path), "--ppo", str(tmp_path / "agent"),
                 "--tune-episodes", "3", "--no-progress", "--system", "rlc_circuit", "--env", "horizon=60"]) == 0
    assert calls[-1] == (4, 2, tmp_path, tmp_path / "agent", 3, False, False, {"horizon": 60, "system": "rlc_circuit"})
    assert main(["benchmark", "--out", str(tmp_path), "--no-ppo", "--trust-pickle"]) == 0
    assert calls[-1][6] is True and calls[-1][7] == {}
    assert calls[-1][:5] == (100, 0, tmp_path, None, library_default)
    assert "oracle 1" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(["benchmark", "--out", str(tmp_path), "--no-ppo", "--ppo", "x"])


def test_cli_default_ppo_is_the_packaged_agent_when_present():
    import agents
    from agents.cli import default_agent

    expected = Path(agents.__file__).parent / "data" / "ppo_phm"
    assert default_agent() == (expected if expected.is_dir() else None)
