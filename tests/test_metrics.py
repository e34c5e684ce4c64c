"""Tests of ea_gym.metrics against hand-computed cases (the arithmetic is in the comments)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from ea_gym.metrics import (
    alpha_lambda,
    confusion_matrix,
    cumulative_relative_accuracy,
    eol_error,
    estimation_errors,
    isolation_accuracy,
    per_class_accuracy,
    prognostic_horizon,
    prognostic_report,
    relative_accuracy,
    rul_errors,
)

CLASSES = ["A", "B", "C"]
# 8 cases:           0    1    2    3    4    5    6    7
TRUE_LABELS = ["A", "A", "A", "B", "B", "C", "C", "C"]
PRED_LABELS = ["A", "A", "B", "B", "C", "C", "C", "A"]

# Prognostic set-up shared by alpha-lambda / PH / RA: EoL = 100 s, predictions at t = 0, 10, ..., 90 s,
# true RUL = 100 - t = 100, 90, ..., 10 s.
EOL = 100.0
T = np.arange(0.0, 100.0, 10.0)
RUL_TRUE = EOL - T


# ------------------------------------------------------------------------------------------------
# isolation
# ------------------------------------------------------------------------------------------------


def test_confusion_matrix_3_classes_8_labels():
    # row A (true A, cases 0-2): predicted A, A, B        -> [2, 1, 0]
    # row B (true B, cases 3-4): predicted B, C           -> [0, 1, 1]
    # row C (true C, cases 5-7): predicted C, C, A        -> [1, 0, 2]
    m = confusion_matrix(TRUE_LABELS, PRED_LABELS, CLASSES)
    np.testing.assert_array_equal(m, [[2, 1, 0], [0, 1, 1], [1, 0, 2]])
    assert m.sum() == 8
    assert np.issubdtype(m.dtype, np.integer)


def test_confusion_matrix_class_order_follows_classes():
    # same data, classes reversed (C, B, A): rows/cols are reversed -> [[2,0,1],[1,1,0],[0,1,2]]
    m = confusion_matrix(TRUE_LABELS, PRED_LABELS, ["C", "B", "A"])
    np.testing.assert_array_equal(m, [[2, 0, 1], [1, 1, 0], [0, 1, 2]])


def test_isolation_accuracy():
    # correct cases: 0, 1, 3, 5, 6 -> 5 of 8 = 0.625
    assert isolation_accuracy(TRUE_LABELS, PRED_LABELS) == pytest.approx(0.625)
    assert isolation_accuracy(["A", "B"], ["A", "B"]) == 1.0
    assert isolation_accuracy(["A", "B"], ["B", "A"]) == 0.0


def test_per_class_accuracy():
    # diagonal / row sums: A 2/3, B 1/2, C 2/3
    m = confusion_matrix(TRUE_LABELS, PRED_LABELS, CLASSES)
    acc = per_class_accuracy(m, CLASSES)
    assert acc == pytest.approx({"A": 2 / 3, "B": 0.5, "C": 2 / 3})


def test_per_class_accuracy_empty_row_is_nan():
    # class B has no true cases: row [0, 0] -> nan; A: 3 / (3 + 1) = 0.75
    acc = per_class_accuracy(np.array([[3, 1], [0, 0]]), ["A", "B"])
    assert acc["A"] == pytest.approx(0.75)
    assert math.isnan(acc["B"])


# ------------------------------------------------------------------------------------------------
# estimation
# ------------------------------------------------------------------------------------------------


def test_estimation_errors_4_points():
    # e = estimate - truth = [0, 0.5, -1, 2], |e| = [0, 0.5, 1, 2]
    # max = 2; median = (0.5 + 1) / 2 = 0.75; rmse = sqrt((0 + 0.25 + 1 + 4) / 4) = sqrt(1.3125)
    errors = estimation_errors([1.0, 2.5, 2.0, 5.0], [1.0, 2.0, 3.0, 3.0])
    assert set(errors) == {"max", "median", "rmse"}
    assert errors["max"] == pytest.approx(2.0)
    assert errors["median"] == pytest.approx(0.75)
    assert errors["rmse"] == pytest.approx(math.sqrt(1.3125))
    assert all(type(v) is float for v in errors.values())


def test_eol_error_sign():
    # predicted - true: 105 - 100 = +5 s (late), 95 - 100 = -5 s (early)
    assert eol_error(105.0, 100.0) == pytest.approx(5.0)
    assert eol_error(95.0, 100.0) == pytest.approx(-5.0)


# ------------------------------------------------------------------------------------------------
# alpha-lambda
# ------------------------------------------------------------------------------------------------


def test_alpha_lambda_passes_with_10_percent_overestimate():
    # t_P = 0, EoL = 100, lam = 0.5 -> t_lambda = 0 + 0.5 * (100 - 0) = 50 s (a prediction time)
    # rul_true(50) = 50; bounds (1 -/+ 0.2) * 50 = [40, 60]; rul_pred = 1.1 * 50 = 55 -> inside
    result = alpha_lambda(T, 1.1 * RUL_TRUE, RUL_TRUE, alpha=0.2, lam=0.5, eol=EOL)
    assert result["t_lambda"] == pytest.approx(50.0)
    assert result["t_prediction"] == pytest.approx(50.0)
    assert result["rul_true"] == pytest.approx(50.0)
    assert result["rul_pred"] == pytest.approx(55.0)
    assert result["lower"] == pytest.approx(40.0)
    assert result["upper"] == pytest.approx(60.0)
    assert result["passed"] is True


def test_alpha_lambda_fails_with_30_percent_overestimate():
    # same t_lambda = 50 s, bounds [40, 60]; rul_pred = 1.3 * 50 = 65 > 60 -> fails
    result = alpha_lambda(T, 1.3 * RUL_TRUE, RUL_TRUE, alpha=0.2, lam=0.5, eol=EOL)
    assert result["t_lambda"] == pytest.approx(50.0)
    assert result["rul_pred"] == pytest.approx(65.0)
    assert result["passed"] is False


def test_alpha_lambda_defaults_infer_eol_and_t_start():
    # eol defaults to t[0] + rul_true[0] = 0 + 100, t_P to t[0] = 0 -> t_lambda = 50 again
    result = alpha_lambda(T, 1.1 * RUL_TRUE, RUL_TRUE)
    assert result["t_lambda"] == pytest.approx(50.0)
    assert result["passed"] is True


def test_alpha_lambda_uses_first_prediction_at_or_after_t_lambda():
    # lam = 0.55 -> t_lambda = 55 s, first prediction time >= 55 is 60 s:
    # rul_true(60) = 40, bounds [32, 48], rul_pred = 1.1 * 40 = 44 -> pass
    result = alpha_lambda(T, 1.1 * RUL_TRUE, RUL_TRUE, alpha=0.2, lam=0.55, eol=EOL)
    assert result["t_lambda"] == pytest.approx(55.0)
    assert result["t_prediction"] == pytest.approx(60.0)
    assert result["rul_true"] == pytest.approx(40.0)
    assert (result["lower"], result["upper"]) == pytest.approx((32.0, 48.0))
    assert result["passed"] is True


def test_alpha_lambda_rounding_of_t_lambda_does_not_skip_a_prediction():
    # EoL = 7 s, lam = 0.1: t_lambda = 0.1 * 7 = 0.7000000000000001 in floating point, just above the
    # prediction time 0.7 s, which must still be the one used (not 1.4 s)
    t = np.array([0.0, 0.7, 1.4, 2.1])
    assert 0.1 * 7.0 > 0.7
    result = alpha_lambda(t, 7.0 - t, 7.0 - t, lam=0.1, eol=7.0)
    assert result["t_prediction"] == 0.7


def test_alpha_lambda_t_start():
    # t_P = 20 -> t_lambda = 20 + 0.5 * (100 - 20) = 60 s; rul_true(60) = 40, 1.3 * 40 = 52 > 48 -> fail
    result = alpha_lambda(T, 1.3 * RUL_TRUE, RUL_TRUE, t_start=20.0, eol=EOL)
    assert result["t_lambda"] == pytest.approx(60.0)
    assert result["t_prediction"] == pytest.approx(60.0)
    assert result["passed"] is False


def test_alpha_lambda_no_prediction_after_t_lambda():
    # lam = 0.95 -> t_lambda = 95 s > last prediction time 90 s
    with pytest.raises(ValueError, match="t_lambda"):
        alpha_lambda(T, RUL_TRUE, RUL_TRUE, lam=0.95, eol=EOL)


# ------------------------------------------------------------------------------------------------
# prognostic horizon
# ------------------------------------------------------------------------------------------------


def test_prognostic_horizon_enters_cone_at_40():
    # cone: rul_true +/- alpha * EoL = rul_true +/- 0.2 * 100 = +/- 20 s
    # error +30 s at t = 0..30 (outside), +10 s from t = 40 on (inside) -> PH = 100 - 40 = 60 s
    rul_pred = RUL_TRUE + np.where(T < 40, 30.0, 10.0)
    assert prognostic_horizon(T, rul_pred, RUL_TRUE, alpha=0.2, eol=EOL) == pytest.approx(60.0)


def test_prognostic_horizon_counts_from_last_entry():
    # inside at t = 0, 10, 20 (+10), outside at 30 (-25), inside from 40 on (+10):
    # predictions stay inside only from t = 40 -> PH = 60 s
    errors = np.array([10, 10, 10, -25, 10, 10, 10, 10, 10, 10], dtype=float)
    assert prognostic_horizon(T, RUL_TRUE + errors, RUL_TRUE, alpha=0.2, eol=EOL) == pytest.approx(60.0)


def test_prognostic_horizon_zero_when_last_prediction_outside():
    # +10 s (inside) everywhere except +25 s (outside the +/- 20 s cone) at the last time t = 90 -> PH = 0
    errors = np.full(T.shape, 10.0)
    errors[-1] = 25.0
    assert prognostic_horizon(T, RUL_TRUE + errors, RUL_TRUE, alpha=0.2, eol=EOL) == 0.0


def test_prognostic_horizon_perfect_predictor():
    # always inside -> first time is t[0] = 0 -> PH = 100 - 0 = 100 s; eol inferred as 0 + 100
    assert prognostic_horizon(T, RUL_TRUE, RUL_TRUE) == pytest.approx(100.0)


def test_prognostic_horizon_cone_is_absolute_not_relative():
    # at t = 80 rul_true = 20; a +15 s error is 75 % relative but inside the absolute +/- 20 s cone.
    # errors +15 s from t = 0 on -> all inside -> PH = 100 s (a relative 20 % cone would give 0 there)
    assert prognostic_horizon(T, RUL_TRUE + 15.0, RUL_TRUE, alpha=0.2, eol=EOL) == pytest.approx(100.0)


# ------------------------------------------------------------------------------------------------
# relative accuracy and CRA
# ------------------------------------------------------------------------------------------------

# 4-point case: EoL = 40, t = 0, 10, 20, 30, rul_true = 40, 30, 20, 10, rul_pred = 44, 27, 20, 15
# RA_i = 1 - |rul_true - rul_pred| / rul_true:
#   t=0:  1 - 4/40 = 0.9;  t=10: 1 - 3/30 = 0.9;  t=20: 1 - 0/20 = 1.0;  t=30: 1 - 5/10 = 0.5
T4 = np.array([0.0, 10.0, 20.0, 30.0])
RUL_TRUE4 = np.array([40.0, 30.0, 20.0, 10.0])
RUL_PRED4 = np.array([44.0, 27.0, 20.0, 15.0])


def test_relative_accuracy_hand_numbers():
    assert relative_accuracy(T4, RUL_PRED4, RUL_TRUE4, at=0.0) == pytest.approx(0.9)
    assert relative_accuracy(T4, RUL_PRED4, RUL_TRUE4, at=10.0) == pytest.approx(0.9)
    assert relative_accuracy(T4, RUL_PRED4, RUL_TRUE4, at=20.0) == pytest.approx(1.0)
    assert relative_accuracy(T4, RUL_PRED4, RUL_TRUE4, at=30.0) == pytest.approx(0.5)


def test_relative_accuracy_nearest_prediction_time():
    # at = 12 -> nearest t = 10 -> 0.9; at = 27 -> nearest t = 30 -> 0.5; at = 25 is a tie -> earlier t = 20 -> 1.0
    assert relative_accuracy(T4, RUL_PRED4, RUL_TRUE4, at=12.0) == pytest.approx(0.9)
    assert relative_accuracy(T4, RUL_PRED4, RUL_TRUE4, at=27.0) == pytest.approx(0.5)
    assert relative_accuracy(T4, RUL_PRED4, RUL_TRUE4, at=25.0) == pytest.approx(1.0)


def test_relative_accuracy_at_t_lambda_of_the_10_percent_predictor():
    # t = 50: rul_true 50, rul_pred 55 -> 1 - 5/50 = 0.9; t = 80: rul_true 20, pred 26 -> 1 - 6/20 = 0.7
    rul_pred = RUL_TRUE.copy()
    rul_pred[5] = 55.0
    rul_pred[8] = 26.0
    assert relative_accuracy(T, rul_pred, RUL_TRUE, at=50.0) == pytest.approx(0.9)
    assert relative_accuracy(T, rul_pred, RUL_TRUE, at=80.0) == pytest.approx(0.7)


def test_relative_accuracy_can_be_negative():
    # rul_true 10, rul_pred 25 -> 1 - 15/10 = -0.5
    assert relative_accuracy([0.0], [25.0], [10.0], at=0.0) == pytest.approx(-0.5)


def test_relative_accuracy_undefined_at_eol():
    with pytest.raises(ValueError, match="rul_true"):
        relative_accuracy([0.0, 10.0], [10.0, 1.0], [10.0, 0.0], at=10.0)


def test_relative_accuracy_at_outside_range():
    with pytest.raises(ValueError, match="at"):
        relative_accuracy(T4, RUL_PRED4, RUL_TRUE4, at=45.0)


def test_cra_is_mean_of_hand_ras():
    # (0.9 + 0.9 + 1.0 + 0.5) / 4 = 3.3 / 4 = 0.825
    assert cumulative_relative_accuracy(T4, RUL_PRED4, RUL_TRUE4) == pytest.approx(0.825)


def test_cra_weights_are_normalised():
    # weights 1, 1, 1, 2: (0.9 + 0.9 + 1.0 + 2 * 0.5) / 5 = 3.8 / 5 = 0.76; scaling the weights changes nothing
    assert cumulative_relative_accuracy(T4, RUL_PRED4, RUL_TRUE4, weights=[1, 1, 1, 2]) == pytest.approx(0.76)
    assert cumulative_relative_accuracy(T4, RUL_PRED4, RUL_TRUE4, weights=[2, 2, 2, 4]) == pytest.approx(0.76)


def test_cra_excludes_points_at_or_after_eol():
    # add t = 40 (rul_true = 0) and t = 50 (rul_true = -10): excluded -> still 0.825
    t = np.append(T4, [40.0, 50.0])
    rul_true = np.append(RUL_TRUE4, [0.0, -10.0])
    rul_pred = np.append(RUL_PRED4, [3.0, 7.0])
    assert cumulative_relative_accuracy(t, rul_pred, rul_true) == pytest.approx(0.825)


def test_rul_errors_reuse_estimation_errors():
    # e = rul_pred - rul_true = [4, -3, 0, 5], |e| = [4, 3, 0, 5]
    # max 5; median (3 + 4) / 2 = 3.5; rmse sqrt((16 + 9 + 0 + 25) / 4) = sqrt(12.5)
    errors = rul_errors(RUL_PRED4, RUL_TRUE4)
    assert errors == pytest.approx({"max": 5.0, "median": 3.5, "rmse": math.sqrt(12.5)})
    assert errors == estimation_errors(RUL_PRED4, RUL_TRUE4)


# ------------------------------------------------------------------------------------------------
# report
# ------------------------------------------------------------------------------------------------


def test_prognostic_report_10_percent_predictor():
    # rul_pred = 1.1 * rul_true: error 0.1 * rul_true = 10, 9, ..., 1 s
    # alpha-lambda: passes at t_lambda = 50 (see above)
    # PH: all errors <= 20 s (cone 0.2 * 100) -> PH = 100 - 0 = 100 s
    # RA at t = 50: 1 - 5/50 = 0.9; every RA_i = 1 - 0.1 = 0.9 -> CRA = 0.9
    # rul errors: max 10; median of 1..10 = (5 + 6) / 2 = 5.5; rmse = sqrt((1 + 4 + ... + 100) / 10) = sqrt(38.5)
    report = prognostic_report(T, 1.1 * RUL_TRUE, RUL_TRUE, eol=EOL, alpha=0.2, lam=0.5)
    assert report["alpha_lambda"]["t_lambda"] == pytest.approx(50.0)
    assert report["alpha_lambda"]["passed"] is True
    assert report["prognostic_horizon"] == pytest.approx(100.0)
    assert report["relative_accuracy"] == pytest.approx(0.9)
    assert report["cumulative_relative_accuracy"] == pytest.approx(0.9)
    assert report["rul_errors"] == pytest.approx({"max": 10.0, "median": 5.5, "rmse": math.sqrt(38.5)})
    assert report["eol"] == EOL

    # JSON round trip, and only plain Python types inside
    assert json.loads(json.dumps(report)) == report

    def plain(value):
        if isinstance(value, dict):
            return all(isinstance(k, str) and plain(v) for k, v in value.items())
        return value is None or type(value) in (float, bool)

    assert plain(report)


# ------------------------------------------------------------------------------------------------
# invalid inputs
# ------------------------------------------------------------------------------------------------


def test_confusion_matrix_unknown_label_named():
    with pytest.raises(ValueError, match=r"predicted_labels.*'D'"):
        confusion_matrix(["A", "B"], ["A", "D"], CLASSES)
    with pytest.raises(ValueError, match=r"true_labels.*'X'"):
        confusion_matrix(["X", "B"], ["A", "B"], CLASSES)


def test_confusion_matrix_invalid():
    with pytest.raises(ValueError, match="predicted_labels"):
        confusion_matrix(["A", "B"], ["A"], CLASSES)
    with pytest.raises(ValueError, match="true_labels is empty"):
        confusion_matrix([], [], CLASSES)
    with pytest.raises(ValueError, match="true_labels"):
        confusion_matrix(["A", float("nan")], ["A", "B"], CLASSES)
    with pytest.raises(ValueError, match="classes"):
        confusion_matrix(["A"], ["A"], ["A", "A"])


def test_isolation_accuracy_invalid():
    with pytest.raises(ValueError, match="predicted"):
        isolation_accuracy(["A", "B"], ["A"])
    with pytest.raises(ValueError, match="true is empty"):
        isolation_accuracy([], [])


def test_per_class_accuracy_invalid():
    with pytest.raises(ValueError, match="classes"):
        per_class_accuracy(np.eye(3), ["A", "B"])
    with pytest.raises(ValueError, match="matrix"):
        per_class_accuracy(np.ones((2, 3)), ["A", "B"])
    with pytest.raises(ValueError, match="matrix"):
        per_class_accuracy(np.array([[1.0, np.nan], [0.0, 1.0]]), ["A", "B"])


def test_estimation_errors_invalid():
    with pytest.raises(ValueError, match="length mismatch.*estimate.*truth"):
        estimation_errors([1.0, 2.0], [1.0])
    with pytest.raises(ValueError, match="estimate contains NaN"):
        estimation_errors([1.0, np.nan], [1.0, 2.0])
    with pytest.raises(ValueError, match="estimate is empty"):
        estimation_errors([], [1.0])
    with pytest.raises(ValueError, match="truth is empty"):
        estimation_errors([1.0], [])


def test_eol_error_invalid():
    with pytest.raises(ValueError, match="true_eol"):
        eol_error(100.0, float("nan"))
    with pytest.raises(ValueError, match="predicted_eol"):
        eol_error(float("nan"), 100.0)


@pytest.mark.parametrize(
    "metric",
    [
        lambda t, p, r: alpha_lambda(t, p, r, eol=EOL),
        lambda t, p, r: prognostic_horizon(t, p, r, eol=EOL),
        lambda t, p, r: relative_accuracy(t, p, r, at=0.0),
        cumulative_relative_accuracy,
        lambda t, p, r: prognostic_report(t, p, r, eol=EOL),
    ],
    ids=["alpha_lambda", "prognostic_horizon", "relative_accuracy", "cra", "report"],
)
def test_rul_metrics_invalid_inputs(metric):
    with pytest.raises(ValueError, match="length mismatch.*rul_pred"):
        metric(T, RUL_TRUE[:-1], RUL_TRUE)
    with pytest.raises(ValueError, match="rul_pred contains NaN"):
        metric(T, np.where(T == 50, np.nan, RUL_TRUE), RUL_TRUE)
    with pytest.raises(ValueError, match="rul_true contains NaN"):
        metric(T, RUL_TRUE, np.where(T == 50, np.nan, RUL_TRUE))
    with pytest.raises(ValueError, match="t is empty"):
        metric([], [], [])
    with pytest.raises(ValueError, match="t must be strictly increasing"):
        metric(T[::-1], RUL_TRUE, RUL_TRUE)


def test_rul_errors_invalid_names_rul_arguments():
    with pytest.raises(ValueError, match="rul_true contains NaN"):
        rul_errors([1.0, 2.0], [1.0, np.nan])
    with pytest.raises(ValueError, match="length mismatch.*rul_pred.*rul_true"):
        rul_errors([1.0, 2.0], [1.0])


def test_invalid_parameters():
    with pytest.raises(ValueError, match="alpha"):
        alpha_lambda(T, RUL_TRUE, RUL_TRUE, alpha=0.0)
    with pytest.raises(ValueError, match="lam"):
        alpha_lambda(T, RUL_TRUE, RUL_TRUE, lam=1.5)
    with pytest.raises(ValueError, match="eol"):
        alpha_lambda(T, RUL_TRUE, RUL_TRUE, eol=float("nan"))
    with pytest.raises(ValueError, match="alpha"):
        prognostic_horizon(T, RUL_TRUE, RUL_TRUE, alpha=-0.1)
    with pytest.raises(ValueError, match="weights"):
        cumulative_relative_accuracy(T4, RUL_PRED4, RUL_TRUE4, weights=[1.0, -1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="weights"):
        cumulative_relative_accuracy(T4, RUL_PRED4, RUL_TRUE4, weights=[1.0, 1.0])
    with pytest.raises(ValueError, match="weights"):
        cumulative_relative_accuracy(T4, RUL_PRED4, RUL_TRUE4, weights=[1.0, np.nan, 1.0, 1.0])
