"""The tracking filter bank's arguments as records (``ea_gym._kernels.tracking.track``): the hypotheses'
filter models, the shared settings, a step's signals, the filters' states and the step's outputs. numba
takes them as typed named tuples."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class HypothesisModels(NamedTuple):
    """What a filter needs of each hypothesis (H = D + 1, "none" first), nx states, K Chebyshev terms.

    coefficients: (H, K, nx, nx + 4 or 5) Chebyshev coefficients of ``ea_gym.phm.tracking.transition``'s
    [Phi | Gamma](theta), the first terms (H,) of them nonzero; lo, hi: (H,) their range (the parameter's
    unit), where theta stays; gain: (H, nx) measurement gains at nominal; own: (H,) the state whose gain is
    1 / theta (-1: none); nominal: (H,) theta at nominal, where a filter starts (the "none" slot's: its
    unused parameter's).
    """

    coefficients: np.ndarray
    terms: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    gain: np.ndarray
    own: np.ndarray
    nominal: np.ndarray


class FilterBank(NamedTuple):
    """Each hypothesis's filter model."""

    hypotheses: HypothesisModels
    #: (H, 2) process-noise variances per sample of theta and drift.
    process_noise: np.ndarray
    #: (H, 2) their variances at the start.
    prior: np.ndarray


class FilterSettings(NamedTuple):
    """The scalars every filter shares."""

    #: each state's process-noise variance per sample, as a multiple of its measurement's variance / g^2.
    state_noise: float
    #: factor on the log-likelihoods per sample.
    forget: float
    #: sample period (s).
    h: float
    #: the sensors' noise variance as a fraction of each signal's mean square.
    noise_variance: float


class TrackedSignals(NamedTuple):
    """One step's signals of N systems, L + 1 samples each."""

    #: (N, nx, L + 1) the measured signals.
    measured: np.ndarray
    #: (N, L + 1) the load and its rate.
    load: np.ndarray
    load_rate: np.ndarray
    #: (N,) the time at the step's end (s).
    t: np.ndarray


class FilterStates(NamedTuple):
    """The filters of N systems, H per system, updated in place."""

    #: (N,) whose filters run (the others start at the next step).
    started: np.ndarray
    #: (N,) the time (s) the filters describe.
    clock: np.ndarray
    #: (N, H, nx + 2) the states [x, theta, drift].
    z: np.ndarray
    #: (N, H, nx + 2, nx + 2) their covariances.
    P: np.ndarray
    #: (N, H) the log-likelihoods.
    log_likelihood: np.ndarray
    #: (N, H) each filter's normalized innovations squared (innovation^2 / its predicted variance),
    #: summed over the channels and samples of its last step.
    nis: np.ndarray


class TrackOutputs(NamedTuple):
    """What a step reads off the filters, written for its systems."""

    #: (6, N, D), D = H - 1: each degradable parameter's value, variance, drift, drift variance,
    #: (value, drift) covariance and the time (s) they describe.
    estimates: np.ndarray
    #: (N, H) the log-likelihoods.
    evidence: np.ndarray
