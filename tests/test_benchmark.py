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
    """2 episodes of 100 steps, tuned on 1 episode with small grids, no PPO (about 10 s); the tuned settings written."""
    out = tmp_path_factory.mktemp("benchmark")
    result = run_benchmark(2, 0, out, None, tune_episodes=1, progress=False, tune=True, grids=GRIDS, env_kwargs={"horizon": 100},
                           ppo_policies={"ppo_sensors": out / "no_such_agent"}, write_tuned_to=out / "tuned" / "rules.json")
    return out, result


@pytest.fixture(scope="module")
def from_file(tiny, tmp_path_factory):
    """The same benchmark, the tuned settings read from the file the tuning wrote."""
    out = tmp_path_factory.mktemp("from_file")
    return out, run_benchmark(2, 0, out, None, progress=False, tuned_file=tiny[0] / "tuned" / "rules.json", env_kwargs={"horizon": 100})


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
    listed = next(line for line in text.splitlines() if line.startswith("Policies evaluated (2 episodes each): "))
    assert [part.split("**")[1] for part in listed.split("; ")] == list(result["policies"]) == list(RULES)


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


def test_the_benchmark_command_moves_its_outputs_in_together_and_records_the_final_path(tiny, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    tuned = tiny[0] / "tuned" / "rules.json"
    argv = ["benchmark", "--episodes", "1", "--no-ppo", "--tuned", str(tuned), "--allow-stale", "--env", "horizon=20", "--no-progress"]
    assert main([*argv, "--out", "results/run"]) == 0, capsys.readouterr().err
    assert [path.name for path in (tmp_path / "results").iterdir()] == ["run"]  # no staging directory left beside it
    assert sorted(path.name for path in (tmp_path / "results" / "run").iterdir()) == [
        "benchmark.json", "benchmark.md", "cost_distribution.png", "timelines.json", "timelines.png"]
    result = json.loads((tmp_path / "results" / "run" / "benchmark.json").read_text())
    assert " --out results/run " in result["commands"]["reproduce"]
    assert "results/.run." not in (tmp_path / "results" / "run" / "benchmark.md").read_text()


def test_a_failed_benchmark_writes_nothing(tmp_path, monkeypatch):
    """The tuning and evaluation done, the second figure fails: neither the outputs, nor the directories above them, nor
    the tuned settings appear."""

    def fail(*args, **kwargs):
        raise RuntimeError("the figure failed")

    monkeypatch.setattr(benchmark_run, "plot_timelines", fail)  # after cost_distribution.png was written
    with pytest.raises(RuntimeError, match="the figure failed"):
        run_benchmark(1, 0, tmp_path / "new" / "out", None, tune_episodes=1, progress=False, tune=True, grids=GRIDS,
                      env_kwargs={"horizon": 20}, write_tuned_to=tmp_path / "tuned.json")
    assert not any(tmp_path.iterdir())


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
        run_benchmark(2, 0, tmp_path, None, grids={"ppo": [1]}, progress=False, tune=True)
    with pytest.raises(ValueError, match="grids applies to tuning only"):
        run_benchmark(2, 0, tmp_path, None, grids={"periodic": [1]}, progress=False)
    with pytest.raises(ValueError, match="obs_mode"):
        run_benchmark(2, 0, tmp_path, None, env_kwargs={"obs_mode": "phm"}, progress=False)
    with pytest.raises(ValueError, match="taken"):
        run_benchmark(2, 0, tmp_path, None, ppo_policies={"oracle": tmp_path}, progress=False)
    assert not any(tmp_path.iterdir())


def test_cli_benchmark_passes_its_arguments(tmp_path, monkeypatch, capsys):
    import inspect

    calls = []
    # the command line's defaults are the library's
    defaults = {name: p.default for name, p in inspect.signature(benchmark_run.run_benchmark).parameters.items()}

    def fake(episodes, seed, out, ppo, tune_episodes=10, progress=True, trust_pickle=False, env_kwargs=None, **options):
        calls.append(((episodes, seed, out, ppo, tune_episodes, progress), {**options, "trust_pickle": trust_pickle, "env_kwargs": env_kwargs}))
        return {"policies": {"oracle": {"mean_cost": 1.0}}, "ranking": ["oracle"], "skipped": {"ppo": "none"}}

    monkeypatch.setattr(benchmark_run, "run_benchmark", fake)
    assert main(["benchmark", "--episodes", "4", "--seed", "2", "--out", str(tmp_path), "--ppo", str(tmp_path / "agent"),
                 "--tune", "--tune-episodes", "3", "--write-tuned", str(tmp_path / "t.json"), "--no-progress",
                 "--system", "rlc_circuit", "--env", "horizon=60"]) == 0
    assert calls[-1] == ((4, 2, tmp_path, tmp_path / "agent", 3, False),
                         {"tune": True, "tuned_file": None, "write_tuned_to": tmp_path / "t.json", "allow_stale": False, "ray": None,
                          "trust_pickle": False, "env_kwargs": {"horizon": 60, "system": "rlc_circuit"}})
    assert main(["benchmark", "--out", str(tmp_path), "--no-ppo", "--trust-pickle"]) == 0
    assert calls[-1][1]["trust_pickle"] is True and calls[-1][1]["env_kwargs"] == {}
    assert main(["benchmark", "--out", str(tmp_path), "--no-ppo", "--tuned", str(tmp_path / "t.json"), "--allow-stale"]) == 0
    assert calls[-1] == ((100, 0, tmp_path, None, None, True),
                         {"tune": False, "tuned_file": tmp_path / "t.json", "write_tuned_to": None, "allow_stale": True, "ray": None,
                          "trust_pickle": False, "env_kwargs": {}})
    # --ray alone: a local Ray; --ray ADDRESS: that cluster
    assert main(["benchmark", "--out", str(tmp_path), "--no-ppo", "--ray"]) == 0 and calls[-1][1]["ray"] == "local"
    assert main(["benchmark", "--out", str(tmp_path), "--no-ppo", "--ray", "10.0.0.1:6379"]) == 0 and calls[-1][1]["ray"] == "10.0.0.1:6379"
    assert main(["benchmark", "--out", str(tmp_path), "--no-ppo"]) == 0
    assert calls[-1][0][4] == defaults["tune_episodes"]
    assert {k: calls[-1][1][k] for k in ("tune", "tuned_file", "write_tuned_to", "allow_stale", "ray")} == {
        k: defaults[k] for k in ("tune", "tuned_file", "write_tuned_to", "allow_stale", "ray")}
    assert "oracle 1" in capsys.readouterr().out
    for clash in (["--ppo", "x"], ["--tune", "--tuned", "x"]):
        with pytest.raises(SystemExit):
            main(["benchmark", "--out", str(tmp_path), "--no-ppo", *clash])


@pytest.mark.parametrize("words, field", [
    (["--tune-episodes", "3"], "--tune-episodes"), (["--write-tuned", "t.json"], "--write-tuned"),
    (["--tuned", "no_such_file.json"], "--tuned"),
])
def test_cli_benchmark_refuses_tuning_options_without_tune_in_one_line(tmp_path, capsys, words, field):
    assert main(["benchmark", "--out", str(tmp_path / "out"), "--no-ppo", "--no-progress", *words]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and field in error and "Traceback" not in error
    assert not (tmp_path / "out").exists()


def test_cli_benchmark_help_names_every_policy_evaluated(capsys):
    from agents.benchmark.evaluation import EVALUATION_ORDER

    with pytest.raises(SystemExit):
        main(["benchmark", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    episodes = text[text.rindex("--episodes N"):]  # the option, not the usage line
    episodes = episodes[: episodes.index("--seed")]
    for name in EVALUATION_ORDER:
        assert name in episodes, name
        assert f"{name} (" in text, name


def test_cli_default_ppo_is_the_packaged_agent_when_present():
    import agents
    from agents.cli import default_agent

    expected = Path(agents.__file__).parent / "data" / "ppo_phm"
    assert default_agent() == (expected if expected.is_dir() else None)


def test_tuned_settings_read_from_the_file_give_the_tuned_run_again(tiny, from_file):
    (out, tuned_run), (_, read_run) = tiny, from_file
    written = json.loads((out / "tuned" / "rules.json").read_text())
    assert written["command"] == tuned_run["commands"]["reproduce"] and "--tune --tune-episodes 1" in written["command"]
    assert written["tuning_seeds"] == [0, 0] and written["tables"] == tuned_run["tuning"]
    assert {name: (rule["value"], rule["action"]) for name, rule in written["rules"].items()} == {
        name: (tuned_run["policies"][name]["parameter"], tuned_run["policies"][name]["action"]) for name in GRIDS}
    assert written["environment"]["config"]["horizon"] == 100 and written["environment"]["config"]["phm"]["estimator_kind"]
    for name in RULES:
        assert read_run["policies"][name]["per_episode"] == tuned_run["policies"][name]["per_episode"], name
    assert read_run["tuning"] == tuned_run["tuning"] and read_run["seeds"]["tuning"] == [0, 0]
    assert tuned_run["tuned_settings"]["tuned"] == "in this run" and read_run["tuned_settings"]["tuned"] == "read from the file"
    assert read_run["tuned_settings"]["stale"] is False
    assert read_run["tuned_settings"]["fingerprint"] == read_run["tuned_settings"]["current_fingerprint"] == written["fingerprint"]
    assert "tuned in this run on seeds 0..0" in (out / "benchmark.md").read_text()
    text = (from_file[0] / "benchmark.md").read_text()
    assert "read from" in text and "rules.json" in text and "the same as this environment's" in text


def test_a_stale_tuned_file_is_refused_before_any_work_and_named(tiny, tmp_path):
    from agents.benchmark.tuned import StaleTuning

    with pytest.raises(StaleTuning, match=r"config\.horizon: 100 in the file, 120 now.*--tune"):
        run_benchmark(2, 0, tmp_path / "out", None, progress=False, tuned_file=tiny[0] / "tuned" / "rules.json", env_kwargs={"horizon": 120})
    assert not (tmp_path / "out").exists()


def test_read_tuned_flags_stale_files_and_refuses_broken_ones(tiny, tmp_path):
    from agents.benchmark.report import markdown
    from agents.benchmark.tuned import fingerprint, read_tuned

    path = tiny[0] / "tuned" / "rules.json"
    data = json.loads(path.read_text())
    settings = data["environment"]
    assert fingerprint(settings) == data["fingerprint"]
    changed = {**settings, "config": {**settings["config"], "phm": {**settings["config"]["phm"], "estimator_kind": "ea_inversion"}}}
    assert fingerprint(changed) != data["fingerprint"]
    assert read_tuned(path, settings)[1] is False
    with pytest.raises(ValueError, match="config.phm.estimator_kind"):
        read_tuned(path, changed)
    tuned, stale = read_tuned(path, changed, allow_stale=True)
    assert stale and tuned.rules["periodic"] == (60, None)
    result = {**tiny[1], "tuned_settings": {**tiny[1]["tuned_settings"], "tuned": "read from the file", "file": "x.json", "stale": True,
                                             "current_fingerprint": fingerprint(changed)}}
    assert f"STALE: this environment's is {fingerprint(changed)[:12]}" in markdown(result)
    broken = tmp_path / "broken.json"
    for content, message in (("{", "not JSON"), ("{}", "not a tuned-rules file"), (json.dumps({**data, "rules": {}}), None)):
        broken.write_text(content)
        if message is None:  # parses, but lacks the rules: refused when the benchmark reads it
            with pytest.raises(ValueError, match="no tuned setting for corrective_band"):
                run_benchmark(2, 0, tmp_path / "out", None, progress=False, tuned_file=broken, env_kwargs={"horizon": 100})
        else:
            with pytest.raises(ValueError, match=message):
                read_tuned(broken, settings)
    assert not (tmp_path / "out").exists()


def test_the_committed_tuned_settings_cover_every_rule_and_hash_to_their_fingerprint():
    from agents.benchmark.settings import DEFAULT_GRIDS
    from agents.benchmark.tuned import TUNED_RULES_FILE, TunedRules, fingerprint

    tuned = TunedRules.from_json(json.loads(TUNED_RULES_FILE.read_text()), str(TUNED_RULES_FILE))
    assert set(tuned.rules) == set(DEFAULT_GRIDS) and fingerprint(tuned.settings) == tuned.fingerprint
    assert "--tune" in tuned.command and len(tuned.tuning_seeds) == 300
    for name, (value, action) in tuned.rules.items():
        table = tuned.tables[name]["table"]
        best = min(table, key=lambda r: r["mean_cost"])
        assert (best["parameter"], best.get("action")) == (value, action), name
        assert [r["parameter"] for r in table if r.get("action") in (None, table[0].get("action"))] == tuned.tables[name]["grid"]


def test_policies_side_by_side_meet_the_episodes_they_meet_alone():
    """Blocks of one vector env, seeds split in chunks (max_envs 4 < 5 seeds): records equal to each policy alone."""
    import numpy as np

    from agents.benchmark.batches import evaluate_side_by_side
    from agents.benchmark.settings import env_factory, vector_env_factory
    from agents.evaluation import evaluate
    from agents.policies import ActionMap, Oracle, Periodic

    actions = ActionMap.from_env(env_factory("oracle", horizon=60)())
    make = vector_env_factory("oracle", horizon=60)
    seeds = range(100_000, 100_005)
    for max_envs in (4, 15):
        policies = {"periodic": Periodic(actions, 20.0), "oracle": Oracle(actions, 30.0), "late": Periodic(actions, 45.0)}
        together = evaluate_side_by_side(policies, make, seeds, False, max_envs)
        for name, policy in policies.items():
            alone = evaluate(policy, make, seeds, False, batch_size=5)
            assert list(together[name].seeds) == list(seeds)
            for key, values in alone.per_episode.items():
                np.testing.assert_array_equal(together[name].per_episode[key], values, err_msg=f"{name} {key} max_envs={max_envs}")
        assert together["periodic"].per_episode["replacements"].sum() > together["late"].per_episode["replacements"].sum()


def test_the_default_tuned_file_is_read_and_a_shorter_horizon_is_refused_as_stale(tmp_path):
    from agents.benchmark.tuned import StaleTuning

    with pytest.raises(StaleTuning, match=r"tuned_rules\.json was tuned on environment .*config\.horizon: 500 in the file, 100 now"):
        run_benchmark(2, 0, tmp_path / "out", None, progress=False, env_kwargs={"horizon": 100})
    assert not (tmp_path / "out").exists()
