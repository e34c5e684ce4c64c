"""Commissioning: the healthy machine's own parameter values, fitted from its signals before any fault is sought.

A machine is not its catalogue values: each part sits somewhere within its tolerance. Taken for the nominal
model, such a machine shows EA residuals and filter innovations that the chain would read as a fault.
:func:`commission` runs the joint filter (:mod:`~ea_gym.phm.joint`) over healthy signals with every part held
constant (no drift, no random walk: its drift prior and both random walks zero), so that the filter is a
recursive least-squares fit of the constant values, and returns each part's value and standard deviation,
the values held within the safe limits. ``PHMChain.commission`` then makes them the chain's healthy machine:
the reference model is simulated with them (``PHMChain.reference_parameters``) and the joint filter starts
around them; faults are departures from the machine, not from the catalogue. A constant offset is not
"degrading" (the joint filter's degrading is drift-based), so a machine off nominal is not named either way;
commissioning makes its EA detection compare it with itself.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ea_gym.models import SystemModel
from ea_gym.phm.config import JointFilterConfig
from ea_gym.phm.estimation import StepSignals
from ea_gym.phm.joint import JointFilter

#: seconds of signal per update of the commissioning filter (its parameters' linearisation point moves once per step)
COMMISSIONING_STEP = 1.0
#: passes over the signals: the first one's early samples are taken through a model linearised about the nominal
#: values, up to a quarter of the span away, and with no process noise what they taught is never unlearnt; the
#: second pass starts from the first's values (the RLC circuit's C1, seeds 20-24: |error| / std up to 4.6 in one
#: pass, within 3 in two)
PASSES = 2


@dataclass(frozen=True)
class Commissioning:
    """The healthy machines' own values.

    Attributes:
        names: the parts (degradable parameters), D of them.
        value: each part's fitted constant value (its SI unit), within its safe limits, (N, D).
        std: its standard deviation (SI), (N, D).
    """

    names: tuple[str, ...]
    value: np.ndarray
    std: np.ndarray


def commission(
    model: SystemModel, measured: np.ndarray, load: np.ndarray, load_rate: np.ndarray, sample_rate: float, noise: float,
    load_noise: float = 0.0, config: JointFilterConfig | None = None,
) -> Commissioning:
    """Fit every degradable part's constant value of N healthy machines from their signals.

    Args:
        model: the monitored system (nominal values, safe limits).
        measured: each machine's measured signals (flows of I, displacements of C in ``model.state_names`` order),
            (N, nx, T) sampled at ``sample_rate`` (Hz), from a healthy stretch.
        load, load_rate: the load source's value and its time derivative (unit/s), (N, T).
        noise: the sensors' noise std, fraction of each signal's RMS over a second; load_noise: the load's.
        config: the joint filter's settings (its drift and random walks are set to zero here); default
            ``JointFilterConfig()``.

    Returns:
        each part's value (held within its safe limits) and standard deviation, (N, D) each.

    Raises:
        ValueError: signals of the wrong shape, or too short for one step of ``COMMISSIONING_STEP`` s.
    """
    measured = np.asarray(measured, dtype=float)
    load, load_rate = np.asarray(load, dtype=float), np.asarray(load_rate, dtype=float)
    nx = len(model.state_names)
    if measured.ndim != 3 or measured.shape[1] != nx:
        raise ValueError(f"measured must be (N, nx={nx}, T) signals, got shape {measured.shape}")
    n, _, samples = measured.shape
    if load.shape != (n, samples) or load_rate.shape != (n, samples):
        raise ValueError(f"load and load_rate must be (N, T) = {(n, samples)}, got {load.shape} and {load_rate.shape}")
    if not (math.isfinite(sample_rate) and sample_rate > 0):
        raise ValueError(f"sample_rate must be a finite number of Hz > 0, got {sample_rate!r}")
    step = max(1, round(COMMISSIONING_STEP * sample_rate))
    if samples < step + 1:
        raise ValueError(f"measured: {samples} samples; commissioning needs at least {step + 1} ({COMMISSIONING_STEP:g} s at {sample_rate:g} Hz)")
    constant = dataclasses.replace(
        config or JointFilterConfig(), theta_noise=0.0, drift_noise=0.0, drift_prior=0.0, commissioned_drift_prior=0.0, onset_threshold=math.inf
    )
    joint = JointFilter(model, sample_rate, noise, n, config=constant, load_noise=load_noise)
    alarm, suspects = np.zeros(n, dtype=bool), np.ones((n, len(joint.degradable)), dtype=bool)
    for _ in range(PASSES):
        for start in range(0, samples - 1, step):
            part = slice(start, min(start + step + 1, samples))
            t = np.full(n, (part.stop - 1) / sample_rate)
            joint.update(StepSignals(measured=measured[..., part], load=load[:, part], load_rate=load_rate[:, part], t=t), alarm, suspects)
        estimates = joint.estimates(np.full(n, (samples - 1) / sample_rate))
        # the next pass linearises about this one's values from the first sample on, its prior as wide as the first's
        joint.commission(estimates.value, joint.config.theta_prior * joint.span)
    limits = np.array([model.safe_limits[name] for name in joint.degradable], dtype=float)
    return Commissioning(
        names=joint.degradable, value=np.clip(estimates.value, limits[:, 0], limits[:, 1]), std=np.sqrt(estimates.variance)
    )
