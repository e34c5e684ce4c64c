"""The tracking estimator: its compiled filter bank against plain numpy, recovery of a constant parameter
and of a ramp's slope from noise-free signals, and the linear-drift End of Life on hand-computed cases."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from numpy.polynomial import chebyshev
from scipy.stats import norm

from ea_gym._kernels.tracking import FilterBank, FilterSettings, FilterStates, TrackedSignals, track_filters
from ea_gym.diagnosis.database import classes_of
from ea_gym.diagnosis.monitor import Monitor
from ea_gym.loads import Sine, SinesLoad
from ea_gym.models import get_model, spring_mass_damper
from ea_gym.phm.config import PHMConfig
from ea_gym.phm.estimation import ParameterEstimates, ParameterEstimator, StepSignals
from ea_gym.phm.prognosis import drift_end_of_life
from ea_gym.phm.tracking import TrackingConfig, TrackingEstimator
from ea_gym.plant import run_model
from ea_gym.sensors import measure

RATE = 100.0


def tracking_step_reference(est: TrackingEstimator, measured, load, load_rate, variance, z, P, ll) -> None:
    """The kernel's arithmetic in plain numpy: every system and hypothesis over samples 1..L, in place."""
    hyp, h = est.hypotheses, est.h
    nx = measured.shape[1]
    for s, f in np.ndindex(z.shape[:2]):
        anchor = z[s, f, nx]
        width = hyp.hi[f] - hyp.lo[f]
        x = np.clip((2 * anchor - hyp.lo[f] - hyp.hi[f]) / width, -1, 1) if width > 0 else 0.0
        c = hyp.coefficients[f, : hyp.terms[f]]
        M0 = chebyshev.chebval(x, c)
        dM = chebyshev.chebval(x, chebyshev.chebder(c, axis=0)) * 2 / width if len(c) > 1 else np.zeros_like(M0)
        for k in range(1, measured.shape[2]):
            theta = z[s, f, nx]
            M = M0 + dM * (theta - anchor)
            u0, u1, d0, d1 = load[s, k - 1], load[s, k], load_rate[s, k - 1], load_rate[s, k]
            slope = (u1 - u0) / h
            w = np.array([u0, d0, 2 * (3 * slope - 2 * d0 - d1) / h, 6 * (d0 + d1 - 2 * slope) / h**2])
            g = hyp.gain[f].copy()
            if hyp.own[f] >= 0:
                g[hyp.own[f]] = 1 / theta
            F = np.zeros((nx + 2, nx + 2))
            F[:nx, :nx] = M[:, :nx]
            F[:nx, nx] = dM[:, :nx] @ z[s, f, :nx] + dM[:, nx:] @ w
            F[nx, nx] = F[nx + 1, nx + 1] = 1
            F[nx, nx + 1] = h
            z[s, f, :nx] = M[:, :nx] @ z[s, f, :nx] + M[:, nx:] @ w
            z[s, f, nx] += h * z[s, f, nx + 1]
            Q = np.diag(np.concatenate([est.config.state_noise * variance[s] / g**2, est.process_noise[f]]))
            P[s, f] = F @ P[s, f] @ F.T + Q
            density = 0.0
            for i in range(nx):  # channel by channel, each linearised where the previous left the state
                H = np.zeros(nx + 2)
                H[i] = hyp.gain[f, i]
                if i == hyp.own[f]:
                    H[i] = 1 / z[s, f, nx]
                    H[nx] = -z[s, f, i] / z[s, f, nx] ** 2
                nu = measured[s, i, k] - H[i] * z[s, f, i]
                S = H @ P[s, f] @ H + variance[s, i]
                K = P[s, f] @ H / S
                density -= 0.5 * (np.log(S) + np.log(2 * np.pi) + nu**2 / S)
                z[s, f] += K * nu
                P[s, f] -= np.outer(K, K) * S
            z[s, f, nx] = np.clip(z[s, f, nx], hyp.lo[f], hyp.hi[f])
            ll[s, f] = est.forget * ll[s, f] + density


def measurement_variance(est: TrackingEstimator, measured: np.ndarray) -> np.ndarray:
    """Each channel's noise variance (N, nx) in plain numpy: noise^2 x its clean RMS^2, from the noisy RMS over the step."""
    mean_square = (measured**2).sum(axis=-1) / measured.shape[-1]
    return np.maximum(est.noise**2 * mean_square / (1.0 + est.noise**2), 1e-30)


def step_reference(est: TrackingEstimator, signals: StepSignals) -> ParameterEstimates:
    """The estimator's step with everything around the filter bank in plain numpy: the measurement noise,
    the fresh systems' filters started at nominal, those of a step longer than its signals carried over
    the difference (theta += drift gap, P = J P J^T plus the random walks), then the filter bank."""
    measured, t, hyp, c = signals.measured, signals.t, est.hypotheses, est.config
    n, nx, samples = measured.shape
    variance = measurement_variance(est, measured)
    running = est.started.copy()
    fresh = np.flatnonzero(~running)
    gain = np.repeat(hyp.gain[None], len(fresh), axis=0)
    est.z[fresh] = 0.0
    est.z[fresh, :, :nx] = measured[fresh, None, :, 0] / gain
    est.z[fresh, :, nx] = hyp.nominal
    est.P[fresh] = 0.0
    diagonal = np.arange(nx)
    est.P[fresh[:, None, None], np.arange(len(hyp.nominal))[:, None], diagonal, diagonal] = variance[fresh, None, :] / gain**2
    est.P[fresh[:, None], 1:, nx, nx] = (c.theta_prior * hyp.nominal[1:]) ** 2
    est.P[fresh[:, None], 1:, nx + 1, nx + 1] = (c.drift_prior * hyp.nominal[1:]) ** 2
    est.log_likelihood[fresh] = 0.0
    est.started[:] = True
    span = t - est.clock
    held = running & (span > (samples - 1) * est.h * (1.0 + 1e-9))
    for m in np.flatnonzero(held):
        gap, z, P = span[m], est.z[m], est.P[m]
        z[:, nx] = np.clip(z[:, nx] + gap * z[:, nx + 1], hyp.lo, hyp.hi)
        P[:, nx, :] += gap * P[:, nx + 1, :]
        P[:, :, nx] += gap * P[:, :, nx + 1]
        P[:, nx, nx] += gap * est.process_noise[:, 0] / est.h
        P[:, nx + 1, nx + 1] += gap * est.process_noise[:, 1] / est.h
    est.clock = t.copy()
    bank = FilterBank(hyp.coefficients, hyp.terms, hyp.lo, hyp.hi, hyp.gain, hyp.own, hyp.nominal, est.process_noise, est.prior)
    track_filters(
        bank, FilterSettings(c.state_noise, est.forget, est.h, est.noise**2), np.where(held, 0.0, est.h), 0,
        TrackedSignals(measured, signals.load, signals.load_rate, t), variance,
        FilterStates(est.started, est.clock, est.z, est.P, est.log_likelihood), (0.0,) * nx, (0.0,) * (hyp.coefficients.shape[3] - nx),
    )
    return est.estimates(t)


def plant_steps(parameters, duration: float, noise: float = 0.0, seed: int = 0, model=None):
    """Step windows (1 s) of a sine-driven system (default the spring-mass-damper) whose parameters follow ``parameters(t)``."""
    model = model or spring_mass_damper()
    t = np.arange(int(duration * RATE) + 1) / RATE
    f = model.excitation_bandwidth / 2.0
    load = SinesLoad(model.nominal_load, tuple(Sine(a * model.nominal_load, b * f) for a, b in ((0.4, 0.125), (0.2, 0.35), (0.1, 0.7))))
    plant = run_model(model, t, load, parameters)
    rng = np.random.default_rng(seed)
    clean = measure(Monitor(model, 1 / RATE), plant.parameters[None], plant.states[None], noise, rng)
    u, du = load.value(t)[None], load.derivative(t)[None]
    step = int(RATE)
    return model, [
        StepSignals(clean[..., s : s + step + 1], u[:, s : s + step + 1], du[:, s : s + step + 1], t[None, s + step])
        for s in range(0, len(t) - step, step)
    ]


def test_kernel_matches_numpy_reference() -> None:
    model, steps = plant_steps(None, 3.0, noise=0.01)
    est = TrackingEstimator(model, RATE, 0.01, 2, config=TrackingConfig(state_noise=1e-3, evidence_memory=50.0))
    both = [
        StepSignals(np.concatenate([s.measured, 1.01 * s.measured]), np.repeat(s.load, 2, 0), np.repeat(s.load_rate, 2, 0), np.repeat(s.t, 2))
        for s in steps
    ]
    suspects = np.ones((2, 3), dtype=bool)
    est.update(both[0], np.zeros(2, dtype=bool), suspects)
    est.z[:, 1:, 2] *= 1.03  # off nominal, so that every theta-slope matters
    z, P, ll = est.z.copy(), est.P.copy(), est.log_likelihood.copy()
    for s in both[1:]:
        variance = measurement_variance(est, s.measured)
        tracking_step_reference(est, s.measured, s.load, s.load_rate, variance, z, P, ll)
        est.update(s, np.ones(2, dtype=bool), suspects)
    np.testing.assert_allclose(est.z, z, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(est.P, P, rtol=1e-8, atol=1e-10 * np.abs(P).max())
    np.testing.assert_allclose(est.log_likelihood, ll, rtol=1e-10)


def test_compiled_step_matches_numpy_around_the_filter_bank() -> None:
    """The compiled step (noise, starts, carries over long steps, the filters, the estimates) gives the
    numpy form's bits, through a reset and steps that stand for more time than their signals, in one
    system or both."""
    model, steps = plant_steps(None, 8.0, noise=0.01)
    config = TrackingConfig(state_noise=1e-3)
    compiled, numpy_form = (TrackingEstimator(model, RATE, 0.01, 2, config=config) for _ in range(2))
    suspects = np.ones((2, 3), dtype=bool)
    t = np.zeros(2)
    for k, s in enumerate(steps):
        t = t + np.array([[1.0, 1.0], [4.0, 1.0], [3.0, 2.5]][k % 3])  # held: both, the first, both
        signals = StepSignals(np.concatenate([s.measured, 1.01 * s.measured]), np.repeat(s.load, 2, 0), np.repeat(s.load_rate, 2, 0), t)
        if k == 2:
            compiled.record_adjustment(np.array([0]), np.array([1]), np.array([0.01]))
            numpy_form.record_adjustment(np.array([0]), np.array([1]), np.array([0.01]))
        if k == 4:
            compiled.reset(np.array([False, True]))
            numpy_form.reset(np.array([False, True]))
        out, expected = compiled.update(signals, np.ones(2, dtype=bool), suspects), step_reference(numpy_form, signals)
        for name in ("z", "P", "log_likelihood", "clock", "started"):
            np.testing.assert_array_equal(getattr(compiled, name), getattr(numpy_form, name), err_msg=name)
        for name in ("value", "variance", "drift", "drift_variance", "covariance", "log_evidence", "estimated", "time"):
            np.testing.assert_array_equal(getattr(out, name), getattr(expected, name), err_msg=name)
    assert (compiled.clock == t).all() and compiled.started.all()


def run_estimator(model, steps, config: TrackingConfig):
    est = TrackingEstimator(model, RATE, 0.0, 1, config=config)
    for s in steps:
        out = est.update(s, np.ones(1, dtype=bool), np.ones((1, len(est.degradable)), dtype=bool))
    return est, out


def test_noise_free_run_recovers_a_constant_parameter() -> None:
    model = spring_mass_damper()
    theta = model.parameter_vector({"k": 95.0})
    model, steps = plant_steps(lambda t: np.broadcast_to(theta, t.shape + theta.shape), 30.0)
    est, out = run_estimator(model, steps, replace(TrackingConfig(), theta_prior=0.1))
    j = est.degradable.index("k")
    assert abs(out.value[0, j] - 95.0) < 0.01
    assert abs(out.drift[0, j]) < 1e-3
    assert np.argmax(out.log_evidence[0]) == j + 1


@pytest.mark.parametrize(("system", "parameter"), [("rlc_circuit", "C1"), ("rlc_circuit", "R1"), ("dc_motor", "K"), ("dc_motor", "J")])
def test_every_kind_of_parameter_is_recovered(system: str, parameter: str) -> None:
    """A C, an R, a GY modulus and an I element (whose own momentum's gain 1 / J the filter estimates)."""
    model = get_model(system)
    theta = model.parameter_vector({parameter: 1.05 * model.nominal[parameter]})
    model, steps = plant_steps(lambda t: np.broadcast_to(theta, t.shape + theta.shape), 20.0, model=model)
    est, out = run_estimator(model, steps, replace(TrackingConfig(), theta_prior=0.1))
    j = est.degradable.index(parameter)
    assert out.value[0, j] == pytest.approx(1.05 * model.nominal[parameter], rel=1e-3)
    assert np.argmax(out.log_evidence[0]) == j + 1


def test_noise_free_run_recovers_a_ramp_slope() -> None:
    model = spring_mass_damper()

    def parameters(t: np.ndarray) -> np.ndarray:
        theta = np.repeat(model.parameter_vector()[None], len(t), 0)
        theta[:, model.parameter_names.index("k")] = 100.0 - 0.2 * np.clip(t - 10.0, 0.0, None)
        return theta

    model, steps = plant_steps(parameters, 60.0)
    est, out = run_estimator(model, steps, TrackingConfig())
    j = est.degradable.index("k")
    assert out.drift[0, j] == pytest.approx(-0.2, rel=0.02)
    assert out.value[0, j] == pytest.approx(90.0, abs=0.05)


def test_steps_longer_than_their_signals() -> None:
    """Windows of 1 s that stand for 5 s of wear each (the environment's step_seconds > window): k drops
    1 N/m between windows, -0.2 N/m per second of the steps' clock; the drift is in that clock's unit."""
    model = spring_mass_damper()
    column = model.parameter_names.index("k")

    def parameters(t: np.ndarray) -> np.ndarray:
        theta = np.repeat(model.parameter_vector()[None], len(t), 0)
        theta[:, column] = 100.0 - np.clip(np.floor(t) - 10.0, 0.0, None)
        return theta

    model, steps = plant_steps(parameters, 40.0)
    steps = [replace(s, t=5.0 * s.t) for s in steps]
    est, out = run_estimator(model, steps, TrackingConfig())
    j = est.degradable.index("k")
    assert out.drift[0, j] == pytest.approx(-0.2, rel=0.05)
    assert out.value[0, j] == pytest.approx(71.0, abs=0.3)


def test_adjustment_and_reset() -> None:
    """A logged adjustment moves its hypothesis's theta by the change; a reset restarts at nominal."""
    model, steps = plant_steps(None, 2.0)
    est = TrackingEstimator(model, RATE, 0.0, 2)
    k = est.degradable.index("k")
    both = [StepSignals(np.repeat(s.measured, 2, 0), np.repeat(s.load, 2, 0), np.repeat(s.load_rate, 2, 0), np.repeat(s.t, 2)) for s in steps]
    suspects = np.ones((2, 3), dtype=bool)
    before = est.update(both[0], np.array([True, False]), suspects)
    assert before.estimated.all()  # every filter runs at every step
    est.record_adjustment(np.array([1]), np.array([k]), np.array([-4.0]))
    np.testing.assert_allclose(est.estimates(both[0].t).value[1, k], before.value[1, k] - 4.0)
    est.reset(np.array([False, True]))
    after = est.update(both[1], np.zeros(2, dtype=bool), suspects)
    assert after.value[1, k] == pytest.approx(100.0, abs=0.01)
    with pytest.raises(ValueError, match="signals.measured"):
        est.update(steps[0], np.zeros(2, dtype=bool), suspects)


@pytest.mark.parametrize("system", ["spring_mass_damper", "dc_motor"])
def test_a_system_at_rest_stays_finite(system: str) -> None:
    """Zero signals and zero load (zero noise): every estimate and evidence stays finite."""
    model = get_model(system)
    est = TrackingEstimator(model, RATE, 0.01, 2)
    rest = StepSignals(np.zeros((2, len(model.state_names), 101)), np.zeros((2, 101)), np.zeros((2, 101)), np.ones(2))
    for _ in range(3):
        out = est.update(rest, np.zeros(2, dtype=bool), np.ones((2, len(est.degradable)), dtype=bool))
    assert np.isfinite(out.value).all() and np.isfinite(out.log_evidence).all()
    nominal = [model.nominal[p] for p in est.degradable]
    np.testing.assert_allclose(out.value, np.broadcast_to(nominal, out.value.shape))


def test_behind_the_chains_seam() -> None:
    """The chain's constructor arguments give the chain's sample rate, noise and isolation classes."""
    model = spring_mass_damper()
    config = PHMConfig(sample_rate=RATE, noise=0.01)
    estimator: ParameterEstimator = TrackingEstimator.from_chain(model, Monitor(model, 1 / RATE), config, 3)
    assert estimator.degradable == classes_of(model)[1:]
    assert isinstance(estimator, TrackingEstimator) and estimator.noise == 0.01 and estimator.h == 1 / RATE


def test_drift_end_of_life_hand_computed() -> None:
    limits = np.array([85.0, 105.0])
    # certain values: the line 100 - 0.5 s reaches 85 in 30 s
    eol, low, high = drift_end_of_life(np.array(100.0), np.array(-0.5), np.zeros((2, 2)), limits, np.array(10.0))
    assert (eol, low, high) == (40.0, 40.0, 40.0)
    # uncertain: at the interval's ends, P(crossed) = 2.5 % and 97.5 % under N(100 - 0.5 tau, 1 + 0.0025 tau^2)
    cov = np.diag([1.0, 0.05**2])
    eol, low, high = drift_end_of_life(np.array(100.0), np.array(-0.5), cov, limits, np.array(10.0))
    for end, p in ((low, 0.025), (high, 0.975)):
        tau = end - 10.0
        assert norm.cdf((85.0 - (100.0 - 0.5 * tau)) / np.sqrt(1.0 + 0.0025 * tau**2)) == pytest.approx(p, abs=1e-9)
    assert low < eol == 40.0 < high
    # theta diffusing on at 0.04 unit^2/s: its variance grows by 0.04 tau
    _, low, high = drift_end_of_life(np.array(100.0), np.array(-0.5), cov, limits, np.array(10.0), diffusion=0.04)
    for end, p in ((low, 0.025), (high, 0.975)):
        tau = end - 10.0
        assert norm.cdf((85.0 - (100.0 - 0.5 * tau)) / np.sqrt(1.0 + 0.04 * tau + 0.0025 * tau**2)) == pytest.approx(p, abs=1e-9)
    # an unresolved drift (|drift| / std < 1.96): no upper bound; a drift away from both limits: no End of Life
    _, low, high = drift_end_of_life(np.array(100.0), np.array(-0.05), cov, limits, np.array(0.0))
    assert np.isinf(high) and 0 < low < np.inf
    eol, _, _ = drift_end_of_life(np.array([100.0]), np.array([0.0]), np.zeros((1, 2, 2)), limits[None], np.array([0.0]))
    assert np.isinf(eol[0])


def test_parameter_theta_noise_replaces_the_default_for_the_named_parameters() -> None:
    model = spring_mass_damper()
    config = TrackingConfig(theta_noise=1e-4, parameter_theta_noise=(("b", 2e-3),))
    est = TrackingEstimator(model, RATE, 0.01, 1, config=config)
    expected = {name: (1e-4 * model.nominal[name]) ** 2 for name in est.degradable} | {"b": (2e-3 * 0.5) ** 2}
    np.testing.assert_allclose(est.diffusion, [expected[name] for name in est.degradable], rtol=1e-12)
    with pytest.raises(ValueError, match="parameter_theta_noise: 'R1'"):
        TrackingEstimator(model, RATE, 0.01, 1, config=TrackingConfig(parameter_theta_noise=(("R1", 1e-3),)))
    with pytest.raises(ValueError, match="parameter_theta_noise"):
        TrackingConfig(parameter_theta_noise=(("b", -1.0),))
