"""results.json per part: ``components``, ``degrading``, ``commissioning``, the run's noise levels and, for a scenario
with several faults, each faulty part's metrics; read from a stand-in of the chain's per-part health whose numbers
are set by hand from the truth, so that every metric has a known value."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

import numpy as np
import pytest

from ea_gym import reporting
from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.diagnosis.database import classes_of
from ea_gym.models import spring_mass_damper
from ea_gym.phm import ChainRun, ChainTiming, DetectorConfig, PHMChain, PHMConfig, calibrate_thresholds, run_scenario
from ea_gym.reporting.results import SETTLING, RunInputs
from ea_gym.scenario import Scenario, load_scenario

TWO_FAULTS = {
    "system": "spring_mass_damper",
    "load": {"kind": "sines", "offset": 10.0, "sines": [{"amplitude": 5.0, "frequency": 0.3}, {"amplitude": 2.0, "frequency": 1.1}]},
    "duration": 80.0,
    # k: -12/70 N/m per s from 10 s, at 85 N/m at 10 + 15 x 70 / 12 = 97.5 s; b: +0.0012 N s/m per s from 30 s, at 0.6 at 113.3 s
    "faults": [{"parameter": "k", "profile": [[0, 100], [10, 100], [80, 88]]},
               {"parameter": "b", "profile": [[0, 0.5], [30, 0.5], [80, 0.56]]}],
    "sensors": {"noise": 0.01, "seed": 0},
}
K_EOL, B_EOL = 97.5, 30.0 + 0.1 / 0.0012


class _FavoursK(FaultClassifier):
    def predict_proba(self, features: np.ndarray) -> np.ndarray:
        return np.tile([0.0, 0.95, 0.03, 0.02], (len(features), 1))


@dataclasses.dataclass(frozen=True)
class FakeParts:
    """``PartHealth``'s fields that results read (N = 1), set by hand."""

    value: np.ndarray
    std: np.ndarray
    degrading: np.ndarray
    named: np.ndarray
    rul: np.ndarray


@pytest.fixture(scope="module")
def setting() -> tuple[ChainRun, PHMChain, Scenario]:
    model = spring_mass_damper()
    config = PHMConfig(timing=ChainTiming(noise=0.01), detector=DetectorConfig(calibration_runs=2, calibration_duration=20.0, balance_span=20.0))
    chain = PHMChain(model, _FavoursK(classes_of(model), "strong", 1), calibrate_thresholds(model, config, np.random.default_rng(2)), config)
    scenario = load_scenario(TWO_FAULTS)
    return run_scenario(scenario, chain, np.random.default_rng(3)), chain, scenario


#: the stand-in's estimate is the truth plus this fraction of the nominal value
OFFSET = 0.002


def with_parts(run: ChainRun, chain: PHMChain, scenario: Scenario, named: Any = None) -> ChainRun:
    """The run with every status's parts set from the truth: the estimate OFFSET x nominal above it, a std of 1 % of
    nominal, degrading probability 0.99 (named) where the profile moves and 0.01 elsewhere (``named(t, d, truth)``
    overrides), the RUL the truth's with an interval of +-10 %; no End of Life where the truth has none."""
    model = scenario.model
    columns = [model.parameter_names.index(name) for name in chain.degradable]
    nominal = model.parameter_vector()[columns]
    statuses = []
    for status in run.statuses:
        t = float(status.t[0])
        truth = scenario.parameters_at(np.array(t))[columns]
        eol = scenario.true_end_of_life(np.array([t]))
        moving = np.array([scenario.parameters_at(np.array(t + 0.5))[c] != truth[d] for d, c in enumerate(columns)])  # the segment from t
        rul = np.full((len(columns), 3), np.inf)
        for d, name in enumerate(chain.degradable):
            if name in eol and np.isfinite(eol[name][0]):
                rul[d] = (eol[name][0] - t) * np.array([1.0, 0.9, 1.1])
        chosen = moving if named is None else np.array([named(t, d, moving[d]) for d in range(len(columns))])
        parts = FakeParts(value=(truth + OFFSET * nominal)[None], std=(0.01 * nominal)[None],
                          degrading=np.where(moving, 0.99, 0.01)[None], named=chosen[None], rul=rul[None])
        statuses.append(dataclasses.replace(status, parts=parts))
    return dataclasses.replace(run, statuses=statuses)


def without_parts(run: ChainRun) -> ChainRun:
    """The run as a chain without its joint side filter gives it: no per-part health."""
    return dataclasses.replace(run, statuses=[dataclasses.replace(s, parts=None) for s in run.statuses])


def test_components_give_every_part_at_every_step_with_nulls_where_undefined(setting) -> None:
    run, chain, scenario = setting
    results = reporting.chain_results(with_parts(run, chain, scenario), chain, scenario)
    json.dumps(results, allow_nan=False)
    components = results["components"]
    assert list(components) == list(chain.degradable) == ["k", "m", "b"]
    steps = len(run.statuses)
    for name, series in components.items():
        assert set(series) == {"unit", "limits", "t", "value", "std", "degrading", "named", "rul", "rul_low", "rul_high"}
        assert series["limits"] == list(scenario.model.safe_limits[name])
        assert all(len(series[key]) == steps for key in series if key not in ("unit", "limits")), name
        assert series["t"] == run.t.tolist()
    k, m = components["k"], components["m"]
    at_40 = k["t"].index(40.0)
    assert k["value"][at_40] == pytest.approx(100 - 30 * 12 / 70 + OFFSET * 100)
    assert k["std"][at_40] == pytest.approx(1.0) and k["degrading"][at_40] == 0.99 and k["named"][at_40] is True
    assert k["rul"][at_40] == pytest.approx(K_EOL - 40) and k["rul_low"][at_40] == pytest.approx(0.9 * (K_EOL - 40))
    assert k["rul"][k["t"].index(5.0)] is None  # before its onset: no End of Life, null (not inf)
    assert m["rul"] == [None] * steps and m["named"] == [False] * steps
    assert results["degrading"] == []  # at 80 s both ramps have ended


def test_the_parts_named_at_the_end_are_the_degrading_set(setting) -> None:
    run, chain, scenario = setting
    cut = dataclasses.replace(run, statuses=run.statuses[:70], t=run.t[:70])  # ends at 70 s, both ramps on
    results = reporting.chain_results(with_parts(cut, chain, scenario), chain, scenario)
    assert results["degrading"] == ["k", "b"]


def test_each_faulty_part_is_scored_against_its_own_profile(setting) -> None:
    run, chain, scenario = setting
    metrics = reporting.chain_results(with_parts(run, chain, scenario), chain, scenario)["metrics"]
    assert metrics["fault_parameters"] == ["k", "b"]
    assert metrics["fault_parameter"] == "k"  # the single-fault keys stay: the isolated faulty part's
    k, b = metrics["parts"]["k"], metrics["parts"]["b"]
    assert (k["onset"], b["onset"]) == (10.0, 30.0)
    # the estimate is OFFSET x nominal above the truth at every step
    assert k["estimation"]["median"] == pytest.approx(OFFSET * 100) and b["estimation"]["max"] == pytest.approx(OFFSET * 0.5)
    assert k["named"] == b["named"] == 1.0
    # from onset + 30 s to 79 s the truth's RUL is finite (at 80 s the ramps end) and inside the +-10 % interval
    assert k["rul_coverage"] == {"fraction": 1.0, "predicted": 1.0, "steps": 40}
    assert b["rul_coverage"] == {"fraction": 1.0, "predicted": 1.0, "steps": 20}
    for part, eol in ((k, K_EOL), (b, B_EOL)):
        phase = part["eol_fault_phase"]
        assert phase["true_eol"] == pytest.approx(eol) and phase["eol_error"]["max"] == pytest.approx(0.0, abs=1e-9)
        assert phase["prognostics"]["alpha_lambda"]["passed"] is True and phase["limit_agreement"] is None
    # every part settled for SETTLING s: from 60 s (b's onset + 30 s) to 79 s (k's and b's ramps end at 80 s)
    assert SETTLING == 30.0
    assert metrics["degrading_set"] == {"exact": 1.0, "steps": 20, "settling": 30.0}


def test_a_set_named_wrongly_is_counted(setting) -> None:
    """m named degrading from 70 s on, b missed from 50 s on: of the 20 steps scored (60-79 s: from b's onset + 30 s
    to the end of both ramps at 80 s) every set is wrong; b's own fraction is 0 over its 20, k's 1 over its 40 (40-79 s)."""
    run, chain, scenario = setting
    m, b = chain.degradable.index("m"), chain.degradable.index("b")

    def named(t: float, d: int, truth: bool) -> bool:
        if d == m:
            return t >= 70.0
        return truth and t < 50.0 if d == b else truth

    metrics = reporting.chain_results(with_parts(run, chain, scenario, named), chain, scenario)["metrics"]
    assert metrics["degrading_set"] == {"exact": 0.0, "steps": 20, "settling": 30.0}
    assert metrics["parts"]["b"]["named"] == 0.0 and metrics["parts"]["k"]["named"] == 1.0
    late_m = with_parts(run, chain, scenario, lambda t, d, truth: (t >= 70.0) if d == m else truth)
    assert reporting.chain_results(late_m, chain, scenario)["metrics"]["degrading_set"]["exact"] == pytest.approx(10 / 20)


def test_a_missing_or_wrong_interval_is_a_miss(setting) -> None:
    """k's RUL predicted 25 % long from 60 s (outside its +-10 % interval), and none at all from 70 s: of its 40 scored
    steps (40-79 s) 20 are covered, 30 predicted."""
    run, chain, scenario = setting
    k = chain.degradable.index("k")
    statuses = []
    for status in with_parts(run, chain, scenario).statuses:
        t, parts = float(status.t[0]), status.parts
        rul = parts.rul.copy()
        if t >= 70.0:
            rul[0, k] = np.inf
        elif t >= 60.0:
            rul[0, k] *= 1.25
        statuses.append(dataclasses.replace(status, parts=dataclasses.replace(parts, rul=rul)))
    metrics = reporting.chain_results(dataclasses.replace(run, statuses=statuses), chain, scenario)["metrics"]
    assert metrics["parts"]["k"]["rul_coverage"] == {"fraction": 0.5, "predicted": 0.75, "steps": 40}


def test_without_the_joint_side_filter_the_components_are_the_estimators_own(setting) -> None:
    """``HealthStatus.parts`` None: each part's estimate and std from ``estimates`` and ``estimation.variance``, the rest
    null; the degrading set is the isolated part; the set's metric is not scored."""
    run, chain, scenario = setting
    run = without_parts(run)
    results = reporting.chain_results(run, chain, scenario)
    json.dumps(results, allow_nan=False)
    d = chain.degradable.index("b")
    series = results["components"]["b"]
    expected = [s.estimates[0, d] for s in run.statuses]
    np.testing.assert_array_equal(series["value"], expected)
    std = [np.sqrt(s.estimation.variance[0, d]) for s in run.statuses]
    assert [x if x is not None else np.nan for x in series["std"]] == pytest.approx(std, nan_ok=True)
    assert series["degrading"] == series["named"] == series["rul"] == [None] * len(run.statuses)
    assert results["degrading"] == ([results["isolated_parameter"]] if results["isolated_parameter"] else [])
    assert results["metrics"]["degrading_set"] is None and results["metrics"]["parts"]["b"]["named"] is None


@dataclasses.dataclass(frozen=True)
class FakeCommissioning:
    names: tuple[str, ...]
    value: np.ndarray
    std: np.ndarray


def test_the_run_says_where_its_noise_levels_and_its_healthy_machine_came_from(setting) -> None:
    run, chain, scenario = setting
    commissioned = FakeCommissioning(("k", "m", "b"), np.array([[97.0, 10.2, 0.51]]), np.array([[0.4, 0.02, np.nan]]))
    inputs = RunInputs(noise_source="estimated", noise_estimate=0.0101, load_noise_source="assumed exact",
                       commissioning=commissioned, commissioning_source="healthy.csv")  # type: ignore[arg-type]
    results = reporting.chain_results(run, chain, None, "data.csv", inputs)
    json.dumps(results, allow_nan=False)
    assert results["run"]["noise"] == 0.01 and results["run"]["noise_source"] == "estimated" and results["run"]["noise_estimate"] == 0.0101
    assert results["run"]["load_noise"] == 0.0 and results["run"]["load_noise_source"] == "assumed exact"
    assert results["commissioning"] == {"values": {"k": 97.0, "m": 10.2, "b": 0.51}, "std": {"k": 0.4, "m": 0.02, "b": None},
                                        "source": "healthy.csv"}
    plain = reporting.chain_results(run, chain, scenario)
    assert "commissioning" not in plain and plain["run"]["noise_source"] == "scenario" and "noise_estimate" not in plain["run"]


def test_the_report_gives_one_line_per_component_and_the_model_fit(setting, tmp_path) -> None:
    run, chain, scenario = setting
    cut = dataclasses.replace(run, statuses=run.statuses[:70], t=run.t[:70])  # 70 s: both ramps on
    results = reporting.write_phm_outputs(tmp_path / "out", with_parts(cut, chain, scenario), chain, scenario, "two faults")
    report = (tmp_path / "out" / "report.md").read_text()
    k = 100 - 60 * 12 / 70 + OFFSET * 100  # N/m at 70 s
    rul = K_EOL - 70
    assert (f"| k at 70 s: estimate, degrading probability, RUL and its 95% interval | {k:.4g} +- 1 N/m "
            f"({(k - 85) / 20:.0%} of its safe range 85-105 N/m); degrading with probability 0.99 (named); "
            f"RUL {rul:.4g} s [{0.9 * rul:.4g}, {1.1 * rul:.4g}] |") in report
    assert "| m at 70 s: estimate, degrading probability, RUL and its 95% interval | 10.02 +- 0.1 kg" in report
    assert "degrading with probability 0.01; no End of Life |" in report
    assert "| degrading parts (named at the end) | k, b |" in report
    assert "| model fit | " in report and "| sensor noise (of each signal's RMS) | 1.00% (scenario) |" in report
    assert reporting.report.degrading_text(results) == "degrading parts: k, b"


# ------------------------------------------------------------------------------------------------
# figures: every component, its own colour and marker, complete legends, End-of-Life labels that never overprint
# ------------------------------------------------------------------------------------------------


def _label_boxes(figure: Any) -> list[Any]:
    """The boxes (display units) of every End-of-Life label in the figure, as its renderer draws them."""
    from matplotlib.text import Annotation

    renderer = figure.canvas.get_renderer()
    return [text.get_window_extent(renderer) for ax in figure.axes for text in ax.texts if isinstance(text, Annotation)]


def _overlaps(boxes: list[Any]) -> int:
    return sum(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:])


def _same_eol(run: ChainRun, chain: PHMChain, scenario: Scenario) -> ChainRun:
    """Every k End of Life at 97 s, from the estimator and the parts alike: without the placement rule their labels
    would sit on one another."""
    k = chain.degradable.index("k")
    statuses = []
    for status in with_parts(run, chain, scenario).statuses:
        t = status.t[0]
        rul = status.parts.rul.copy()
        if np.isfinite(rul[0, k, 0]):
            rul[0, k] = np.array([97.0, 90.0, 104.0]) - t
        statuses.append(dataclasses.replace(status, parts=dataclasses.replace(status.parts, rul=rul)))
    return dataclasses.replace(run, statuses=statuses)


@pytest.mark.parametrize("name", ["estimate", "rul", "estimate_error"])
def test_every_component_has_its_own_colour_marker_and_complete_legend(setting, monkeypatch, tmp_path, name) -> None:
    from test_reporting import check_axes, figure_of

    run, chain, scenario = setting
    run = with_parts(run, chain, scenario)
    results = reporting.chain_results(run, chain, scenario)
    figure = figure_of(reporting.PLOTS[name], monkeypatch, run, chain, scenario, tmp_path / "f.png", results=results)
    check_axes(figure)
    styles = {}
    for ax in figure.axes:
        for line in ax.lines:
            label = line.get_label()
            for part in chain.degradable:
                if label in (f"estimate of {part}", f"predicted RUL of {part}") or label.startswith(f"estimate - truth of {part}"):
                    styles[part] = (line.get_color(), line.get_marker())
    expected = ["k", "b"] if name == "rul" else ["k", "m", "b"]  # m has no End of Life: no RUL to draw
    assert sorted(styles) == sorted(expected)
    assert len(set(styles.values())) == len(styles) and len({color for color, _ in styles.values()}) == len(styles)
    if name == "estimate":
        assert len(figure.axes) == 3 and [ax.get_ylabel() for ax in figure.axes] == ["k (N/m)", "m (kg)", "b (N s/m)"]


def test_end_of_life_labels_never_overprint(setting, monkeypatch, tmp_path) -> None:
    """The labels' boxes, as the renderer draws them, do not intersect; with the placement rule turned off the same
    figures have overlapping labels (the check sees them)."""
    from test_reporting import figure_of

    run, chain, scenario = setting
    crowded = _same_eol(run, chain, scenario)
    results = reporting.chain_results(crowded, chain, scenario)
    suspect = without_parts(run)  # the estimator's suspect alone, with its fits
    plain = reporting.chain_results(suspect, chain, scenario)
    figures = [figure_of(reporting.plot_estimate, monkeypatch, crowded, chain, scenario, tmp_path / "a.png", results=results),
               figure_of(reporting.plot_estimate, monkeypatch, suspect, chain, scenario, tmp_path / "b.png", results=plain)]
    for figure, least in zip(figures, (3, 1)):  # k's fit and End of Life at one place, b's; the suspect's fit
        boxes = _label_boxes(figure)
        assert len(boxes) >= least and _overlaps(boxes) == 0
        frames = [ax.get_window_extent(figure.canvas.get_renderer()) for ax in figure.axes]
        assert all(any(frame.x0 <= box.x0 and box.x1 <= frame.x1 for frame in frames) for box in boxes)  # within an axes' width
    monkeypatch.setattr(reporting.estimate_figure, "place_labels", lambda ax, labels: None)
    unplaced = figure_of(reporting.plot_estimate, monkeypatch, crowded, chain, scenario, tmp_path / "c.png", results=results)
    assert _overlaps(_label_boxes(unplaced)) > 0
