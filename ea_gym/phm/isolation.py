"""Isolation: the network's running belief, the energy-balance evidence and their fusion with the estimator's.

Isolation weighs three kinds of evidence. The network's probabilities are averaged (exponentially)
over the frames seen since the alarm; the estimator says how well each hypothesis "parameter j alone
has changed" (and "none") explains the measurements (its log evidence: for the EA inversion, minus
the running average of its log fit cost); and the energy balance of the last few seconds, regressed
on the energies the components absorb, says how much worse it is explained with component j's
column alone (:func:`balance_chi_square`). The belief in class j is the network's share of it (plus a
floor) times exp(ll_j - ll_max) times exp(-(chi2_j - chi2_min) / 2), deflated (summed in logs): a network that cannot
yet tell a small fault apart does not outvote a hypothesis that the EA fits a hundred times better,
and a young storage fault (which the balance pins to a tenth of a per cent) is not taken for the
light damper, whose EA fit it can mimic.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ea_gym._kernels.isolation import (
    balance_log_ratios,
    belief_inputs,
    chi_squares,
    history_sums,
    network_average,
    pseudo_inverse_factors,
    shifted_log_belief,
    suspect_hypotheses,
    verdict,
)
from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.diagnosis.features import frame_features
from ea_gym.diagnosis.monitor import Monitor
from ea_gym.energy import window_samples
from ea_gym.phm.config import ChainTiming, IsolationConfig
from ea_gym.phm.history import MonitorHistory, rows_of

#: the pseudo-inverse's cut: singular values below it relative to the largest count as zero
_PINV_RCOND = 1e-12


def balance_chi_square(gram: np.ndarray, cross: np.ndarray, square: np.ndarray, windows: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """How much worse the energy balance is explained under each isolation class, (N, 1 + D).

    The balance residual R of every balance window (real minus reference, J) is regressed on the
    energies the components absorb in it: a fault of component i with relative coefficient change
    beta_i adds beta_i E_i. "None" keeps no column, "degradable parameter j alone has changed" its
    component's column alone. The chi-square of a class is the rise of the residual sum of squares
    over the full regression's, in units of the full regression's residual variance.

    Args:
        gram: sum over the windows of E_i E_j, (N, C, C) in J^2.
        cross: sum of E_i R, (N, C) in J^2.
        square: sum of R^2, (N,) in J^2.
        windows: number of windows summed, (N,).
        columns: each degradable parameter's component column, -1 for one that is no component's: such
            a hypothesis cannot be judged by the balance and gets the smallest chi-square (no evidence).
    """
    return chi_squares(gram, cross, square, windows, _pseudo_inverse(gram), columns)


def _pseudo_inverse(gram: np.ndarray) -> np.ndarray:
    """``np.linalg.pinv(gram, rcond=_PINV_RCOND, hermitian=True)`` of the grams (N, C, C): a component the span
    barely excites drops out instead of taking a ridge's bias. numpy's eigendecomposition and product, the
    steps between compiled."""
    left, right_t, tied = pseudo_inverse_factors(*np.linalg.eigh(gram), _PINV_RCOND)
    return np.linalg.pinv(gram, rcond=_PINV_RCOND, hermitian=True) if tied else np.matmul(left, right_t.transpose(0, 2, 1))


@dataclass(frozen=True)
class EvidenceWeights:
    """The exponents of the three kinds of evidence's likelihood ratios in the belief (1: as they are).

    A log-likelihood summed over thousands of correlated samples (the tracking filters': their
    innovations are correlated through the model's errors) is tempered by a weight below 1, so that
    a stretch of a few seconds cannot lock a verdict; the balance summarises the same signals the
    filters' likelihood holds, and an early network frame is often wrong: they count less beside it.
    """

    estimator: float = 1.0
    network: float = 1.0
    balance: float = 1.0


@dataclass
class IsolationState:
    """Per system: the network's running average since the alarm (N, K), the suspect's class index (0 while
    none) (N,) and whether the isolation is confident of it (N,)."""

    probability_average: np.ndarray
    isolated: np.ndarray
    confident: np.ndarray

    @classmethod
    def new(cls, n: int, classes: int) -> IsolationState:
        state = cls(probability_average=np.empty((n, classes)), isolated=np.empty(n, dtype=int), confident=np.empty(n, dtype=bool))
        state.reset()
        return state

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Start over for all systems, or for those where the boolean mask (N,) is true."""
        rows = rows_of(systems)
        self.probability_average[rows] = 0.0
        self.isolated[rows] = 0
        self.confident[rows] = False


@dataclass(frozen=True)
class Fusion:
    """One step's isolation verdict, N systems.

    Attributes:
        belief: the fused class probabilities ("none" = 1 before the alarm), (N, K).
        isolated: class index of the suspect, 0 while none, (N,).
        confidence: the suspect's share of the fault classes' belief, 0 while none, (N,).
        confident: confidence at or above ``IsolationConfig.confidence``, (N,).
        restarted: the systems whose new suspect was not estimated at this step (its estimates are stale), (M,).
    """

    belief: np.ndarray
    isolated: np.ndarray
    confidence: np.ndarray
    confident: np.ndarray
    restarted: np.ndarray


class Isolation:
    """The isolation stage of N systems: network, balance evidence, fusion.

    Args:
        classifier: the isolation network (its classes are "none" then the degradable parameters).
        monitor: the monitor whose outputs the history holds.
        config: the isolation's settings.
        timing: the chain's step.
        classes: "none" then the degradable parameters.
        n_systems: N.
        weights: the network's and the balance's weights beside the estimator's evidence.
    """

    def __init__(
        self, classifier: FaultClassifier, monitor: Monitor, config: IsolationConfig, timing: ChainTiming, classes: tuple[str, ...],
        n_systems: int,
        weights: EvidenceWeights = EvidenceWeights(),
    ):
        self.classifier = classifier
        self.weights = weights
        self.monitor = monitor
        self.config = config
        self.classes = classes
        self.n = n_systems
        self.frame_steps = window_samples(config.frame, timing.step)
        self.evidence_steps = window_samples(config.balance_evidence_span, timing.step)
        step_samples = window_samples(timing.step, monitor.h)
        self.balance_windows_per_step = step_samples // (monitor.n_sub * monitor.n_balance)
        # each degradable parameter's column in the balance regression (-1: not a component's)
        self.balance_column = np.array([monitor.components.index(p) if p in monitor.components else -1 for p in classes[1:]])
        self.state = IsolationState.new(n_systems, len(classes))

    def suspects(self, parameters: int) -> np.ndarray:
        """The hypotheses to estimate at the next step, (N, D): every one until the isolation is confident of
        a suspect (so that a change of suspect finds a history), then the suspect alone."""
        return suspect_hypotheses(self.state.confident, self.state.isolated, parameters)

    def counted(self, history: MonitorHistory, alarm: np.ndarray) -> np.ndarray:
        """The systems whose newest frame enters the network's average, (N,): alarm raised and a full frame seen."""
        return (history.steps >= self.frame_steps) & alarm

    def classify(self, history: MonitorHistory, alarm: np.ndarray) -> np.ndarray:
        """The newest frame's network class probabilities (N, K); updates their running average."""
        # isolation only matters once a fault is detected, and needs a full frame
        counted = self.counted(history, alarm).nonzero()[0]  # flatnonzero's indices, without its wrappers
        if len(counted) == 0:
            predicted = np.empty((0, len(self.classes)))
        else:
            # the frame of every system, read in place from the history, its sums those of the counted ones (the
            # others' are zero: their features are not read)
            n, _, states, steps = history.noise.shape
            noise_sums = history.noise.reshape(n, 2 * states, steps)
            gram, cross, noise = history_sums(history.gram, history.cross, noise_sums, counted, self.frame_steps, True)
            frame = self.monitor.frame_of(history.ea, history.ea_reference, gram, cross, noise.reshape(n, 2, states))
            features = frame_features(frame, self.classifier.variant, self.monitor.model.excitation_bandwidth, counted)
            predicted = self.classifier.predict_proba(features)
        # an exponential average over the frames since the alarm: later frames, with the fault grown,
        # outweigh the first ambiguous ones
        return network_average(predicted, counted, self.n, self.config.smoothing, self.state.probability_average)

    def balance_evidence(self, history: MonitorHistory, alarm: np.ndarray) -> np.ndarray:
        """Log likelihood ratio (N, K) of each class to the best one from the energy balance of the last ``balance_evidence_span``."""
        rows = alarm.nonzero()[0]
        if len(rows) == 0:
            return np.zeros((self.n, len(self.classes)))
        span = self.evidence_steps
        gram, cross, square = history_sums(history.gram, history.cross, history.balance_square[:, None], rows, span, False)
        # the residual's noise is correlated across windows (the smoothing filter spans several), so
        # the regression's own variance understates it: chi-squares are deflated by a calibrated factor
        return balance_log_ratios(
            gram, cross, square[:, 0], _pseudo_inverse(gram), history.steps, rows, span, self.balance_windows_per_step, self.balance_column,
            self.config.balance_inflation, self.n,
        )

    def fuse(self, alarm: np.ndarray, log_evidence: np.ndarray, estimated: np.ndarray, balance: np.ndarray) -> Fusion:
        """The belief (N, K) from the network's average, the estimator's log evidence (N, K) and the balance's
        log evidence (N, K); sets the suspect. ``estimated`` (N, D): the hypotheses the estimator updated at this step."""
        s = self.state
        # before the network's first frame its belief is uniform: the fits alone decide; a hypothesis
        # not yet fitted gives no evidence either way
        network, evidence, believed = belief_inputs(
            s.probability_average, log_evidence, alarm, self.weights.estimator, self.config.network_floor
        )
        # in logs: evidence a thousand nats apart must not underflow every class to 0 (numpy's log and
        # exp, between the compiled steps)
        belief = np.exp(shifted_log_belief(np.log(network), evidence, balance, self.weights.network, self.weights.balance))
        # the alarm already says there is a fault: confidence is the suspect's share among the fault
        # classes; a new suspect not estimated at this step has stale estimates: the estimator restarts it
        diagnosis, isolated, confidence, confident, restarted = verdict(
            belief, believed, s.isolated, s.confident, estimated, self.config.confidence
        )
        return Fusion(belief=diagnosis, isolated=isolated, confidence=confidence, confident=confident, restarted=restarted)
