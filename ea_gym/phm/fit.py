"""The model-fit test: whether the model explains the measurements at all, before any fault is named.

A Kalman filter whose model is right predicts its innovations' variances: each innovation squared over
its predicted variance (the normalized innovation squared, NIS) has mean 1, and their sum over k terms
(a channel's sample each) is chi-square with k degrees of freedom. Over a window of the estimator's
filter that explains the data best, the sum per degree of freedom is compared with that chi-square
band (``scipy.stats.chi2``), its upper edge widened by ``ModelFitConfig.tolerance`` for the model's
small honest errors. Data the model cannot explain (a load column in kN read as N, a time base off by
2x, a C element's form flipped) gives innovations tens to thousands of times their predicted variance;
no parameter within its limits explains them, whichever hypothesis the estimator follows.

Only the upper edge decides: innovations smaller than predicted mean that the noise level the chain
was given is larger than the data's, not that the model is wrong.

Estimators offer their innovations through :class:`InnovationSource`; the tracking filter bank
(:mod:`~ea_gym.phm.tracking`) does, the EA inversion has no innovations (the chain then says the fit is
not tested and gives its diagnosis as before).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy.stats import chi2

from ea_gym.phm.config import ChainTiming, ModelFitConfig


@functools.lru_cache(maxsize=256)
def chi_square_band(dof: float, probability: float) -> tuple[float, float]:
    """The central ``probability`` interval of a chi-square with ``dof`` degrees of freedom, divided by ``dof``."""
    tail = 0.5 * (1.0 - probability)
    return float(chi2.ppf(tail, dof)) / dof, float(chi2.isf(tail, dof)) / dof


@dataclass(frozen=True)
class StepInnovations:
    """One step's innovations of the filter that explains each system's data best, N systems.

    Attributes:
        nis: the normalized innovations squared summed over the step's channels and samples, (N,).
        dof: how many terms the sum has (its chi-square degrees of freedom), (N,).
    """

    nis: np.ndarray
    dof: np.ndarray


class InnovationSource(Protocol):
    """An estimator whose filters predict their innovations' variances."""

    def innovations(self) -> StepInnovations:
        """The last update's innovations, per system, of the hypothesis or filter that explains the data best."""


@dataclass(frozen=True)
class ModelFit:
    """The model-fit test's verdict after a step, N systems.

    Attributes:
        statistic: NIS per degree of freedom over the window (1 where the model fits), NaN until the
            window has filled, (N,).
        low, high: the band of the statistic (``ModelFitConfig``: probability, tolerance on ``high``), NaN
            until the window has filled, (N,).
        fits: the verdict is "the model fits", (N,).
        misfit: the verdict is "the model does not fit", (N,); neither: not yet known.
        since: when (s) the current verdict was reached (the first of the steps that decided it), NaN while
            there is none, (N,).
    """

    statistic: np.ndarray
    low: np.ndarray
    high: np.ndarray
    fits: np.ndarray
    misfit: np.ndarray
    since: np.ndarray

    @property
    def withheld(self) -> np.ndarray:
        """Where no part may be isolated and no End of Life given: the model is not known to fit, (N,)."""
        return ~self.fits


class ModelFitTest:
    """The NIS of N systems over a sliding window of whole steps, and the verdict it supports.

    Args:
        config: window, band and persistence.
        timing: the chain's step (s).
        n_systems: N.
    """

    def __init__(self, config: ModelFitConfig, timing: ChainTiming, n_systems: int = 1) -> None:
        self.config = config
        self.steps = max(1, round(config.window / timing.step))
        self.n = n_systems
        self.nis = np.zeros((n_systems, self.steps))
        self.dof = np.zeros((n_systems, self.steps))
        self.filled = np.zeros(n_systems, dtype=np.int64)
        self.above = np.zeros(n_systems, dtype=np.int64)  # consecutive steps above the band
        self.within = np.zeros(n_systems, dtype=np.int64)  # consecutive steps within it (or below)
        self.fits = np.zeros(n_systems, dtype=bool)
        self.misfit = np.zeros(n_systems, dtype=bool)
        self.since = np.full(n_systems, np.nan)
        self.run_start = np.full(n_systems, np.nan)  # when the current run of steps above or within began

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Start over for all systems, or for those where the boolean mask (N,) is true."""
        rows = slice(None) if systems is None else np.asarray(systems, dtype=bool)
        self.filled[rows] = self.above[rows] = self.within[rows] = 0
        self.fits[rows] = self.misfit[rows] = False
        self.since[rows] = self.run_start[rows] = np.nan

    def update(self, step: StepInnovations, t: np.ndarray) -> ModelFit:
        """Add one step's innovations (ending at times ``t`` (s), (N,)) and return the verdict."""
        slot = self.filled % self.steps
        rows = np.arange(self.n)
        self.nis[rows, slot], self.dof[rows, slot] = step.nis, step.dof
        self.filled += 1
        full = self.filled >= self.steps
        dof = np.maximum(self.dof.sum(axis=1), 1.0)
        statistic = np.where(full, self.nis.sum(axis=1) / dof, np.nan)
        # every system's window has the same terms, as a rule: one band for each distinct count
        counts, which = np.unique(dof, return_inverse=True)
        bands = np.array([chi_square_band(float(count), self.config.probability) for count in counts])[which.reshape(-1)]
        low = np.where(full, bands[:, 0], np.nan)
        high = np.where(full, self.config.tolerance * bands[:, 1], np.nan)
        above = full & (statistic > high)
        within = full & ~above
        # a run of steps on one side starts when the side changes
        changed = (above & (self.above == 0)) | (within & (self.within == 0))
        self.run_start = np.where(changed, t, self.run_start)
        self.above = np.where(above, self.above + 1, 0)
        self.within = np.where(within, self.within + 1, 0)
        persistence = self.config.persistence
        misfit, fits = self.above >= persistence, self.within >= persistence
        flipped = (misfit & ~self.misfit) | (fits & ~self.fits)
        self.since = np.where(flipped, self.run_start, self.since)
        self.misfit, self.fits = misfit | (self.misfit & ~fits), fits | (self.fits & ~misfit)
        return ModelFit(statistic, low, high, self.fits.copy(), self.misfit.copy(), self.since.copy())
