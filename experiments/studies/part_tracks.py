"""Every part's track through an estimator, and its scores against a record's truth (issue 30's acceptance).

A :class:`PartTrack` holds, at the end of every 1 s step, each degradable part's estimate, its std, its
probability of degrading, whether it is named degrading, and its End of Life with the 95 % interval; and the
machine's alarm, isolated class and model-fit verdict. :func:`chain_track` reads it off the chain's statuses
(``HealthStatus.parts``), :func:`chain_run` runs the chain on a record as ``ea-gym phm --measurements`` does.

Scores, against the record's machine (``experiments/studies/records.py``):

* the set named (:func:`set_named_right`): at every counted step the parts named degrading are exactly those
  that wear; a step counts from ``SET_SETTLE`` s after the first onset, except the ``SET_SETTLE`` s after each
  later onset (a part starting to wear is not yet expected to be named);
* estimate errors (:func:`estimate_errors`): each part's |estimate - truth| at every step from ``SETTLE`` s
  after the first onset;
* prognosis (:func:`prognosis_hits`): every prediction of a wearing part from 50 to 90 % of the way from its
  onset to its End of Life (the time it reaches its safe limit): within +-20 % of the true RUL (alpha-lambda),
  and whether its 95 % interval is bounded and covers the true RUL; a missing prediction misses both;
* false alarms (:func:`first_alarm`, :func:`raised_by`): the first step with the detector's alarm, a part named, or an
  End of Life, and which of them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ea_gym.models import SystemModel
from ea_gym.phm import HealthStatus, PHMChain, build_chain, chain_config, classifier_for, commission, run_measurements
from experiments.studies.records import NOISE, Machine, Record, system_model

SETTLE = 10.0  # s after the first onset from which estimate errors count
SET_SETTLE = 30.0  # s after an onset before the named set is expected to hold it
ALPHA = 0.2
PREDICTION_SPAN = (0.5, 0.9)  # of the way from onset to End of Life


@dataclass(frozen=True)
class PartTrack:
    """One estimator on one record, at the end of every step (S steps, D degradable parts in the chain's order).

    Attributes:
        t: end of the step (s), (S,).
        parts: the degradable parts' names, (D,).
        value, std: each part's estimate and its std (SI), (S, D).
        degrading: each part's probability of degrading, (S, D); named: judged degrading, (S, D).
        eol, eol_low, eol_high: each part's End of Life and its interval (s), inf where none, (S, D).
        alarm: the detector's alarm, (S,); isolated: the isolated part's index in ``parts``, -1 for none, (S,).
        fits, misfit: the model-fit test's verdict ("fits", "does not fit"; neither: not known), (S,).
        machine_eol: the machine's End of Life (s), inf where none, (S,).
    """

    t: np.ndarray
    parts: tuple[str, ...]
    value: np.ndarray
    std: np.ndarray
    degrading: np.ndarray
    named: np.ndarray
    eol: np.ndarray
    eol_low: np.ndarray
    eol_high: np.ndarray
    alarm: np.ndarray
    isolated: np.ndarray
    fits: np.ndarray
    misfit: np.ndarray
    machine_eol: np.ndarray


def chain_track(chain: PHMChain, statuses: Sequence[HealthStatus]) -> PartTrack:
    """The per-part outputs (``HealthStatus.parts``) of a one-system chain's ``statuses``."""
    parts = [s.parts for s in statuses]
    if not parts or any(p is None for p in parts):
        raise ValueError("chain_track: the chain gives no per-part health (its joint filter is off: JointFilterConfig.beside)")

    def column(name: str) -> np.ndarray:
        return np.array([getattr(p, name)[0] for p in parts])

    return PartTrack(
        t=np.array([s.t[0] for s in statuses]), parts=chain.degradable, value=column("value"), std=column("std"), degrading=column("degrading"),
        named=column("named"), eol=column("eol"), eol_low=column("eol_low"), eol_high=column("eol_high"),
        alarm=np.array([bool(s.alarm[0]) for s in statuses]), isolated=np.array([int(s.isolated[0]) - 1 for s in statuses]),
        fits=np.array([s.model_fit is not None and bool(s.model_fit.fits[0]) for s in statuses]),
        misfit=np.array([s.model_fit is not None and bool(s.model_fit.misfit[0]) for s in statuses]),
        machine_eol=np.array([s.eol[0] for s in statuses]),
    )


def chain_run(record: Record, model: SystemModel | None = None, classifier: str | None = None, load_noise: float = 0.0,
              commissioning: Record | None = None) -> PartTrack:
    """The chain on ``record``'s measurements as ``ea-gym phm --measurements REC --noise 0.01 --load-noise L --commission HEALTHY``
    runs it: ``chain_config`` at the record's rate, the known 1 % sensor noise and ``load_noise``, the isolation network of
    ``classifier_for`` (``model`` and ``classifier`` default to the record's system's), commissioned on the healthy record
    ``commissioning`` (``ea_gym.phm.commission``, ``PHMChain.commission``) where given."""
    model = model or system_model(record.machine.system)
    measurements = record.measurements
    config = chain_config(measurements.sample_rate, NOISE, load_noise)
    chain = build_chain(model, config, classifier_for(model, classifier), np.random.default_rng(0))
    if commissioning is not None:
        healthy = commissioning.measurements
        load_rate = np.gradient(healthy.load, healthy.sample_period)  # as the chain's stream takes it
        fitted = commission(model, healthy.signals.T[None], healthy.load[None], load_rate[None], healthy.sample_rate, NOISE, load_noise)
        chain.commission(fitted.value)
    return chain_track(chain, run_measurements(chain, measurements).statuses)


def hysteresis(probability: np.ndarray, name: float, release: float) -> np.ndarray:
    """Named (S, D) from each step's probabilities of degrading (S, D): from the step one reaches ``name`` until it falls below
    ``release`` (the chain's rule, ``JointFilterConfig.name_probability`` and ``release_probability``)."""
    named = np.zeros(probability.shape, dtype=bool)
    state = np.zeros(probability.shape[1], dtype=bool)
    for s, p in enumerate(probability):
        state = (p >= name) | (state & (p >= release))
        named[s] = state
    return named


def truth(machine: Machine, track: PartTrack) -> np.ndarray:
    """Each of ``track``'s parts' true value at its steps' ends, (S, D)."""
    names = list(system_model(machine.system).parameter_names)
    return machine.values(track.t)[:, [names.index(name) for name in track.parts]]


def set_named_right(track: PartTrack, machine: Machine) -> np.ndarray:
    """At every counted step (see the module docstring), whether the named parts are exactly the wearing ones, (counted,)."""
    onsets = sorted(ramp.onset for ramp in machine.ramps)
    if not onsets:
        return np.zeros(0, dtype=bool)
    counted = track.t >= onsets[0] + SET_SETTLE - 1e-9
    for onset in onsets[1:]:
        counted &= ~((track.t > onset) & (track.t < onset + SET_SETTLE - 1e-9))
    wearing = np.zeros(track.named.shape, dtype=bool)
    for ramp in machine.ramps:
        wearing[:, track.parts.index(ramp.parameter)] = track.t > ramp.onset
    return np.asarray(np.all(track.named == wearing, axis=1)[counted])


def estimate_errors(track: PartTrack, machine: Machine) -> dict[str, np.ndarray]:
    """Each part's absolute estimate error (SI) at every step from ``SETTLE`` s after the first onset (every step without one)."""
    first = min((ramp.onset for ramp in machine.ramps), default=-SETTLE)
    window = track.t >= first + SETTLE - 1e-9
    error = np.abs(track.value - truth(machine, track))[window]
    return {name: error[:, j] for j, name in enumerate(track.parts)}


def prediction_mask(t: np.ndarray, onset: float, eol: float) -> np.ndarray:
    """Predictions evaluated by alpha-lambda and coverage: from 50 to 90 % of the way from onset to End of Life."""
    first, last = (onset + f * (eol - onset) for f in PREDICTION_SPAN)
    return (t >= first - 1e-9) & (t <= last + 1e-9)


def alpha_hits(rul: np.ndarray, rul_true: np.ndarray, alpha: float = ALPHA) -> np.ndarray:
    """Whether each point RUL (s) lies within +-alpha of the true RUL (bounds inclusive; inf misses).

    ``ea_gym.metrics.alpha_lambda`` judges the one prediction at a single lambda and refuses infinite
    predictions; issue 17 counts every prediction of a span, a missing one (inf) as a miss."""
    return np.isfinite(rul) & (np.abs(rul - rul_true) <= alpha * rul_true)


def interval_hits(low: np.ndarray, high: np.ndarray, rul_true: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(covers, bounded): whether each RUL interval (s) contains the true RUL, and whether it is bounded."""
    return (low <= rul_true) & (rul_true <= high), np.isfinite(low) & np.isfinite(high)


def prognosis_hits(track: PartTrack, machine: Machine) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per wearing part: (alpha hits, bounded interval covers the true RUL) of each prediction in its span."""
    hits = {}
    for ramp in machine.ramps:
        eol = machine.end_of_life(ramp)
        span = prediction_mask(track.t, ramp.onset, eol)
        j = track.parts.index(ramp.parameter)
        rul_true = eol - track.t[span]
        covers, bounded = interval_hits(track.eol_low[span, j] - track.t[span], track.eol_high[span, j] - track.t[span], rul_true)
        hits[ramp.parameter] = (alpha_hits(track.eol[span, j] - track.t[span], rul_true), covers & bounded)
    return hits


def raised(track: PartTrack) -> np.ndarray:
    """Whether each step has the detector's alarm, a part named or an End of Life (a part's or the machine's), (S,)."""
    return np.asarray(track.alarm | track.named.any(axis=1) | np.isfinite(track.eol).any(axis=1) | np.isfinite(track.machine_eol))


def first_alarm(track: PartTrack) -> float:
    """When (s) the track first raised the alarm, named a part or gave an End of Life; inf if never."""
    steps = raised(track)
    return float(track.t[np.argmax(steps)]) if steps.any() else np.inf


def raised_by(track: PartTrack) -> str:
    """What the track raised first: "detector alarm", "named" and the parts, "End of Life" (joined by " + "); "" if nothing."""
    steps = raised(track)
    if not steps.any():
        return ""
    k = int(np.argmax(steps))
    what = ["detector alarm"] if track.alarm[k] else []
    if track.named[k].any():
        what.append("named " + ", ".join(part for part, named in zip(track.parts, track.named[k]) if named))
    if np.isfinite(track.eol[k]).any() or np.isfinite(track.machine_eol[k]):
        what.append("End of Life")
    return " + ".join(what)


def wear_scores(track: PartTrack, machine: Machine) -> dict[str, Any]:
    """One record's scores: the set named per counted step, errors per part, alpha-lambda and coverage hits per wearing
    part, the first alarm."""
    hits = prognosis_hits(track, machine)
    return {
        "set_right": set_named_right(track, machine), "errors": estimate_errors(track, machine),
        "alpha": {part: h[0] for part, h in hits.items()}, "covered": {part: h[1] for part, h in hits.items()},
        "first_alarm": first_alarm(track), "raised_by": raised_by(track),
    }


def pooled(runs: Sequence[dict[str, Any]], key: str) -> dict[str, np.ndarray]:
    """Per part, ``key``'s arrays of every run (``wear_scores``) that has it, joined."""
    parts = dict.fromkeys(part for run in runs for part in run[key])
    return {part: np.concatenate([run[key][part] for run in runs if part in run[key]]) for part in parts}


def wear_summary(runs: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The figures over ``runs`` (``wear_scores``): the share of counted steps with the set named right, each part's median
    error, each wearing part's alpha-lambda and coverage (shares of its predictions)."""
    return {
        "set_named": float(np.concatenate([run["set_right"] for run in runs]).mean()),
        "set_steps": int(sum(len(run["set_right"]) for run in runs)),
        "error_median": {part: float(np.median(e)) for part, e in pooled(runs, "errors").items()},
        "alpha_lambda": {part: float(h.mean()) for part, h in pooled(runs, "alpha").items()},
        "coverage": {part: float(h.mean()) for part, h in pooled(runs, "covered").items()},
        "predictions": {part: len(h) for part, h in pooled(runs, "alpha").items()},
        "runs": len(runs),
    }
