"""Results, figures and report of a scenario run through the PHM chain; the ground-truth End of Life."""

import json
import math

import numpy as np
import pytest

from ea_gym import reporting
from ea_gym.degradation import PiecewiseLinearProfile
from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.diagnosis.database import classes_of
from ea_gym.models import spring_mass_damper
from ea_gym.phm import (
    DetectorConfig,
    PHMChain,
    PHMConfig,
    calibrate_thresholds,
    run_scenario,
)
from ea_gym.scenario import load_scenario

PNG = b"\x89PNG\r\n\x1a\n"
FIG10 = PiecewiseLinearProfile((0.0, 5.0, 50.0, 100.0), (100.0, 100.0, 86.5, 100.0))
LIMITS = (85.0, 105.0)

# a short version of the paper's fault: k falls from 5 s, then a corrective action from 45 s
SCENARIO = {
    "system": "spring_mass_damper",
    "load": {"kind": "sines", "offset": 10.0,
             "sines": [{"amplitude": 5.0, "frequency": 0.3}, {"amplitude": 2.0, "frequency": 1.1, "phase": 0.5}]},
    "duration": 70.0,
    "fault": {"parameter": "k", "profile": [[0, 100], [5, 100], [45, 88], [70, 95]]},
    "sensors": {"noise": 0.01, "seed": 0},
}


# ------------------------------------------------------------------------------------------------
# PiecewiseLinearProfile.trend_end_of_life
# ------------------------------------------------------------------------------------------------


def test_trend_end_of_life_fault_phase_reaches_the_lower_limit_at_55_s():
    t = np.array([5.0, 5.5, 20.0, 49.9])  # 5 s: a breakpoint takes the segment that starts there
    np.testing.assert_allclose(FIG10.trend_end_of_life(t, LIMITS), 55.0, rtol=0, atol=1e-9)


def test_trend_end_of_life_corrective_phase_reaches_the_upper_limit():
    t = np.array([50.0, 50.1, 75.0, 99.9])
    expected = 50.0 + (105.0 - 86.5) / 0.27  # 118.52 s
    np.testing.assert_allclose(FIG10.trend_end_of_life(t, LIMITS), expected, rtol=0, atol=1e-9)
    assert expected == pytest.approx(118.5185, abs=1e-4)


def test_trend_end_of_life_is_inf_where_the_profile_is_flat():
    eol = FIG10.trend_end_of_life(np.array([0.0, 2.0, 4.999, 100.0, 150.0]), LIMITS)
    assert np.all(np.isinf(eol))
    assert np.all(np.isinf(PiecewiseLinearProfile((3.0,), (100.0,)).trend_end_of_life(np.array([0.0, 3.0, 9.0]), LIMITS)))


def test_trend_end_of_life_is_t_itself_outside_the_limits():
    profile = PiecewiseLinearProfile((0.0, 10.0, 20.0), (100.0, 80.0, 110.0))  # crosses 85 at 7.5 s
    t = np.array([5.0, 7.5, 9.0, 10.5, 19.0])
    eol = profile.trend_end_of_life(t, LIMITS)
    np.testing.assert_allclose(eol[:2], 7.5, rtol=0, atol=1e-9)  # heading down, reached at 7.5 s
    np.testing.assert_array_equal(eol[2:4], t[2:4])  # below 85 N/m
    # 19 s: 107 N/m, beyond the upper limit
    assert profile.value(19.0) > 105.0 and eol[4] == 19.0
    assert profile.trend_end_of_life(np.array([[1.0, 2.0]]), LIMITS).shape == (1, 2)


def test_trend_end_of_life_rejects_reversed_limits():
    with pytest.raises(ValueError, match="lower < upper"):
        FIG10.trend_end_of_life(np.array([1.0]), (105.0, 85.0))


# ------------------------------------------------------------------------------------------------
# a real (short) run of the chain with a stand-in isolation network
# ------------------------------------------------------------------------------------------------


class _FavoursK(FaultClassifier):
    """A stand-in for the trained network: always "k" with probability 0.95 (no training in tests)."""

    def predict_proba(self, features):
        return np.tile([0.0, 0.95, 0.03, 0.02], (len(features), 1))


@pytest.fixture(scope="module")
def setting():
    model = spring_mass_damper()
    config = PHMConfig(noise=0.01, detector=DetectorConfig(calibration_runs=2, calibration_duration=20.0, balance_span=20.0))
    thresholds = calibrate_thresholds(model, config, np.random.default_rng(2))
    chain = PHMChain(model, _FavoursK(classes_of(model), "strong", 1), thresholds, config)
    scenario = load_scenario(SCENARIO)
    run = run_scenario(scenario, chain, np.random.default_rng(3))
    return run, chain, scenario


def test_chain_results_are_json_and_consistent_with_the_run(setting):
    run, chain, scenario = setting
    results = reporting.chain_results(run, chain, scenario)
    json.dumps(results, allow_nan=False)
    assert results["isolated_parameter"] == "k"
    assert results["detection_time"] is not None and 5.0 < results["detection_time"] < 30.0
    probabilities = results["class_probabilities"]
    assert set(probabilities) == {"none", "k", "m", "b"}
    assert probabilities["k"] == pytest.approx(0.95)
    assert sum(probabilities.values()) == pytest.approx(1.0)

    estimate = results["estimate"]
    t = np.array(estimate["t"])
    assert estimate["parameter"] == "k" and len(t) == len(estimate["value"]) > 0
    assert np.all(np.diff(t) > 0)
    assert t[0] >= 0.0 and t[-1] <= run.t[-1]
    assert np.all(np.abs(np.array(estimate["value"]) - 100.0) < 20.0)

    predictions = results["eol_predictions"]
    assert predictions
    for p in predictions:
        assert math.isfinite(p["eol"]) and p["rul"] == pytest.approx(p["eol"] - p["t"])
        assert p["limit"] in ("lower", "upper") and p["parameter"] == "k"

    metrics = results["metrics"]
    assert metrics["isolation_correct"] is True
    assert metrics["fault_onset"] == 5.0
    assert metrics["detection_delay"] == pytest.approx(results["detection_time"] - 5.0)
    assert metrics["estimation"]["window"][0] >= 10.0
    assert metrics["estimation"]["rmse"] < 3.0  # N/m
    fault = metrics["eol_fault_phase"]
    assert fault is not None and fault["segment"] == [5.0, 45.0] and fault["limit"] == "lower"
    assert fault["true_eol"] == pytest.approx(55.0)  # 5 + 15 / 0.3
    assert fault["n_predictions"] >= 3
    assert fault["eol_error"]["min"] <= fault["eol_error"]["median"] <= fault["eol_error"]["max"]
    assert "alpha_lambda" in fault["prognostics"]
    # the corrective phase's true EoL (45 + 17 / 0.28 = 105.7 s) lies so far beyond the run that
    # alpha-lambda has no prediction at t_lambda: reported, not raised
    corrective = [p for p in metrics["eol_phases"] if p["segment"] == [45.0, 70.0]]
    if corrective:
        assert corrective[0]["true_eol"] == pytest.approx(45.0 + 17.0 / 0.28)
        assert "error" in corrective[0]["prognostics"]


def test_chain_results_without_a_fault_have_no_metrics(setting):
    run, chain, _ = setting
    healthy = load_scenario({key: value for key, value in SCENARIO.items() if key != "fault"})
    results = reporting.chain_results(run, chain, healthy)
    json.dumps(results, allow_nan=False)
    assert "metrics" not in results


def test_write_phm_outputs_writes_results_report_and_every_figure(setting, tmp_path):
    run, chain, scenario = setting
    out = tmp_path / "report"
    results = reporting.write_phm_outputs(out, run, chain, scenario, "test run", sections=["## Notes\n\nextra text"])
    assert json.loads((out / "results.json").read_text()) == results
    report = (out / "report.md").read_text()
    assert report.startswith("# test run") and "extra text" in report
    for name, (file_name, _) in reporting.FIGURES.items():
        assert (out / file_name).read_bytes()[:8] == PNG, name
        assert f"]({file_name})" in report
    assert "| detection time (s) |" in report and "| 5-45 | lower | 55 |" in report
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report"]  # no staging directory left


def test_write_phm_outputs_leaves_nothing_when_a_figure_fails(setting, tmp_path, monkeypatch):
    run, chain, scenario = setting

    def broken(*args, **kwargs):
        raise RuntimeError("figure failed")

    monkeypatch.setitem(reporting.PLOTS, "rul", broken)
    out = tmp_path / "report"
    with pytest.raises(RuntimeError, match="figure failed"):
        reporting.write_phm_outputs(out, run, chain, scenario, "test run")
    assert list(tmp_path.iterdir()) == []
