"""experiments/estimates_in_env.py and experiments/builtin_systems.py: their metrics on hand-computed
cases, and each script's --quick run end to end."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments"))

import builtin_systems  # noqa: E402
import estimates_in_env  # noqa: E402

from ea_gym.models import get_model  # noqa: E402


def test_position_toward_limit_is_the_share_of_the_way_to_the_limit_moved_toward():
    values = np.array([100.0, 92.5, 85.0, 102.5, 105.0])
    assert estimates_in_env.position_toward_limit(values, 100.0, (85.0, 105.0)).tolist() == [0.0, 0.5, 1.0, 0.5, 1.0]


def test_rul_metrics_on_a_hand_case():
    steps = estimates_in_env.PastHalfway(
        rul_true=np.array([10.0, 20.0, 40.0, 80.0]),
        rul=np.array([12.0, 20.0, 20.0, 1000.0]),  # the last: no prediction (clipped to rul_max)
        low=np.array([9.0, 25.0, 10.0, 0.0]),
        high=np.array([11.0, 30.0, 50.0, 1000.0]),  # the last: unbounded, a miss though it holds the truth
        episodes=2,
    )
    m = estimates_in_env.rul_metrics(steps, rul_max=1000.0)
    assert m["median_relative_error"] == pytest.approx(np.median([0.2, 0.0, 0.5, 11.5]))
    assert m["coverage"] == 0.5
    # ranks (1, 2.5, 2.5, 4) against (1, 2, 3, 4): 4.5 / sqrt(4.5 * 5)
    assert m["spearman"] == pytest.approx(4.5 / np.sqrt(22.5))
    assert (m["steps"], m["episodes"], m["predicted"], m["bounded"]) == (4, 2, 0.75, 0.75)
    empty = estimates_in_env.rul_metrics(estimates_in_env.PastHalfway(*(np.zeros(0),) * 4, episodes=0), rul_max=1000.0)
    assert empty["median_relative_error"] is None and empty["steps"] == 0


def test_estimates_in_env_quick_counts_the_steps_past_half_way(tmp_path):
    assert estimates_in_env.main(["--quick", "--out", str(tmp_path)]) == 0
    result = json.loads((tmp_path / "results.json").read_text())
    for fault in estimates_in_env.FAULTS:
        m = result["faults"][fault]
        # linear wear at 1.5 % of the way per s from 0 s: past half-way at the ends of steps 34..66, failure at 67 s
        assert (m["episodes"], m["steps"]) == (1, 33)
        assert 0.0 <= m["coverage"] <= 1.0 and m["median_relative_error"] >= 0.0
        truth = np.array(result["steps"][fault]["rul_true"])
        np.testing.assert_allclose(truth, 1.0 / 0.015 - np.arange(34, 67), atol=1e-3)  # kept to the millisecond
    assert result["pooled"]["steps"] == 99 and -1.0 <= result["pooled"]["spearman"] <= 1.0
    assert (tmp_path / "table.md").read_text().count("\n| ") == 5 and (tmp_path / "rul.png").stat().st_size > 0


def test_ramp_reaches_the_limit_at_the_end_and_plan_ends_with_the_fault_free_runs():
    model = get_model("spring_mass_damper")
    k = model.parameter_names.index("k")
    values = builtin_systems.ramp(model, "k", 85.0, 40.0)(np.array([0.0, 10.0, 25.0, 40.0, 50.0]))
    assert values[:, k].tolist() == [100.0, 100.0, 92.5, 85.0, 85.0]
    np.testing.assert_array_equal(np.delete(values, k, axis=1), np.repeat(np.delete(model.parameter_vector(), k)[None], 5, 0))
    rows = builtin_systems.plan(model, 3, np.random.default_rng(0))
    assert [p for p, _ in rows] == ["k"] * 3 + ["m"] * 3 + ["b"] * 3 + [None] * 3
    assert all(limit in model.safe_limits[p] for p, limit in rows if p is not None)


def test_builtin_systems_quick_detects_every_ramp(tmp_path):
    assert builtin_systems.main(["--quick", "--out", str(tmp_path)]) == 0
    result = json.loads((tmp_path / "results.json").read_text())
    spring = result["systems"]["spring_mass_damper"]
    assert set(spring["parameters"]) == {"k", "m", "b"}
    for m in spring["parameters"].values():
        # every ramp reaches its safe limit 30 s after onset: far past the detection thresholds
        assert m["runs"] == 2 and m["detected"] == 1.0
        assert 0.0 <= m["isolated"] <= 1.0 and 0.0 <= m["wrong_belief"] <= 1.0 and m["estimate_error"] >= 0.0
    assert spring["fault_free"]["runs"] == 2
    assert "| spring_mass_damper | fault-free |" in (tmp_path / "table.md").read_text()
