"""Isolation, estimation and prognostic metrics (pure numpy).

Three families:

* Isolation: :func:`confusion_matrix`, :func:`isolation_accuracy`, :func:`per_class_accuracy` on fault
  labels (strings).
* Estimation: :func:`estimation_errors` between an estimated and a true parameter trajectory sampled
  at the same times (errors in the parameter's SI unit), and :func:`eol_error` on the end-of-life time.
* Prognostics, after Saxena, Celaya, Saha, Saha and Goebel, "Metrics for Offline Evaluation of
  Prognostic Performance", IJPHM 1(1), 2010: :func:`alpha_lambda`, :func:`prognostic_horizon`,
  :func:`relative_accuracy`, :func:`cumulative_relative_accuracy`, :func:`rul_errors` and the bundle
  :func:`prognostic_report`.

Conventions for the prognostic metrics: all times are absolute times in s on one clock (the same
clock as the end of life, EoL, in s); predictions are point predictions of the remaining useful life
(RUL, in s) ``rul_pred[i]`` made at the prediction time ``t[i]`` (strictly increasing), and
``rul_true[i]`` is the true RUL at ``t[i]`` (normally ``EoL - t[i]``). Every metric is computed on the
RUL, not on the predicted event time. The paper's probability-mass criterion (beta) reduces, for point
predictions, to "the prediction lies inside the bounds"; bounds are inclusive.

Every function validates its inputs and raises ``ValueError`` naming the offending argument for empty
arrays, arrays that are not 1-D, mismatched lengths and NaN (or infinite) values.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = [
    "alpha_lambda",
    "confusion_matrix",
    "cumulative_relative_accuracy",
    "eol_error",
    "estimation_errors",
    "isolation_accuracy",
    "per_class_accuracy",
    "prognostic_horizon",
    "prognostic_report",
    "relative_accuracy",
    "rul_errors",
]


# --------------------------------------------------------------------------------------------------
# validation helpers
# --------------------------------------------------------------------------------------------------


def _as_1d(name: str, values: Any) -> np.ndarray:
    """``values`` as a non-empty 1-D float array of finite numbers, or ValueError naming ``name``."""
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a 1-D array of numbers: {exc}") from exc
    if array.ndim != 1:
        raise ValueError(f"{name} must be 1-D, got shape {array.shape}")
    if array.size == 0:
        raise ValueError(f"{name} is empty")
    if np.isnan(array).any():
        raise ValueError(f"{name} contains NaN at index {int(np.flatnonzero(np.isnan(array))[0])}")
    if not np.isfinite(array).all():
        raise ValueError(f"{name} contains an infinite value at index {int(np.flatnonzero(~np.isfinite(array))[0])}")
    return array


def _as_scalar(name: str, value: Any) -> float:
    """``value`` as a finite float, or ValueError naming ``name``."""
    try:
        number = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a number, got {value!r}") from exc
    if np.isnan(number):
        raise ValueError(f"{name} is NaN")
    if not np.isfinite(number):
        raise ValueError(f"{name} is infinite")
    return number


def _same_length(**arrays: np.ndarray) -> None:
    """ValueError naming the arrays when their lengths differ."""
    lengths = {name: len(array) for name, array in arrays.items()}
    if len(set(lengths.values())) > 1:
        detail = ", ".join(f"{name} has {n}" for name, n in lengths.items())
        raise ValueError(f"length mismatch: {detail}")


def _labels(name: str, labels: Sequence[Any]) -> list[Any]:
    """``labels`` as a non-empty list without NaN, or ValueError naming ``name``."""
    if isinstance(labels, str):
        raise ValueError(f"{name} must be a sequence of labels, not a single string")
    values = list(np.asarray(labels, dtype=object).ravel()) if isinstance(labels, np.ndarray) else list(labels)
    if not values:
        raise ValueError(f"{name} is empty")
    for i, value in enumerate(values):
        if value is None or (isinstance(value, (float, np.floating)) and np.isnan(value)):
            raise ValueError(f"{name} contains a missing label (None/NaN) at index {i}")
    return values


def _rul_inputs(t: Any, rul_pred: Any, rul_true: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validated (t, rul_pred, rul_true): finite, non-empty, same length, t strictly increasing."""
    t = _as_1d("t", t)
    rul_pred = _as_1d("rul_pred", rul_pred)
    rul_true = _as_1d("rul_true", rul_true)
    _same_length(t=t, rul_pred=rul_pred, rul_true=rul_true)
    if t.size > 1 and not np.all(np.diff(t) > 0):
        raise ValueError("t must be strictly increasing")
    return t, rul_pred, rul_true


def _alpha(alpha: Any) -> float:
    alpha = _as_scalar("alpha", alpha)
    if alpha <= 0:
        raise ValueError(f"alpha must be > 0, got {alpha}")
    return alpha


def _eol(eol: Any, t: np.ndarray, rul_true: np.ndarray) -> float:
    """The true end of life in s: ``eol`` when given, else ``t[0] + rul_true[0]``."""
    return float(t[0] + rul_true[0]) if eol is None else _as_scalar("eol", eol)


# --------------------------------------------------------------------------------------------------
# isolation
# --------------------------------------------------------------------------------------------------


def confusion_matrix(
    true_labels: Sequence[str], predicted_labels: Sequence[str], classes: Sequence[str]
) -> np.ndarray:
    """Confusion matrix of a fault-isolation result.

    Args:
        true_labels: the true class of each case (one label per case).
        predicted_labels: the isolated class of each case, same length as ``true_labels``.
        classes: the class names; they fix the order of the rows and columns.

    Returns:
        Integer array ``M`` of shape ``(len(classes), len(classes))``: ``M[i, j]`` counts the cases
        whose true class is ``classes[i]`` (rows) and predicted class is ``classes[j]`` (columns).
        Dimensionless counts.

    Raises:
        ValueError: empty or mismatched inputs, missing (None/NaN) labels, duplicate or empty
            ``classes``, or a label not in ``classes`` (the message names the label and argument).
    """
    class_list = _labels("classes", classes)
    if len(set(class_list)) != len(class_list):
        raise ValueError(f"classes contains duplicates: {class_list}")
    index = {name: i for i, name in enumerate(class_list)}
    true_list = _labels("true_labels", true_labels)
    predicted_list = _labels("predicted_labels", predicted_labels)
    if len(true_list) != len(predicted_list):
        raise ValueError(
            f"length mismatch: true_labels has {len(true_list)}, predicted_labels has {len(predicted_list)}"
        )
    matrix = np.zeros((len(class_list), len(class_list)), dtype=np.int64)
    for name, labels in (("true_labels", true_list), ("predicted_labels", predicted_list)):
        for label in labels:
            if label not in index:
                raise ValueError(f"{name} contains unknown label {label!r} (classes: {class_list})")
    for true, predicted in zip(true_list, predicted_list):
        matrix[index[true], index[predicted]] += 1
    return matrix


def isolation_accuracy(true: Sequence[str], predicted: Sequence[str]) -> float:
    """Fraction of cases whose predicted label equals the true label (dimensionless, in [0, 1]).

    Args:
        true: the true label of each case.
        predicted: the isolated label of each case, same length as ``true``.
    """
    true_list = _labels("true", true)
    predicted_list = _labels("predicted", predicted)
    if len(true_list) != len(predicted_list):
        raise ValueError(f"length mismatch: true has {len(true_list)}, predicted has {len(predicted_list)}")
    return float(sum(a == b for a, b in zip(true_list, predicted_list)) / len(true_list))


def per_class_accuracy(matrix: np.ndarray, classes: Sequence[str]) -> dict[str, float]:
    """Per-class accuracy (recall) from a confusion matrix: ``M[i, i] / sum_j M[i, j]``.

    Args:
        matrix: square confusion matrix as returned by :func:`confusion_matrix` (rows true,
            columns predicted, non-negative counts).
        classes: the class names in the matrix's row order.

    Returns:
        ``{class: accuracy}`` (dimensionless, in [0, 1]); a class with no true cases (empty row)
        gets ``nan``.
    """
    class_list = _labels("classes", classes)
    try:
        counts = np.asarray(matrix, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"matrix must be a numeric array: {exc}") from exc
    if counts.ndim != 2 or counts.shape[0] != counts.shape[1]:
        raise ValueError(f"matrix must be square, got shape {counts.shape}")
    if counts.size == 0:
        raise ValueError("matrix is empty")
    if counts.shape[0] != len(class_list):
        raise ValueError(
            f"length mismatch: matrix is {counts.shape[0]}x{counts.shape[1]}, classes has {len(class_list)}"
        )
    if np.isnan(counts).any():
        raise ValueError("matrix contains NaN")
    if not np.isfinite(counts).all() or (counts < 0).any():
        raise ValueError("matrix must hold finite, non-negative counts")
    totals = counts.sum(axis=1)
    return {
        str(name): (float(counts[i, i] / totals[i]) if totals[i] > 0 else float("nan"))
        for i, name in enumerate(class_list)
    }


# --------------------------------------------------------------------------------------------------
# estimation
# --------------------------------------------------------------------------------------------------


def estimation_errors(estimate: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    """Error statistics of an estimate against the truth sampled at the same times.

    Args:
        estimate: estimated values (a parameter in its SI unit, or a RUL in s), 1-D.
        truth: true values at the same times, same unit and length.

    Returns:
        ``{"max": max |e|, "median": median |e|, "rmse": sqrt(mean e^2)}`` with
        ``e = estimate - truth``, all in the unit of the inputs.
    """
    estimate = _as_1d("estimate", estimate)
    truth = _as_1d("truth", truth)
    _same_length(estimate=estimate, truth=truth)
    error = estimate - truth
    absolute = np.abs(error)
    return {
        "max": float(absolute.max()),
        "median": float(np.median(absolute)),
        "rmse": float(np.sqrt(np.mean(error**2))),
    }


def eol_error(predicted_eol: float, true_eol: float) -> float:
    """End-of-life error ``predicted_eol - true_eol`` in s (positive: predicted too late)."""
    return _as_scalar("predicted_eol", predicted_eol) - _as_scalar("true_eol", true_eol)


# --------------------------------------------------------------------------------------------------
# prognostics (Saxena et al. 2010), on the RUL
# --------------------------------------------------------------------------------------------------


def rul_errors(rul_pred: np.ndarray, rul_true: np.ndarray) -> dict[str, float]:
    """RUL error statistics: :func:`estimation_errors` of ``rul_pred`` against ``rul_true`` (all in s).

    Returns:
        ``{"max", "median", "rmse"}`` of ``rul_pred - rul_true`` in s.
    """
    rul_pred = _as_1d("rul_pred", rul_pred)
    rul_true = _as_1d("rul_true", rul_true)
    _same_length(rul_pred=rul_pred, rul_true=rul_true)
    return estimation_errors(rul_pred, rul_true)


def alpha_lambda(
    t: np.ndarray,
    rul_pred: np.ndarray,
    rul_true: np.ndarray,
    alpha: float = 0.2,
    lam: float = 0.5,
    t_start: float | None = None,
    eol: float | None = None,
) -> dict[str, Any]:
    """Alpha-lambda accuracy (Saxena et al. 2010, sec. "alpha-lambda performance") for point predictions.

    ``t_lambda = t_P + lam * (EoL - t_P)`` (s) with ``t_P = t_start`` (default ``t[0]``, the first
    prediction time) and ``EoL = eol`` (default ``t[0] + rul_true[0]``). The prediction evaluated is the
    one made at the FIRST prediction time ``t[i] >= t_lambda`` (a time within ``1e-9`` relative of
    ``t_lambda`` counts as equal, to absorb rounding); no interpolation. It passes when
    ``(1 - alpha) * rul_true[i] <= rul_pred[i] <= (1 + alpha) * rul_true[i]`` (bounds inclusive,
    relative to the true RUL at that time).

    Args:
        t: prediction times in s, strictly increasing.
        rul_pred: predicted RUL at ``t`` in s.
        rul_true: true RUL at ``t`` in s.
        alpha: relative half-width of the accuracy cone (dimensionless, > 0).
        lam: fraction of the interval from ``t_P`` to EoL at which to evaluate (in [0, 1]).
        t_start: ``t_P`` in s (default ``t[0]``).
        eol: true end of life in s (default ``t[0] + rul_true[0]``); must be after ``t_P``.

    Returns:
        ``{"t_lambda": s, "t_prediction": s (the prediction time used), "rul_pred": s, "rul_true": s,
        "lower": s, "upper": s, "passed": bool}``.

    Raises:
        ValueError: invalid inputs, or no prediction at or after ``t_lambda``.
    """
    t, rul_pred, rul_true = _rul_inputs(t, rul_pred, rul_true)
    alpha = _alpha(alpha)
    lam = _as_scalar("lam", lam)
    if not 0.0 <= lam <= 1.0:
        raise ValueError(f"lam must be in [0, 1], got {lam}")
    t_p = float(t[0]) if t_start is None else _as_scalar("t_start", t_start)
    end = _eol(eol, t, rul_true)
    if end <= t_p:
        raise ValueError(f"eol ({end} s) must be after the first prediction time t_start ({t_p} s)")
    t_lambda = t_p + lam * (end - t_p)
    tolerance = 1e-9 * max(abs(t_lambda), end - t_p, 1.0)
    candidates = np.flatnonzero(t >= t_lambda - tolerance)
    if candidates.size == 0:
        raise ValueError(f"t has no prediction at or after t_lambda = {t_lambda} s (last is {t[-1]} s)")
    i = int(candidates[0])
    lower = (1.0 - alpha) * rul_true[i]
    upper = (1.0 + alpha) * rul_true[i]
    return {
        "t_lambda": float(t_lambda),
        "t_prediction": float(t[i]),
        "rul_pred": float(rul_pred[i]),
        "rul_true": float(rul_true[i]),
        "lower": float(lower),
        "upper": float(upper),
        "passed": bool(lower <= rul_pred[i] <= upper),
    }


def prognostic_horizon(
    t: np.ndarray,
    rul_pred: np.ndarray,
    rul_true: np.ndarray,
    alpha: float = 0.2,
    eol: float | None = None,
) -> float:
    """Prognostic horizon (Saxena et al. 2010) in s, for point predictions.

    Saxena's PH bounds are absolute: ``rul_true[j] - alpha * EoL <= rul_pred[j] <= rul_true[j] + alpha * EoL``
    (bounds inclusive), where EoL is the true end-of-life time in s on the clock of ``t`` (so the cone's
    half-width ``alpha * EoL`` assumes that clock starts at the beginning of life). The horizon is
    ``PH = EoL - t[i]`` where ``t[i]`` is the first prediction time from which ALL later predictions
    (``t[i]`` included) stay inside the bounds. If the last prediction is outside, no such time exists
    and PH is ``0.0``.

    Args:
        t: prediction times in s, strictly increasing.
        rul_pred: predicted RUL at ``t`` in s.
        rul_true: true RUL at ``t`` in s.
        alpha: accuracy as a fraction of EoL (dimensionless, > 0).
        eol: true end of life in s (default ``t[0] + rul_true[0]``).
    """
    t, rul_pred, rul_true = _rul_inputs(t, rul_pred, rul_true)
    alpha = _alpha(alpha)
    end = _eol(eol, t, rul_true)
    half_width = alpha * end
    inside = (rul_true - half_width <= rul_pred) & (rul_pred <= rul_true + half_width)
    if not inside[-1]:
        return 0.0
    outside = np.flatnonzero(~inside)
    i = 0 if outside.size == 0 else int(outside[-1]) + 1
    return float(end - t[i])


def relative_accuracy(t: np.ndarray, rul_pred: np.ndarray, rul_true: np.ndarray, at: float) -> float:
    """Relative accuracy (Saxena et al. 2010) ``RA = 1 - |rul_true - rul_pred| / rul_true`` (dimensionless).

    Evaluated at the prediction time nearest to ``at`` (exactly at ``at`` when it is a prediction time;
    a tie between two neighbours goes to the earlier one); no interpolation. RA is 1 for a perfect
    prediction and can be negative for errors larger than the true RUL.

    Args:
        t: prediction times in s, strictly increasing.
        rul_pred: predicted RUL at ``t`` in s.
        rul_true: true RUL at ``t`` in s.
        at: the evaluation time in s, within ``[t[0], t[-1]]`` (e.g. ``t_lambda``).

    Raises:
        ValueError: invalid inputs, ``at`` outside the prediction times, or ``rul_true <= 0`` at the
            selected time (RA undefined).
    """
    t, rul_pred, rul_true = _rul_inputs(t, rul_pred, rul_true)
    at = _as_scalar("at", at)
    tolerance = 1e-9 * max(abs(t[0]), abs(t[-1]), 1.0)
    if at < t[0] - tolerance or at > t[-1] + tolerance:
        raise ValueError(f"at = {at} s is outside the prediction times [{t[0]}, {t[-1]}] s")
    i = int(np.argmin(np.abs(t - at)))  # argmin returns the first (earlier) index on ties
    if rul_true[i] <= 0:
        raise ValueError(f"rul_true is {rul_true[i]} s <= 0 at t = {t[i]} s: relative accuracy undefined")
    return float(1.0 - abs(rul_true[i] - rul_pred[i]) / rul_true[i])


def cumulative_relative_accuracy(
    t: np.ndarray,
    rul_pred: np.ndarray,
    rul_true: np.ndarray,
    weights: np.ndarray | None = None,
) -> float:
    """Cumulative relative accuracy (Saxena et al. 2010): weighted mean of RA over the prediction times.

    ``CRA = sum_i w_i * RA_i / sum_i w_i`` over ALL prediction times with ``rul_true > 0`` (points with
    ``rul_true <= 0``, at or after EoL, are excluded since RA is undefined there); the weights are
    normalised over the included points. Dimensionless.

    Args:
        t: prediction times in s, strictly increasing.
        rul_pred: predicted RUL at ``t`` in s.
        rul_true: true RUL at ``t`` in s.
        weights: non-negative weight per prediction time (default uniform).

    Raises:
        ValueError: invalid inputs, no point with ``rul_true > 0``, or weights of the included points
            that sum to zero.
    """
    t, rul_pred, rul_true = _rul_inputs(t, rul_pred, rul_true)
    if weights is None:
        w = np.ones_like(t)
    else:
        w = _as_1d("weights", weights)
        _same_length(t=t, weights=w)
        if (w < 0).any():
            raise ValueError("weights must be non-negative")
    keep = rul_true > 0
    if not keep.any():
        raise ValueError("rul_true has no positive value: relative accuracy undefined everywhere")
    w = w[keep]
    if w.sum() <= 0:
        raise ValueError("weights sum to zero over the points with rul_true > 0")
    ra = 1.0 - np.abs(rul_true[keep] - rul_pred[keep]) / rul_true[keep]
    return float(np.sum(w * ra) / np.sum(w))


def prognostic_report(
    t: np.ndarray,
    rul_pred: np.ndarray,
    rul_true: np.ndarray,
    eol: float,
    alpha: float = 0.2,
    lam: float = 0.5,
) -> dict[str, Any]:
    """All prognostic metrics of one RUL prediction run, JSON-serialisable (plain floats, bools, dicts).

    Args:
        t: prediction times in s, strictly increasing (``t_P = t[0]``).
        rul_pred: predicted RUL at ``t`` in s.
        rul_true: true RUL at ``t`` in s.
        eol: true end of life in s.
        alpha: accuracy cone parameter, used both by alpha-lambda (relative) and PH (fraction of EoL).
        lam: alpha-lambda evaluation fraction.

    Returns:
        ``{"eol": s, "alpha", "lam", "alpha_lambda": dict (see :func:`alpha_lambda`),
        "prognostic_horizon": s, "relative_accuracy": RA at the alpha-lambda prediction time
        (``None`` when ``rul_true <= 0`` there), "cumulative_relative_accuracy",
        "rul_errors": {"max", "median", "rmse"} in s}``.
    """
    t, rul_pred, rul_true = _rul_inputs(t, rul_pred, rul_true)
    eol = _as_scalar("eol", eol)
    al = alpha_lambda(t, rul_pred, rul_true, alpha=alpha, lam=lam, eol=eol)
    ra = (
        relative_accuracy(t, rul_pred, rul_true, at=al["t_prediction"]) if al["rul_true"] > 0 else None
    )
    return {
        "eol": float(eol),
        "alpha": float(alpha),
        "lam": float(lam),
        "alpha_lambda": al,
        "prognostic_horizon": prognostic_horizon(t, rul_pred, rul_true, alpha=alpha, eol=eol),
        "relative_accuracy": ra,
        "cumulative_relative_accuracy": cumulative_relative_accuracy(t, rul_pred, rul_true),
        "rul_errors": rul_errors(rul_pred, rul_true),
    }
