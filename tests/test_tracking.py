"""The tracking estimator: its compiled step against the kernels' numpy reference (``reference.tracking``), recovery of a constant parameter
and of a ramp's slope from noise-free signals, and the linear-drift End of Life on hand-computed cases."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import norm

from ea_gym._kernels.filter_records import FilterBank, FilterSettings, FilterStates, TrackedSignals, TrackOutputs
from ea_gym._kernels.reference import tracking as reference
from ea_gym._kernels.tracking import track_filters
from ea_gym.diagnosis.database import classes_of
from ea_gym.diagnosis.monitor import Monitor
from ea_gym.loads import Sine, SinesLoad
from ea_gym.models import get_model, spring_mass_damper
from ea_gym.phm.config import ChainTiming, PHMConfig, TrackingConfig
from ea_gym.phm.estimation import ParameterEstimates, ParameterEstimator, StepSignals
from ea_gym.phm.prognosis import drift_end_of_life
from ea_gym.phm.tracking import TrackingEstimator, tracking_stages
from ea_gym.plant import run_model
from ea_gym.sensors import Sensors

RATE = 100.0


def bank_and_settings(est: TrackingEstimator) -> tuple[FilterBank, FilterSettings]:
    """The estimator's filter bank and settings as its ``update`` passes them to the kernel."""
    return FilterBank(est.hypotheses, est.process_noise, est.prior), FilterSettings(est.config.state_noise, est.forget, est.h, est.noise**2)


def reference_step(est: TrackingEstimator, signals: StepSignals) -> ParameterEstimates:
    """The estimator's step by ``reference.track_step`` on its own arrays."""
    n, D = len(signals.t), len(est.degradable)
    outputs = TrackOutputs(np.empty((6, n, D)), np.empty((n, D + 1)))
    filters = FilterStates(est.started, est.clock, est.z, est.P, est.log_likelihood, est.nis)
    bank, settings = bank_and_settings(est)
    nx = signals.measured.shape[1]
    sizes = (0.0,) * nx, (0.0,) * (bank.hypotheses.coefficients.shape[3] - nx)  # unused by the reference, the kernels' loop bounds
    reference.track_step(bank, settings, 0, n, TrackedSignals(signals.measured, signals.load, signals.load_rate, signals.t), filters, outputs, *sizes)
    value, variance, drift, drift_variance, covariance, time = outputs.estimates
    return ParameterEstimates(value=value, variance=variance, drift=drift, drift_variance=drift_variance, covariance=covariance,
                              log_evidence=outputs.evidence, estimated=np.ones((n, D), dtype=bool), time=time)


def plant_steps(parameters, duration: float, noise: float = 0.0, seed: int = 0, model=None):
    """Step windows (1 s) of a sine-driven system (default the spring-mass-damper) whose parameters follow ``parameters(t)``."""
    model = model or spring_mass_damper()
    t = np.arange(int(duration * RATE) + 1) / RATE
    f = model.excitation_bandwidth / 2.0
    load = SinesLoad(model.nominal_load, tuple(Sine(a * model.nominal_load, b * f) for a, b in ((0.4, 0.125), (0.2, 0.35), (0.1, 0.7))))
    plant = run_model(model, t, load, parameters)
    rng = np.random.default_rng(seed)
    clean = Sensors(model).measure(plant.parameters[None], plant.states[None], noise, rng)
    u, du = load.value(t)[None], load.derivative(t)[None]
    step = int(RATE)
    return model, [
        StepSignals(clean[..., s : s + step + 1], u[:, s : s + step + 1], du[:, s : s + step + 1], t[None, s + step])
        for s in range(0, len(t) - step, step)
    ]


def test_kernel_matches_numpy_reference() -> None:
    model, steps = plant_steps(None, 3.0, noise=0.01)
    est = TrackingEstimator(model, RATE, 0.01, 2, config=TrackingConfig(state_noise=1e-3, evidence_memory=50.0))
    numpy_form = TrackingEstimator(model, RATE, 0.01, 2, config=TrackingConfig(state_noise=1e-3, evidence_memory=50.0))
    both = [
        StepSignals(np.concatenate([s.measured, 1.01 * s.measured]), np.repeat(s.load, 2, 0), np.repeat(s.load_rate, 2, 0), np.repeat(s.t, 2))
        for s in steps
    ]
    suspects = np.ones((2, 3), dtype=bool)
    est.update(both[0], np.zeros(2, dtype=bool), suspects)
    est.z[:, 1:, 2] *= 1.03  # off nominal, so that every theta-slope matters
    for name in ("started", "clock", "z", "P", "log_likelihood"):
        getattr(numpy_form, name)[:] = getattr(est, name)
    for s in both[1:]:
        reference_step(numpy_form, s)
        est.update(s, np.ones(2, dtype=bool), suspects)
    np.testing.assert_allclose(est.z, numpy_form.z, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(est.P, numpy_form.P, rtol=1e-8, atol=1e-10 * np.abs(numpy_form.P).max())
    np.testing.assert_allclose(est.log_likelihood, numpy_form.log_likelihood, rtol=1e-10)
    np.testing.assert_allclose(est.nis, numpy_form.nis, rtol=1e-10)


def test_compiled_step_matches_numpy_around_the_filter_bank(monkeypatch: pytest.MonkeyPatch) -> None:
    """The compiled step (noise, starts, carries over long steps, the filters, the estimates) gives the
    bits of the reference's step around the compiled filter bank, through a reset and steps that stand
    for more time than their signals, in one system or both."""
    monkeypatch.setattr(reference, "track_filters", track_filters)
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
        out, expected = compiled.update(signals, np.ones(2, dtype=bool), suspects), reference_step(numpy_form, signals)
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
    config = PHMConfig(timing=ChainTiming(sample_rate=RATE, noise=0.01))
    estimator: ParameterEstimator = tracking_stages(model, Monitor(model, 1 / RATE), config, 3).estimator
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


def _strict_fit(model, index: int, lo: float, hi: float, h: float, rtol: float = 1e-11) -> np.ndarray:
    """The interpolant under the rule before the rounding floor: the lowest degree that reaches ``rtol``."""
    from numpy.polynomial import chebyshev

    from ea_gym.phm.tracking import transition

    base = model.parameter_vector()

    def evaluate(s: np.ndarray) -> np.ndarray:
        theta = np.repeat(base[None], len(s), axis=0)
        theta[:, index] = lo + (s + 1.0) * 0.5 * (hi - lo)
        return transition(model, theta, h)

    check = chebyshev.chebpts2(129)
    exact = evaluate(check)
    for degree in (8, 16, 24, 32, 48, 64, 96):
        nodes = chebyshev.chebpts1(degree + 1)
        coefficients = chebyshev.chebfit(nodes, evaluate(nodes).reshape(len(nodes), -1), degree)
        approx = chebyshev.chebval(check, coefficients).T.reshape(exact.shape)
        scale = np.abs(exact).max(axis=0, keepdims=True) + np.finfo(float).tiny
        if np.max(np.abs(approx - exact) / scale.max()) <= rtol:
            return coefficients.reshape((degree + 1,) + exact.shape[1:])
    raise AssertionError("no degree reaches rtol")


@pytest.mark.parametrize("name", ["spring_mass_damper", "two_mass_chain"])
def test_a_model_that_reaches_rtol_keeps_the_strict_rules_interpolant_bit_for_bit(name):
    from ea_gym.phm.tracking import discretization_fit

    if name == "spring_mass_damper":
        model = spring_mass_damper()
    else:
        from pathlib import Path

        from ea_gym.model_files import load_model_file

        model = load_model_file(Path(__file__).resolve().parents[1] / "experiments" / "models" / "two_mass_chain.yaml")
    nominal = model.parameter_vector()
    for parameter, (lower, upper) in model.safe_limits.items():
        index = model.state_space.parameter_names.index(parameter)
        lo, hi = 0.5 * min(lower, nominal[index]), 1.5 * max(upper, nominal[index])
        for rate in (10.0, RATE):
            coefficients, error = discretization_fit(model, index, lo, hi, 1.0 / rate)
            assert error <= 1e-11
            assert np.array_equal(coefficients, _strict_fit(model, index, lo, hi, 1.0 / rate))
