"""Results, figures and report of a scenario run through the PHM chain; the ground-truth End of Life."""

import dataclasses
import json
import math

import numpy as np
import pytest
from matplotlib.collections import Collection
from matplotlib.lines import Line2D

from ea_gym import reporting
from ea_gym.degradation import PiecewiseLinearProfile
from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.diagnosis.database import classes_of
from ea_gym.models import spring_mass_damper
from ea_gym.phm import (
    ChainTiming,
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
    config = PHMConfig(timing=ChainTiming(noise=0.01), detector=DetectorConfig(calibration_runs=2, calibration_duration=20.0, balance_span=20.0))
    thresholds = calibrate_thresholds(model, config, np.random.default_rng(2))
    chain = PHMChain(model, _FavoursK(classes_of(model), "strong", 1), thresholds, config)
    scenario = load_scenario(SCENARIO)
    run = run_scenario(scenario, chain, np.random.default_rng(3))
    # the chain's one suspect alone, as without its joint side filter: the per-part outputs are test_reporting_parts.py's
    return _with_statuses(run, lambda status: dataclasses.replace(status, parts=None)), chain, scenario


def test_chain_results_are_json_and_consistent_with_the_run(setting):
    run, chain, scenario = setting
    results = reporting.chain_results(run, chain, scenario)
    json.dumps(results, allow_nan=False)
    assert results["isolated_parameter"] == "k"
    assert results["detection_time"] is not None and 5.0 < results["detection_time"] < 30.0
    probabilities = results["class_probabilities"]
    assert set(probabilities) == {"none", "k", "m", "b"}
    assert probabilities["k"] > 0.75
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


# ------------------------------------------------------------------------------------------------
# one diagnosis: the fused belief, an undecided chain, a wrong isolation, figures that stay honest
# ------------------------------------------------------------------------------------------------


def _with_statuses(run, change):
    """The run with ``change(status)`` applied to every status (a dataclass replace)."""
    return dataclasses.replace(run, statuses=[change(s) for s in run.statuses])


def _isolating(chain, parameter, confident=True, belief=None):
    """A change of status: ``parameter`` the suspect (confident or not) with the fused ``belief``."""
    index = chain.classes.index(parameter)

    def change(status):
        if not status.alarm[0]:
            return status
        diagnosis = np.array([belief if belief is not None else [0.02 if c != parameter else 0.9 for c in chain.classes]])
        diagnosis = diagnosis / diagnosis.sum()
        return dataclasses.replace(status, isolated=np.array([index]), confident=np.array([confident]), diagnosis=diagnosis)

    return change


def test_class_probabilities_are_the_fused_belief_that_isolates(setting):
    run, chain, scenario = setting
    results = reporting.chain_results(run, chain, scenario)
    fused = results["class_probabilities"]
    np.testing.assert_allclose(list(fused.values()), run.statuses[-1].diagnosis[0])
    assert sum(fused.values()) == pytest.approx(1.0)
    faults = {name: p for name, p in fused.items() if name != "none"}
    assert results["isolated_parameter"] == max(faults, key=faults.get)
    assert results["isolation"]["state"] == "isolated"
    assert results["isolation"]["confidence"] == pytest.approx(faults["k"] / sum(faults.values()))
    # the network's own output, named as such
    assert results["network_probabilities"]["k"] == pytest.approx(0.95)


def test_an_undecided_chain_isolates_nothing_and_reports_the_split_belief(setting, monkeypatch, tmp_path):
    run, chain, scenario = setting
    split = [0.02, 0.5, 0.38, 0.1]
    late = _isolating(chain, "k", confident=False, belief=split)
    # undecided from 30 s on: no End of Life from then
    undecided = _with_statuses(run, lambda s: late(s) if s.t[0] > 30.0 else s)
    results = reporting.chain_results(undecided, chain, scenario)
    json.dumps(results, allow_nan=False)
    assert results["isolated_parameter"] is None
    np.testing.assert_allclose(list(results["class_probabilities"].values()), split)
    assert results["isolation"] == {"state": "undecided", "favoured": "k", "confidence": pytest.approx(0.5 / 0.98), "threshold": 0.75}
    assert results["estimate"]["parameter"] is None
    assert results["eol_predictions"] and all(p["t"] <= 30.0 for p in results["eol_predictions"])
    metrics = results["metrics"]
    assert metrics["isolation_outcome"] == "undecided" and metrics["isolation_correct"] is False
    assert "eol_phases" not in metrics and "estimation" not in metrics
    assert "undecided" in reporting.report.isolation_text(results)
    # the figure shows the favoured hypothesis's estimate, and no End of Life on it
    figure = figure_of(reporting.plot_estimate, monkeypatch, undecided, chain, scenario, tmp_path / "f.png", results=results)
    check_axes(figure)
    labels = [t.get_text() for t in figure.axes[0].get_legend().get_texts()]
    assert "estimate of k (favoured, not isolated)" in labels
    assert not any("fit" in label or "EoL" in label for label in labels), labels


def figure_of(plot, monkeypatch, *args, **kwargs):
    """The matplotlib figure ``plot`` draws (kept open instead of saved)."""
    drawn = []
    monkeypatch.setattr(reporting.figures, "save_figure", lambda fig, path: drawn.append(fig) or path)
    plot(*args, **kwargs)
    (figure,) = drawn
    return figure


def _has_data(artist):
    if isinstance(artist, Line2D):
        return np.isfinite(np.asarray(artist.get_ydata(), dtype=float)).any()
    if isinstance(artist, Collection):
        return len(artist.get_paths()) > 0
    return True  # a patch (axvspan)


def check_axes(figure):
    """Every legend entry stands for an artist with data; every data line's points lie within the y limits."""
    for ax in figure.axes:
        legend = ax.get_legend()
        if legend is not None:
            labelled = [a for a in (*ax.lines, *ax.collections, *ax.patches) if not a.get_label().startswith("_")]
            assert sorted(t.get_text() for t in legend.get_texts()) == sorted(a.get_label() for a in labelled)
            assert all(_has_data(a) for a in labelled), [a.get_label() for a in labelled if not _has_data(a)]
        bottom, top = sorted(ax.get_ylim())
        for line in ax.lines:
            if line.get_transform() is ax.transData:
                y = np.asarray(line.get_ydata(), dtype=float)
                y = y[np.isfinite(y)]
                assert np.all((y >= bottom - 1e-9 * abs(bottom)) & (y <= top + 1e-9 * abs(top))), line.get_label()


@pytest.mark.parametrize("name", sorted(reporting.PLOTS))
def test_figures_draw_every_legend_entry_and_keep_data_within_the_axes(setting, monkeypatch, tmp_path, name):
    run, chain, scenario = setting
    results = reporting.chain_results(run, chain, scenario)
    # a runaway estimate at the start must not stretch the axis nor leave it
    results["estimate"]["value"][0] = 1e6
    figure = figure_of(reporting.PLOTS[name], monkeypatch, run, chain, scenario, tmp_path / "f.png", results=results)
    check_axes(figure)
    if name == "estimate":
        (ax,) = figure.axes
        assert ax.get_ylim() == pytest.approx((85.0 - 3.0, 105.0 + 7.0))
        assert any("off the axis" in t.get_text() for t in ax.get_legend().get_texts())


def test_a_wrong_isolation_draws_no_end_of_life_of_the_fault_on_its_estimate(setting, monkeypatch, tmp_path):
    run, chain, scenario = setting
    wrong = _isolating(chain, "m")
    # k isolated (with its End-of-Life predictions) until 40 s, then m without an End of Life
    run_m = _with_statuses(run, lambda s: dataclasses.replace(wrong(s), eol=np.array([np.inf])) if s.t[0] > 40.0 else s)
    results = reporting.chain_results(run_m, chain, scenario)
    assert results["isolated_parameter"] == "m" and results["metrics"]["isolation_outcome"] == "wrong"
    assert {p["parameter"] for p in results["eol_predictions"]} == {"k"}
    figure = figure_of(reporting.plot_estimate, monkeypatch, run_m, chain, scenario, tmp_path / "f.png", results=results)
    check_axes(figure)
    (ax,) = figure.axes
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert not any("fit" in label or "EoL" in label for label in labels), labels
    assert "wrong" in ax.get_title() and ax.get_ylim() == pytest.approx((9.0 - 0.3, 11.0 + 0.7))
    figure = figure_of(reporting.plot_rul, monkeypatch, run_m, chain, scenario, tmp_path / "r.png", results=results)
    check_axes(figure)
