"""The tracking filter bank's arguments as records (``ea_gym._kernels.tracking.track``): the hypotheses'
filter models, the shared settings, a step's signals, the filters' states and the step's outputs. numba
takes them as typed named tuples."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class FilterBank(NamedTuple):
    """Each hypothesis's filter model, H hypotheses over nx states and K Chebyshev terms."""

    #: (H, K, nx, nx + 4 or 5) Chebyshev coefficients of ``transition``'s [Phi | Gamma] per hypothesis.
    coefficients: np.ndarray
    #: (H,) how many of the coefficients are used.
    terms: np.ndarray
    #: (H,) the interpolants' ranges, where theta stays.
    lo: np.ndarray
    hi: np.ndarray
    #: (H, nx) the measurement's gain at nominal.
    gain: np.ndarray
    #: (H,) the state read through 1 / theta (-1: none).
    own: np.ndarray
    #: (H,) theta at nominal, where a filter starts.
    nominal: np.ndarray
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


class TrackOutputs(NamedTuple):
    """What a step reads off the filters, written for its systems."""

    #: (6, N, D), D = H - 1: each degradable parameter's value, variance, drift, drift variance,
    #: (value, drift) covariance and the time (s) they describe.
    estimates: np.ndarray
    #: (N, H) the log-likelihoods.
    evidence: np.ndarray
