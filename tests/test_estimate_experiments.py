"""experiments/studies/estimates_in_env.py and experiments/studies/builtin_systems.py: their metrics on
hand-computed cases (their --smoke runs end to end are in test_experiments.py)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments" / "studies"))

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


def test_ramp_reaches_the_limit_at_the_end_and_plan_ends_with_the_fault_free_runs():
    model = get_model("spring_mass_damper")
    k = model.parameter_names.index("k")
    values = builtin_systems.ramp(model, "k", 85.0, 40.0)(np.array([0.0, 10.0, 25.0, 40.0, 50.0]))
    assert values[:, k].tolist() == [100.0, 100.0, 92.5, 85.0, 85.0]
    np.testing.assert_array_equal(np.delete(values, k, axis=1), np.repeat(np.delete(model.parameter_vector(), k)[None], 5, 0))
    rows = builtin_systems.plan(model, 3, np.random.default_rng(0))
    assert [p for p, _ in rows] == ["k"] * 3 + ["m"] * 3 + ["b"] * 3 + [None] * 3
    assert all(limit in model.safe_limits[p] for p, limit in rows if p is not None)
