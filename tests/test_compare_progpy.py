"""experiments/compare_progpy.py: its metric helpers on hand-computed cases, and ProgPy's UKF on a noise-free run (when installed)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments"))

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
    assert compare.main(["--quick", "--out", "unused"]) == 2
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
