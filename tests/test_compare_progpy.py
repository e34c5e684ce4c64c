"""experiments/studies/compare_progpy.py: its metric helpers on hand-computed cases, and ProgPy's UKF on a noise-free run (when installed)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments" / "studies"))

import compare_progpy as compare  # noqa: E402

from ea_gym import load_scenario  # noqa: E402


def test_fault_window_is_the_onset_and_the_safe_limit_crossing():
    onset, eol = compare.fault_window(load_scenario(compare.SCENARIOS / "spring_k_ramp.json"))
    assert onset == 10.0
    assert eol == pytest.approx(10.0 + 15.0 / 18.0 * 110.0)  # k: 100 -> 82 over 10..120 s, limit 85 N/m
    onset, eol = compare.fault_window(load_scenario(compare.SCENARIOS / "mass_m_ramp.json"))
    assert (onset, eol) == (5.0, pytest.approx(5.0 + 85.0 / 1.6))  # m: 10 -> 11.6 over 5..90 s, limit 11 kg


def test_prediction_span_alpha_and_coverage_on_a_hand_case():
    t = np.arange(0.0, 101.0)
    mask = compare.prediction_mask(t, onset=10.0, eol=110.0)  # 50 .. 90 % of the way: 60 .. 100 s
    assert t[mask][0] == 60.0 and t[mask][-1] == 100.0 and mask.sum() == 41
    rul_true = np.array([10.0, 10.0, 10.0, 10.0])
    hits = compare.alpha_hits(np.array([8.0, 12.0, 12.5, np.inf]), rul_true)  # +-20 %: bounds inclusive, inf misses
    assert hits.tolist() == [True, True, False, False]
    covers, bounded = compare.interval_hits(np.array([9.0, 0.0, 11.0]), np.array([11.0, np.inf, np.inf]), np.array([10.0, 10.0, 10.0]))
    assert covers.tolist() == [True, True, False] and bounded.tolist() == [True, False, False]


def test_drift_rul_is_fieller_interval_of_the_linear_drift():
    limits = (85.0, 105.0)
    # no uncertainty: the crossing time itself, to the lower limit the drift heads for
    assert compare.drift_rul(100.0, -0.1, np.zeros((2, 2)), limits) == pytest.approx((150.0, 150.0, 150.0))
    covariance = np.array([[0.04, -0.001], [-0.001, 1e-4]])
    point, low, high = compare.drift_rul(100.0, -0.1, covariance, limits)
    tau = np.linspace(0.0, 400.0, 400001)
    mean = 100.0 - 0.1 * tau - 85.0
    sd = np.sqrt(covariance[0, 0] + 2 * tau * covariance[0, 1] + tau**2 * covariance[1, 1])
    inside = tau[np.abs(mean) <= compare.Z95 * sd]
    assert point == pytest.approx(150.0)
    assert low == pytest.approx(inside[0], abs=2e-3) and high == pytest.approx(inside[-1], abs=2e-3)
    # an unresolved drift: the limit is within reach for ever
    assert compare.drift_rul(100.0, -0.1, np.array([[0.04, 0.0], [0.0, 0.01]]), limits)[2] == np.inf


def test_the_script_refuses_without_progpy(monkeypatch, capsys):
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "progpy" else importlib.machinery.PathFinder.find_spec(name))
    assert compare.main(["--smoke", "--out", "unused"]) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_ukf_recovers_a_constant_parameter_from_noise_free_signals():
    pytest.importorskip("progpy")
    scenario = load_scenario({
        "system": "spring_mass_damper",
        "load": {"kind": "sines", "offset": 10.0, "sines": [{"amplitude": 4.0, "frequency": 0.25}, {"amplitude": 1.0, "frequency": 1.4}]},
        "duration": 8.0,
        "fault": {"parameter": "k", "profile": [[0, 96.0]]},
    })
    signals = compare.record_signals(scenario, np.random.default_rng(0))
    record = compare.run_ukf(scenario.model, signals, 0.0, ("k",), compare.FilterSettings())
    assert record.mean[-1, record.states.index("k")] == pytest.approx(96.0, rel=1e-3)
    track = compare.filter_track(record, scenario.model, "k")
    assert track.estimate[-1] == record.mean[-1, 2] and track.rul.shape == (8, 3)


def exact_track(scenario) -> compare.Track:
    """A track that knows the truth: the true parameter, the true RUL with a 1 s wide interval around it."""
    onset, eol = compare.fault_window(scenario)
    t = np.arange(1.0, scenario.duration)
    rul = np.maximum(eol - t, 0.0)
    return compare.Track(t, scenario.fault.profile.value(t), t, (scenario.fault.parameter,) * len(t), np.stack([rul, rul - 0.5, rul + 0.5], axis=1))


def test_a_track_survives_its_json_with_missing_estimates_and_unbounded_intervals():
    from ea_gym.files import json_ready

    rul = np.array([[np.inf, 0.0, np.inf], [4.0, 3.0, 5.0]])
    track = compare.Track(np.array([1.0, 2.0]), np.array([np.nan, 3.0]), np.array([0.5, 1.5]), ("", "k"), rul)
    back = compare.read_track(json_ready(compare.track_data(track)))
    for name in ("t", "estimate", "estimate_time", "rul"):
        np.testing.assert_array_equal(getattr(back, name), getattr(track, name))
    assert back.isolated == track.isolated


def test_ukf_from_reuses_an_earlier_runs_ukf_rows_and_runs_the_chain(tmp_path, capsys):
    import json

    from ea_gym.files import json_ready, write_json

    scenario = compare.with_seed(load_scenario(compare.SCENARIOS / "mass_m_ramp.json"), 0)
    runs = {compare.UKF: [compare.track_data(exact_track(scenario))], compare.UKF_ALL: [compare.track_data(exact_track(scenario))]}
    earlier = write_json(tmp_path / "earlier.json", json_ready({
        "arguments": ["--seeds", "0"], "seeds": [0], "ukf": vars(compare.FilterSettings(drift_noise=1e-5)), "tuning": [],
        "runs": {"mass_m_ramp": runs},
    }))
    # the earlier run's seeds must be the ones asked for: one line, exit 2, nothing written
    assert compare.main(["--scenarios", "mass_m_ramp", "--seeds", "0", "1", "--ukf-from", str(earlier), "--out", str(tmp_path / "no")]) == 2
    assert capsys.readouterr().err.count("\n") == 1 and not (tmp_path / "no").exists()
    assert compare.main(["--scenarios", "mass_m_ramp", "--seeds", "0", "--ukf-from", str(earlier), "--out", str(tmp_path / "out")]) == 0
    results = json.loads((tmp_path / "out" / "results.json").read_text())
    ukf = results["summary"][compare.UKF]["mass_m_ramp"]
    assert ukf["error_median"] == 0.0 and ukf["alpha_lambda"] == 1.0 and ukf["coverage"] == 1.0  # rescored from the file's track
    assert results["ukf"]["drift_noise"] == 1e-5 and results["ukf_source"]["path"] == str(earlier)
    assert set(results["summary"]) == {compare.UKF, compare.UKF_ALL, compare.chain_method("tracking")}
    assert str(earlier) in (tmp_path / "out" / "table.md").read_text()
