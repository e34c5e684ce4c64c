"""Estimation: the ``ParameterEstimator`` seam, what every parameter estimator takes and gives.

An estimator follows, for every system, each degradable parameter as if it alone were faulty, and
says how well each hypothesis ("none" first) explains the measurements. The chain tells it at every
step which hypotheses to estimate (all of them until the isolation is confident of a suspect, then the
suspect alone), and logs maintenance that moved a parameter.

The implementations (the EA inversion of :mod:`~ea_gym.phm.inversion_estimator`, the tracking
filters of :mod:`~ea_gym.phm.tracking`, the joint filter of :mod:`~ea_gym.phm.joint`, which estimates
every parameter at once and says how likely each is to be degrading) register with
:mod:`~ea_gym.phm.registry`, which pairs each with its prognosis.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ea_gym.diagnosis.database import classes_of
from ea_gym.models import SystemModel


@dataclass(frozen=True)
class StepSignals:
    """One step of signals, N systems.

    Attributes:
        measured: noisy measured signals (flows of I, displacements of C), (N, nx, L + 1).
        load, load_rate: the source's value and time derivative, (N, L + 1).
        t: time at the end of the step (s), (N,).
    """

    measured: np.ndarray
    load: np.ndarray
    load_rate: np.ndarray
    t: np.ndarray


@dataclass(frozen=True)
class ParameterEstimates:
    """An estimator's output after one step, N systems and D degradable parameters.

    Attributes:
        value: estimate of each degradable parameter (SI), each as if it alone were faulty (all at once for
            the joint filter), (N, D).
        variance: its variance, NaN where the estimator has none, (N, D).
        drift: its rate of change (unit/s), NaN where none, (N, D); drift_variance: its variance, (N, D).
        log_evidence: log-likelihood-like evidence of "none" then each hypothesis, larger is better,
            NaN where not yet fitted, (N, D + 1).
        covariance: the covariance of each value and its drift (unit^2/s), NaN where none, (N, D).
        estimated: which hypotheses were updated at this step, (N, D).
        time: the time each value describes (s), (N, D).
        degrading: each parameter's probability of drifting (of wearing), (N, D), from an estimator that
            estimates every parameter at once (the "joint" filter); None from the others.
    """

    value: np.ndarray
    variance: np.ndarray
    drift: np.ndarray
    drift_variance: np.ndarray
    covariance: np.ndarray
    log_evidence: np.ndarray
    estimated: np.ndarray
    time: np.ndarray
    degrading: np.ndarray | None = None


class ParameterEstimator(Protocol):
    """Follows every degradable parameter of N systems, each as if it alone were faulty.

    Attributes:
        degradable: the parameters, the isolation's fault classes in order.
        lag: its estimates describe the parameters so many seconds before the step's end (s).
        warmup_steps: updates after a reset before its first estimate.
    """

    degradable: tuple[str, ...]
    lag: float
    warmup_steps: int

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Start over for all systems (None), or for those where the boolean mask (N,) is true."""

    def record_adjustment(self, systems: np.ndarray, parameters: np.ndarray, changes: np.ndarray) -> None:
        """Log maintenance that moved degradable parameter ``parameters[k]`` of system ``systems[k]`` by
        ``changes[k]`` (its SI unit) before the next update: the estimates so far are shifted by it."""

    def restart(self, systems: np.ndarray, parameters: np.ndarray) -> None:
        """Forget what hypothesis ``parameters[k]`` of system ``systems[k]`` has learned: it became the
        suspect without being estimated at this step, so its estimates are stale."""

    def update(self, signals: StepSignals, alarm: np.ndarray, suspects: np.ndarray) -> ParameterEstimates:
        """Process one step; ``alarm`` (N,): a fault is detected; ``suspects`` (N, D): the hypotheses to estimate."""


def checked_arguments(
    model: SystemModel, degradable: Sequence[str] | None, sample_rate: float, noise: float, n_systems: int
) -> tuple[str, ...]:
    """An estimator's parameters (default: the isolation classes', every one with safe limits), its sample rate
    (Hz), noise fraction and N checked.

    Raises:
        ValueError: a parameter that is not the model's or has no safe limits; a sample rate not > 0, a
            negative noise fraction, or N < 1.
    """
    names = tuple(degradable) if degradable is not None else classes_of(model)[1:]
    for name in names:
        model.check_name(name, "degradable")
        if name not in model.safe_limits:
            raise ValueError(f"degradable: {name!r} has no safe limits in model {model.name!r}")
    if not (math.isfinite(sample_rate) and sample_rate > 0):
        raise ValueError(f"sample_rate must be a finite number of Hz > 0, got {sample_rate!r}")
    if not (math.isfinite(noise) and noise >= 0):
        raise ValueError(f"noise must be a finite fraction >= 0, got {noise!r}")
    if n_systems < 1:
        raise ValueError(f"n_systems must be >= 1, got {n_systems!r}")
    return names


def checked_signals(signals: StepSignals, n: int, nx: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A step's measured signals (N, nx, L + 1), load and its rate (N, L + 1) and end times (N,), as contiguous
    float arrays, their shapes checked against N = ``n`` systems of ``nx`` signals."""
    measured = np.ascontiguousarray(signals.measured, dtype=float)
    if measured.ndim != 3 or measured.shape[:2] != (n, nx):
        raise ValueError(f"signals.measured must be (N={n}, nx={nx}, L + 1), got {measured.shape}")
    load, load_rate = np.ascontiguousarray(signals.load, dtype=float), np.ascontiguousarray(signals.load_rate, dtype=float)
    if load.shape != (n, measured.shape[2]) or load_rate.shape != (n, measured.shape[2]):
        raise ValueError(f"signals.load and load_rate must be (N={n}, L + 1 = {measured.shape[2]})")
    t = np.ascontiguousarray(signals.t, dtype=float)
    if t.shape != (n,):
        raise ValueError(f"signals.t must be (N={n},), got {t.shape}")
    return measured, load, load_rate, t
