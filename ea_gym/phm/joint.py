"""Joint estimation: one extended Kalman filter per system over the energy variables, every degradable
parameter and its drift, so that each part's estimate, variance and drift hold whatever the others do.

The state is x = [energy variables (nx), theta (D), drift (D)]: theta the degradable parameters (SI),
each drift a random walk (unit/s) and theta its integral plus a random walk. The prediction is the
plant's own exact discretization (``ea_gym.phm.tracking.transition``: matrix exponential, cubic Hermite
load), evaluated once per step at the step's first estimate (the anchor) and at the anchor moved by
+-delta in each parameter: [Phi | Gamma](theta) = M0 + sum_j dM_j (theta_j - anchor_j) within the
step, dM_j the central difference, so the Jacobian's parameter columns dM_j [x; w] come with it. The
measurement model is ``Sensors(model)``'s: an I element's flow p / I (nonlinear where I is estimated,
its H row carries -p / I^2), a C element's displacement q. Each sample's update is the filterpy form
(y = z - h(x), S = H P H^T + R, K = P H^T S^-1; compiled, ``ea_gym._kernels.joint``, beside its numpy
reference); its innovations y and their covariances S are kept for the step (``innovation``,
``innovation_covariance``: a model-fit test reads them).

Why an EKF and not an unscented filter (ProgPy's ``UnscentedKalmanFilter``, the comparison's anchor): the
model is linear in the states and smooth in the parameters, the parameters move by a fraction of a per
cent per step, so the linearisation's error is far below the 1 % sensor noise, and one step's 2 D + 1
discretizations replace the 2 (nx + 2 D) + 1 sigma points' propagation at every sample
(experiments/studies/joint_filter.py compares their errors and times on the same signals).

Noise model (``JointFilterConfig``): measurement variance the noise fraction squared times each
signal's mean square over the step (as the sensors scale it); random walks of theta and drift relative
to the nominal values (the tracking filters' measured choice, ``ea_gym.phm.tracking``); a prior on
theta of 0.15 of the safe span around nominal (a machine anywhere in the middle half of its range) and
on the drift of 1e-3 / s. The estimates are held within the safe limits widened by half their span.

Degrading evidence: a part degrades when its drift exceeds ``degrading_rate`` of its safe span per
second; with the drift's Gaussian N(d, s^2), P(degrading) = Phi((d - r) / s) + Phi((-d - r) / s). A
constant offset from nominal is not a drift, so a machine off its catalogue values is not "degrading".
Load noise (errors in variables, ``load_noise`` s as a fraction of the load's RMS over a step): the filter's
prediction x' = Phi x + Gamma w runs on the measured load, w = [u, u', 2 c2, 6 c3] the Taylor coefficients
of the cubic Hermite interpolant through the samples (``ea_gym.bondgraph.simulation.hermite_coefficients``:
c2 = (3 (u1 - u0) / h - 2 u0' - u1') / h, c3 = (u0' + u1' - 2 (u1 - u0) / h) / h^2). Samples read with white
noise e_k of std s (and the rate their central difference, as the recorded route takes it: its error
(e_{k+1} - e_{k-1}) / 2 h) make Gamma w off by a sum over e_{k-1} .. e_{k+2}: with Gamma's columns
G0 .. G3, the sample's own value enters through G0 - 6 G2 / h^2 + 12 G3 / h^3, the next one's through
6 G2 / h^2 - 12 G3 / h^3, and the rate's errors through G1 - 4 G2 / h + 6 G3 / h^2 and -2 G2 / h + 6 G3 / h^2.
These errors are coloured (successive samples share an e); what the states gather over their response,
many samples long, is the sequence's spectral density at frequencies far below the sampling rate, at zero
frequency s^2 (sum of the coefficients)(sum)^T, and the sum is G0 (the rate's terms cancel): the error of a
load held over the sample. So the filter adds s^2 G0 G0^T to each sample's state prediction covariance
(G0 at the step's anchor; the sample's own variance, about half of it, would count the shared errors once).

Wear onsets: the drift's random walk (``drift_noise``) follows a wear rate that changes slowly; a wear that
starts, or whose rate jumps, is a change the walk cannot follow in time (a damper's drift from 0 to 5e-3 of
its span per s is some fifty of the walk's standard deviations over a second), and the filter, sure of a
zero drift, would learn it over a minute while its estimate lags by several of its standard deviations.
So each step's correction of each parameter (its estimate after the step's samples minus its prediction
from the step's start, theta + tau drift) is watched: under the filter's model it is Gaussian with zero
mean and variance the predicted variance minus the updated one, independent from step to step (a linear
function of the step's innovations). A two-sided CUSUM (Page) of the normalized corrections
(``onset_allowance``, ``onset_threshold``) finds a run of one sign, and the parameter is re-opened by what
the run says: over its T seconds the corrections moved the parameter by m, so the lag it had built up is of
the order of m and its drift's error of m / T; the parameter's variance grows by m^2 and its drift's by
(m / T)^2, and the next seconds' data set them. On the scipy-ODE records of two and three parts ramping
(spring-mass-damper seeds 10-19, RLC circuit and DC motor 10-14) the lightly damped b's RUL-interval
coverage rose from 0.53-0.71 without re-opening to 0.96-0.97, and every part's coverage to 0.96 or more;
re-opening the drift to its prior instead gave b 0.93-0.94, the RLC circuit's R2 0.93.

The chain's single-class isolation reads these as its log evidence: "none" log prod (1 - p_i), "j
alone" that with p_j for 1 - p_j; the probabilities themselves travel in ``ParameterEstimates.degrading``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ea_gym._kernels.joint import joint_samples
from ea_gym._kernels.tracking import VARIANCE_FLOOR
from ea_gym.bondgraph.simulation import hermite_coefficients
from ea_gym.diagnosis.monitor import Monitor
from ea_gym.models import SystemModel
from ea_gym.phm.config import JointFilterConfig, ModelFitConfig, PHMConfig
from ea_gym.phm.estimation import ParameterEstimates, StepSignals, checked_arguments, checked_signals
from ea_gym.phm.fit import StepInnovations
from ea_gym.phm.isolation import EvidenceWeights
from ea_gym.phm.prognosis import DriftPrognosis
from ea_gym.phm.registry import EstimationStages, register_estimator
from ea_gym.phm.tracking import transition
from ea_gym.sensors import Sensors
from ea_gym.threads import over_rows

#: the central differences' step, relative to the parameter's nominal value: near the cube root of
#: machine epsilon, where truncation and round-off errors meet
DIFFERENCE_STEP = 1e-5
#: probabilities are kept this far from 0 and 1 so that their logs stay finite
PROBABILITY_FLOOR = 1e-12
#: a step whose normalized innovations squared exceed this many times their degrees of freedom is one the model does not
#: explain (the model-fit test's default edge, ``ModelFitConfig.tolerance`` x a band's upper edge of about 1): its
#: parameter corrections say nothing of a wear's onset, and no part is re-opened on them
MISFIT = ModelFitConfig.tolerance


def degrading_probability(drift: np.ndarray, variance: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """P(|drift| > rate) under N(drift, variance), elementwise (drift and rate in unit/s, variance in unit^2/s^2)."""
    from scipy.special import ndtr  # imported when first needed: scipy.special takes a few tenths of a second

    std = np.sqrt(np.maximum(variance, np.finfo(float).tiny))
    return np.asarray(ndtr((drift - rate) / std) + ndtr((-drift - rate) / std))


class JointFilter:
    """Estimates every degradable parameter of N systems at once, with its drift (see the module docstring).

    Args:
        model: the monitored system; every degradable parameter needs safe limits.
        sample_rate: the signals' sampling rate (Hz).
        noise: the sensors' noise std as a fraction of each signal's RMS over a step.
        load_noise: the load measurement's noise std as a fraction of the load's RMS over a step (errors in variables).
        n_systems: N.
        degradable: the estimated parameters; default the isolation classes' (every one with safe limits).
        config: process noise, priors, bounds and the degrading rate.

    Attributes:
        x: each system's state [energy variables, theta (SI), drift (SI/s)], (N, nx + 2 D).
        P: its covariance, (N, nx + 2 D, nx + 2 D).
        innovation: the last step's innovations (measured minus predicted signal), (N, L, nx).
        innovation_covariance: their covariances S, (N, L, nx, nx).
    """

    def __init__(
        self, model: SystemModel, sample_rate: float, noise: float, n_systems: int = 1,
        degradable: Sequence[str] | None = None, config: JointFilterConfig | None = None, load_noise: float = 0.0,
    ) -> None:
        self.model = model
        self.degradable: tuple[str, ...] = checked_arguments(model, degradable, sample_rate, noise, n_systems)
        if not (math.isfinite(load_noise) and load_noise >= 0):
            raise ValueError(f"load_noise must be a finite fraction >= 0, got {load_noise!r}")
        self.config = config or JointFilterConfig()
        self.h = 1.0 / sample_rate
        self.noise = max(float(noise), self.config.min_noise)
        self.load_noise = float(load_noise)
        self.n = n_systems
        space = model.state_space
        self.nx, d = space.n_states, len(self.degradable)
        self.columns = np.array([space.parameter_names.index(name) for name in self.degradable])
        self.base = model.parameter_vector()
        self.nominal = self.base[self.columns]
        limits = np.array([model.safe_limits[name] for name in self.degradable], dtype=float).reshape(d, 2)
        self.span = limits[:, 1] - limits[:, 0]
        # a physical value stays positive however wide the margin
        self.lo = np.maximum(limits[:, 0] - self.config.bound_margin * self.span, 0.5 * limits[:, 0])
        self.hi = limits[:, 1] + self.config.bound_margin * self.span
        self.theta_noise = (self.config.theta_noise * self.nominal) ** 2  # variance per s
        self.drift_noise = (self.config.drift_noise * self.nominal) ** 2
        self.rate = self.config.degrading_rate * self.span
        # every I element's flow p / I: its signal and the degradable index of I (-1: I is not estimated), and I's nominal value
        sensors, degradable_columns = Sensors(model), list(self.columns)
        pairs = [(i, degradable_columns.index(p) if p in degradable_columns else -1) for i, p in sensors.momenta]
        self.momenta = np.array(pairs, dtype=np.int64).reshape(-1, 2)
        self.inertia = np.array([self.base[p] for _, p in sensors.momenta], dtype=float)
        self.nominal_inverse_gain = sensors.inverse_gain(self.base)  # (nx,): the energy variables from the signals at nominal
        self._sensors = sensors
        # where each system's filter starts: its healthy machine's parameters (nominal until commissioned) and their prior std
        self.center = np.repeat(self.nominal[None], n_systems, axis=0)
        self.prior_std = np.repeat((self.config.theta_prior * self.span)[None], n_systems, axis=0)
        self.drift_prior_std = np.repeat((self.config.drift_prior * self.nominal)[None], n_systems, axis=0)
        self.start_inverse_gain = np.repeat(self.nominal_inverse_gain[None], n_systems, axis=0)  # (N, nx) at the center
        size = self.nx + 2 * d
        self.x = np.zeros((n_systems, size))
        self.P = np.zeros((n_systems, size, size))
        self.innovation = np.zeros((n_systems, 0, self.nx))
        self.innovation_covariance = np.zeros((n_systems, 0, self.nx, self.nx))
        self._innovations: StepInnovations | None = None
        self.started = np.zeros(n_systems, dtype=bool)
        # each parameter's CUSUM of its normalized corrections, upward and downward, and how far the corrections of
        # its current run have moved it (its unit)
        self.onset_sums = np.zeros((n_systems, d, 2))
        self.onset_runs = np.zeros((n_systems, d, 2))
        self.onset_times = np.zeros((n_systems, d, 2))
        self._step_seconds = 0.0
        self.clock = np.zeros(n_systems)  # the time (s) the filter describes, the end of the last step
        self.lag = 0.0  # its estimates describe the step's end
        self.warmup_steps = 0  # and come from the first step on
        # every parameter is estimated at every step: one read-only answer shared by every step's estimates
        self._estimated = np.ones((n_systems, d), dtype=bool)
        self._estimated.flags.writeable = False

    @property
    def theta(self) -> slice:
        """Where the parameters sit in the state."""
        return slice(self.nx, self.nx + len(self.degradable))

    @property
    def drift(self) -> slice:
        """Where the drifts sit in the state."""
        return slice(self.nx + len(self.degradable), self.nx + 2 * len(self.degradable))

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Start over for all systems, or those where the boolean mask (N,) is true: their filters restart,
        at their healthy machine's values (nominal until commissioned), from their next step."""
        rows = slice(None) if systems is None else np.asarray(systems, dtype=bool)
        self.started[rows] = False
        self.onset_sums[rows] = self.onset_runs[rows] = self.onset_times[rows] = 0.0

    def restart(self, systems: np.ndarray, parameters: np.ndarray) -> None:
        """Nothing to forget: every parameter is estimated at every step, so none is ever stale."""

    def commission(self, values: np.ndarray, std: np.ndarray, systems: np.ndarray | None = None) -> None:
        """Make ``values`` (M, D) the healthy machine of all systems (M = N) or of those where the boolean mask
        ``systems`` (N,) is true (M of them): their filters start over from their next step around these values,
        with the prior std ``std`` (M, D) (each part's SI unit), instead of the nominal values and
        ``JointFilterConfig.theta_prior``, and their drifts with ``commissioned_drift_prior``'s std (a machine
        just seen healthy); a reset keeps them."""
        rows = np.ones(self.n, dtype=bool) if systems is None else np.asarray(systems, dtype=bool)
        shape = (int(rows.sum()), len(self.degradable))
        values, std = np.broadcast_to(np.asarray(values, dtype=float), shape), np.broadcast_to(np.asarray(std, dtype=float), shape)
        if not (np.all(np.isfinite(values)) and np.all(values > 0)):
            raise ValueError(f"values must be finite and > 0 ({', '.join(self.degradable)}), got {values.tolist()}")
        if not (np.all(np.isfinite(std)) and np.all(std > 0)):
            raise ValueError(f"std must be finite and > 0, got {std.tolist()}")
        self.center[rows], self.prior_std[rows] = values, std
        self.drift_prior_std[rows] = self.config.commissioned_drift_prior * self.rate
        parameters = np.repeat(self.base[None], shape[0], axis=0)
        parameters[:, self.columns] = values
        self.start_inverse_gain[rows] = self._sensors.inverse_gain(parameters)
        self.reset(rows)

    def record_adjustment(self, systems: np.ndarray, parameters: np.ndarray, changes: np.ndarray) -> None:
        """Maintenance moved degradable parameter ``parameters[k]`` of system ``systems[k]`` by ``changes[k]``
        (its SI unit) before the next update: its estimate moves by the known change (its drift stays)."""
        self.x[np.asarray(systems), self.nx + np.asarray(parameters)] += np.asarray(changes, dtype=float)

    def update(self, signals: StepSignals, alarm: np.ndarray, suspects: np.ndarray) -> ParameterEstimates:
        """Run every system's filter over one step, whatever ``alarm`` (N,) and ``suspects`` (N, D) say (every
        parameter is estimated at every step). A system starts, at its healthy machine's values, at its first step after a reset;
        where a step stands for more time than its signals last (``StepSignals.t`` moved by more), theta is
        carried by its drift over the difference and holds over the signals."""
        measured, load, load_rate, t = checked_signals(signals, self.n, self.nx)
        samples = measured.shape[2] - 1
        variance = np.maximum(self.noise**2 * np.mean(measured**2, axis=2) / (1.0 + self.noise**2), VARIANCE_FLOOR)  # (N, nx)
        watched = self.started.copy()  # a system's first step after a start tells nothing of a change
        self._start(~self.started, measured[:, :, 0], variance)
        gap = t - self.clock
        carried = self.started & (gap > samples * self.h * (1.0 + 1e-9))
        self._carry(carried, gap)
        drift_time = np.where(carried, 0.0, self.h)
        self.started[:] = True
        self.clock[:] = t
        predicted, predicted_variance = self._predicted_parameters(drift_time * samples)
        self._step_seconds = samples * self.h
        anchor = self.x[:, self.theta].copy()
        M0, dM = self._transitions(anchor)
        w = hermite_coefficients(load[..., None], load_rate[..., None], self.h)  # (N, L, 4)
        if M0.shape[2] - self.nx > w.shape[2]:  # the constant sources' column multiplies 1
            w = np.concatenate([w, np.ones(w.shape[:2] + (1,))], axis=2)
        Q = self._process_noise(variance, drift_time)
        if self.load_noise > 0:  # errors in variables (module docstring): s^2 Gamma_0 Gamma_0^T per sample
            load_variance = self.load_noise**2 * np.mean(load**2, axis=1) / (1.0 + self.load_noise**2)  # (N,)
            held = M0[:, :, self.nx]  # Gamma's column of the load's value
            Q[:, : self.nx, : self.nx] += load_variance[:, None, None] * held[:, :, None] * held[:, None, :]
        self.innovation = np.empty((self.n, samples, self.nx))
        self.innovation_covariance = np.empty((self.n, samples, self.nx, self.nx))
        w = np.ascontiguousarray(w)

        def filter_rows(start: int, stop: int) -> None:  # the systems' filters are independent: rows split between threads
            rows = slice(start, stop)
            joint_samples(
                M0[rows], dM[rows], anchor[rows], w[rows], drift_time[rows], Q[rows], measured[rows], variance[rows], self.momenta,
                self.inertia, self.lo, self.hi, self.x[rows], self.P[rows], self.innovation[rows], self.innovation_covariance[rows],
            )

        over_rows(filter_rows, self.n)
        self._innovations = None
        step = self.innovations()
        # where the model does not explain the step (the model-fit test's edge), its corrections tell no onset
        self._watch_onsets(watched & (step.nis <= MISFIT * step.dof), predicted, predicted_variance)
        return self.estimates(t)

    def _predicted_parameters(self, span: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each parameter predicted from the filter's state over ``span`` seconds (N,) of drift without measurements, and
        its variance, (N, D) each: theta + span drift, var_theta + 2 span cov + span^2 var_drift plus the random walks of
        theta (span q_theta) and of its drift (span^3 q_drift / 3) over it."""
        d = len(self.degradable)
        thetas, drifts = np.arange(self.nx, self.nx + d), np.arange(self.nx + d, self.nx + 2 * d)
        tau = span[:, None]
        predicted = self.x[:, self.theta] + tau * self.x[:, self.drift]
        variance = (
            self.P[:, thetas, thetas] + 2.0 * tau * self.P[:, thetas, drifts] + tau**2 * self.P[:, drifts, drifts]
            + tau * self.theta_noise + tau**3 * self.drift_noise / 3.0
        )
        return predicted, variance

    def _watch_onsets(self, watched: np.ndarray, predicted: np.ndarray, predicted_variance: np.ndarray) -> None:
        """The CUSUM of each parameter's normalized correction by the step (its estimate minus ``predicted``, over the
        square root of ``predicted_variance`` minus its variance now) for the ``watched`` systems (N,); where it
        passes ``JointFilterConfig.onset_threshold`` the parameter's drift is re-opened (see the module docstring)."""
        d = len(self.degradable)
        thetas, drifts = np.arange(self.nx, self.nx + d), np.arange(self.nx + d, self.nx + 2 * d)
        spread = np.sqrt(np.maximum(predicted_variance - self.P[:, thetas, thetas], VARIANCE_FLOOR))
        correction = (self.x[:, self.theta] - predicted) / spread
        allowance = self.config.onset_allowance
        sums = np.stack([self.onset_sums[..., 0] + correction - allowance, self.onset_sums[..., 1] - correction - allowance], axis=-1)
        moved = (self.x[:, self.theta] - predicted)[..., None] * np.array([1.0, -1.0])  # upward, downward
        watching = watched[:, None, None] & (sums > 0)
        self.onset_runs = np.where(watching, self.onset_runs + moved, np.where(watched[:, None, None], 0.0, self.onset_runs))
        self.onset_times = np.where(watching, self.onset_times + self._step_seconds, np.where(watched[:, None, None], 0.0, self.onset_times))
        self.onset_sums = np.where(watched[:, None, None], np.maximum(sums, 0.0), self.onset_sums)
        fired = np.any(self.onset_sums > self.config.onset_threshold, axis=-1)  # (N, D)
        if fired.any():
            rows, parameters = np.nonzero(fired)
            side = np.argmax(self.onset_sums[rows, parameters], axis=-1)
            moved_by, over = self.onset_runs[rows, parameters, side], self.onset_times[rows, parameters, side]
            # the parameter never wider than its prior, which knows nothing of the machine (the drift's prior is no bound:
            # a wear's onset may outrun it, the lightly damped b's on the records of issue 30's tests)
            theta_prior = self.config.theta_prior * self.span[parameters]
            self.P[rows, thetas[parameters], thetas[parameters]] += np.minimum(np.abs(moved_by), theta_prior) ** 2
            self.P[rows, drifts[parameters], drifts[parameters]] += (np.abs(moved_by) / over) ** 2
            self.onset_sums[fired] = self.onset_runs[fired] = self.onset_times[fired] = 0.0

    def _start(self, rows: np.ndarray, first: np.ndarray, variance: np.ndarray) -> None:
        """Systems ``rows`` (N,) at their healthy machine's values (nominal until commissioned): the energy variables
        read off the first samples ``first`` (N, nx) through its gains, with their measurement's ``variance``; no
        drift; the priors' variances."""
        if not rows.any():
            return
        inverse = self.start_inverse_gain[rows]
        d = len(self.degradable)
        x, P = np.zeros((rows.sum(), len(self.x[0]))), np.zeros((rows.sum(),) + self.P.shape[1:])
        x[:, : self.nx], x[:, self.theta] = first[rows] * inverse, self.center[rows]
        states, thetas, drifts = np.arange(self.nx), np.arange(self.nx, self.nx + d), np.arange(self.nx + d, self.nx + 2 * d)
        P[:, states, states] = variance[rows] * inverse**2
        P[:, thetas, thetas] = self.prior_std[rows] ** 2
        P[:, drifts, drifts] = self.drift_prior_std[rows] ** 2
        self.x[rows], self.P[rows] = x, P

    def _carry(self, rows: np.ndarray, gap: np.ndarray) -> None:
        """Systems ``rows`` (N,) carried over ``gap`` (s, (N,)) without signals: theta += drift gap within the
        bounds, P = J P J^T (J the identity but d theta / d drift = gap) plus the random walks over the gap."""
        if not rows.any():
            return
        d = len(self.degradable)
        J = np.repeat(np.eye(self.x.shape[1])[None], rows.sum(), axis=0)
        thetas, drifts = np.arange(self.nx, self.nx + d), np.arange(self.nx + d, self.nx + 2 * d)
        J[:, thetas, drifts] = gap[rows, None]
        x = self.x[rows]
        x[:, self.theta] = np.clip(x[:, self.theta] + gap[rows, None] * x[:, self.drift], self.lo, self.hi)
        P = J @ self.P[rows] @ J.transpose(0, 2, 1)
        P[:, thetas, thetas] += gap[rows, None] * self.theta_noise
        P[:, drifts, drifts] += gap[rows, None] * self.drift_noise
        self.x[rows], self.P[rows] = x, P

    def _transitions(self, anchor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """[Phi | Gamma] at each system's ``anchor`` (N, D), (N, nx, nx + 4 or 5), and its central-difference
        slope in each parameter, (N, D, nx, nx + 4 or 5)."""
        d = len(self.degradable)
        delta = DIFFERENCE_STEP * self.nominal
        thetas = np.repeat(self.base[None, None], self.n * (2 * d + 1), axis=0).reshape(self.n, 2 * d + 1, -1).copy()
        thetas[:, :, self.columns] = anchor[:, None, :]
        rows = np.arange(d)
        thetas[:, 1 + rows, self.columns] += delta
        thetas[:, 1 + d + rows, self.columns] -= delta
        M = transition(self.model, thetas, self.h)
        return M[:, 0], (M[:, 1 : 1 + d] - M[:, 1 + d :]) / (2.0 * delta[None, :, None, None])

    def _process_noise(self, variance: np.ndarray, drift_time: np.ndarray) -> np.ndarray:
        """Each system's process-noise covariance per sample, (N, nx + 2 D, nx + 2 D): the states' a multiple of
        their measurement variance (``variance`` (N, nx) in the signals' units, taken to the energy
        variables at nominal), theta's and the drift's their random walks over a sample, none for theta
        where it holds over the signals (``drift_time`` 0)."""
        inverse = self.nominal_inverse_gain
        diagonal = np.concatenate(
            [self.config.state_noise * variance * inverse**2,
             np.where(drift_time[:, None] > 0, self.theta_noise * self.h, 0.0),
             np.broadcast_to(self.drift_noise * self.h, (self.n, len(self.degradable)))],
            axis=1,
        )
        return diagonal[:, :, None] * np.eye(diagonal.shape[1])

    def degrading(self) -> np.ndarray:
        """Each parameter's probability of degrading, (N, D): P(|drift| > ``degrading_rate`` x its safe span)."""
        drifts = np.arange(self.nx + len(self.degradable), self.x.shape[1])
        return degrading_probability(self.x[:, self.drift], self.P[:, drifts, drifts], self.rate)

    def estimates(self, t: np.ndarray) -> ParameterEstimates:
        """The filters' current estimates at times ``t`` (N,), with each parameter's degrading probability and
        the single-class isolation's log evidence read off them (see the module docstring)."""
        d = len(self.degradable)
        thetas, drifts = np.arange(self.nx, self.nx + d), np.arange(self.nx + d, self.nx + 2 * d)
        degrading = self.degrading()
        p = np.clip(degrading, PROBABILITY_FLOOR, 1.0 - PROBABILITY_FLOOR)
        none = np.sum(np.log1p(-p), axis=1)
        log_evidence = np.concatenate([none[:, None], none[:, None] - np.log1p(-p) + np.log(p)], axis=1)
        return ParameterEstimates(
            value=self.x[:, self.theta].copy(),
            variance=self.P[:, thetas, thetas],
            drift=self.x[:, self.drift].copy(),
            drift_variance=self.P[:, drifts, drifts],
            covariance=self.P[:, thetas, drifts],
            log_evidence=log_evidence,
            estimated=self._estimated,
            time=np.repeat(np.asarray(t, dtype=float)[:, None], d, axis=1),
            degrading=degrading,
        )

    def innovations(self) -> StepInnovations:
        """The last step's normalized innovations squared, y^T S^-1 y summed over its samples, and their
        terms (samples x signals) (``ea_gym.phm.fit.InnovationSource``)."""
        if self._innovations is None:  # once a step: the filter's own onset watch reads them, then the model-fit test
            y, S = self.innovation, self.innovation_covariance
            nis = np.einsum("nli,nli->n", y, np.linalg.solve(S, y[..., None])[..., 0]) if y.shape[1] else np.zeros(self.n)
            self._innovations = StepInnovations(nis=nis, dof=np.full(self.n, float(y.shape[1] * y.shape[2])))
        return self._innovations

    @property
    def diffusion(self) -> np.ndarray:
        """Each parameter's random walk as the filter models it, variance per second (unit^2/s), (D,): it goes on
        over a prognosis's horizon."""
        return self.theta_noise


#: The joint route's isolation evidence: its log evidence is already a probability's log (not a sum over
#: thousands of correlated samples, as the tracking filters' is), so it counts fully; the network and the
#: balance keep the tracking route's weights beside it.
JOINT_WEIGHTS = EvidenceWeights(estimator=1.0, network=0.25, balance=0.1)


@register_estimator("joint")
def joint_stages(model: SystemModel, monitor: Monitor, config: PHMConfig, n_systems: int) -> EstimationStages:
    """The joint filter at the chain's sample rate and noise level (``config.timing``, ``config.joint``) and each
    parameter's drift carried to its limits (``config.extrapolation``)."""
    timing = config.timing
    estimator = JointFilter(model, timing.sample_rate, timing.noise, n_systems, config=config.joint, load_noise=timing.load_noise)
    prognosis = DriftPrognosis(model, estimator.degradable, config.extrapolation, estimator.diffusion, n_systems)
    return EstimationStages(estimator, prognosis, JOINT_WEIGHTS, innovations=estimator)
