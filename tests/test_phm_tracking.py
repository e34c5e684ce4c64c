"""The chain's tracking route: the filter bank as its estimator, its drift carried to the limits
(``DriftPrognosis``), a ramp isolated and tracked end to end, and no End of Life while undecided."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ea_gym.diagnosis.training import load_shipped_classifier
from ea_gym.models import spring_mass_damper
from ea_gym.phm import (
    ESTIMATORS,
    ChainTiming,
    DriftPrognosis,
    ExtrapolationConfig,
    ParameterEstimates,
    PHMConfig,
    TrendPrognosis,
    build_chain,
    drift_end_of_life,
    run_scenario,
)
from ea_gym.scenario import load_scenario

MODEL = spring_mass_damper()
SINES = {"kind": "sines", "offset": 10.0, "sines": [
    {"amplitude": 4.0, "frequency": 0.25}, {"amplitude": 2.0, "frequency": 0.7}, {"amplitude": 1.0, "frequency": 1.4}]}


def estimates(value, drift, variance, drift_variance, covariance, t) -> ParameterEstimates:
    """A record of N systems x D parameters with the given (N, D) arrays at times t (N,)."""
    n, d = np.shape(value)
    return ParameterEstimates(
        value=np.asarray(value, float), variance=np.asarray(variance, float), drift=np.asarray(drift, float),
        drift_variance=np.asarray(drift_variance, float), covariance=np.asarray(covariance, float),
        log_evidence=np.zeros((n, d + 1)), estimated=np.ones((n, d), dtype=bool), time=np.repeat(np.asarray(t, float)[:, None], d, 1),
    )


def test_the_estimator_kinds_and_their_prognosis() -> None:
    assert {"ea_inversion", "tracking"} <= set(ESTIMATORS)  # the built-in ones (a test adds its own)
    assert PHMConfig().estimator_kind == "tracking"
    classifier = load_shipped_classifier(MODEL.name)
    for kind, prognosis, lag in (("tracking", DriftPrognosis, 0.0), ("ea_inversion", TrendPrognosis, None)):
        chain = build_chain(MODEL, PHMConfig(timing=ChainTiming(noise=0.01), estimator_kind=kind), classifier, np.random.default_rng(0))
        assert isinstance(chain.prognosis, prognosis)
        assert chain.estimate_lag == (lag if lag is not None else chain.estimator.lag) and (lag is not None or chain.estimate_lag > 0)


def test_drift_prognosis_carries_the_confident_suspects_value_and_drift_to_its_limit() -> None:
    lower, upper = MODEL.safe_limits["k"]
    degradable = ("k", "m", "b")
    config = ExtrapolationConfig()
    prognosis = DriftPrognosis(MODEL, degradable, config, np.array([0.04, 0.0, 0.0]), 2)
    # both systems: k at 95 N/m falling 0.5 N/m/s at t = 10 s; only system 0 is confident of it
    value = np.array([[95.0, 10.0, 0.5]] * 2)
    drift = np.array([[-0.5, 0.0, 0.0]] * 2)
    record = estimates(value, drift, np.full((2, 3), 1.0), np.full((2, 3), 0.05**2), np.full((2, 3), 0.01), np.full(2, 10.0))
    out = prognosis.update(record, np.array([1, 1]), np.array([True, False]), np.full(2, 10.0))
    cov = np.array([[1.0, 0.01], [0.01, 0.05**2]])
    expected = drift_end_of_life(np.array(95.0), np.array(-0.5), cov, np.array([lower, upper]), np.array(10.0), config.confidence, 0.04)
    np.testing.assert_allclose([out.eol[0], out.eol_low[0], out.eol_high[0]], [float(e) for e in expected], rtol=1e-12)
    assert out.eol[0] == pytest.approx(10.0 + (95.0 - lower) / 0.5)
    assert out.eol_low[0] < out.eol[0] < out.eol_high[0] < math.inf
    prediction = out.end_of_life[0]
    assert prediction is not None and prediction.fit is None and prediction.limit == "lower"
    assert (prediction.value, prediction.drift, prediction.drift_std) == (95.0, -0.5, pytest.approx(0.05))
    assert prediction.path(np.array([30.0]))[0] == pytest.approx(85.0)
    # the unsure system: no End of Life, no estimate
    assert out.end_of_life[1] is None and math.isinf(out.eol[1]) and math.isnan(out.estimate[1])
    # the predictions read as a sequence of N: by negative index and slice alike
    assert len(out.end_of_life) == 2 and out.end_of_life[-1] is None and out.end_of_life[-2] == prediction
    assert out.end_of_life[:] == (prediction, None) and list(out.end_of_life) == [prediction, None]
    with pytest.raises(IndexError):
        out.end_of_life[2]
    # beyond the horizon: none either
    far = prognosis.update(estimates(value, drift * 1e-3, np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 3)), np.full(2, 10.0)),
                           np.array([1, 1]), np.array([True, False]), np.full(2, 10.0))
    assert math.isinf(far.eol[0]) and far.end_of_life[0] is not None and far.end_of_life[0].limit is None


def test_the_drift_interval_covers_the_true_end_of_life_95_percent_of_the_time() -> None:
    """Hand case: the truth drawn from the filter's own (value, drift) distribution; each draw's End of
    Life lies in the interval as often as the interval's confidence says."""
    rng = np.random.default_rng(3)
    mean = np.array([95.0, -0.2])
    cov = np.array([[0.5, -0.002], [-0.002, 0.02**2]])
    draws = rng.multivariate_normal(mean, cov, size=20_000)
    lower = 85.0
    true_eol = (lower - draws[:, 0]) / draws[:, 1]
    eol, low, high = drift_end_of_life(mean[0], mean[1], cov, np.array([lower, 105.0]), np.array(0.0), 0.95)
    covered = np.mean((true_eol >= low) & (true_eol <= high))
    assert covered == pytest.approx(0.95, abs=0.01)
    assert low < eol < high and eol == pytest.approx(50.0)


def test_a_damper_ramp_is_isolated_tracked_and_its_rul_interval_covers_the_truth() -> None:
    """Issue 17's damper ramp through the default chain: b isolated, estimated within 0.005 N s/m, and
    the RUL interval covering the true RUL from half-way to the End of Life."""
    scenario = load_scenario({
        "system": "spring_mass_damper", "load": SINES, "duration": 150.0,
        "fault": {"parameter": "b", "profile": [[0, 0.5], [10, 0.5], [150, 0.66]]}, "sensors": {"noise": 0.01, "seed": 22},
    })
    chain = build_chain(MODEL, PHMConfig(timing=ChainTiming(noise=0.01)), load_shipped_classifier(MODEL.name), np.random.default_rng(0))
    run = run_scenario(scenario, chain, np.random.default_rng(1))
    b = chain.classes.index("b")
    assert run.statuses[-1].isolated[0] == b and run.statuses[-1].confident[0]
    true_eol = 10.0 + (MODEL.safe_limits["b"][1] - 0.5) / (0.16 / 140.0)
    late = [s for s in run.statuses if 30.0 <= s.t[0] <= 150.0]
    errors = np.array([abs(s.estimate[0] - scenario.parameters_at(s.t)[0, MODEL.parameter_names.index("b")]) for s in late])
    assert np.median(errors) <= 0.005
    half = [s for s in run.statuses if 10.0 + 0.5 * (true_eol - 10.0) <= s.t[0] <= min(true_eol, 150.0)]
    assert half, "the run reaches half-way to the End of Life"
    covered = [s.eol_low[0] <= true_eol <= s.eol_high[0] for s in half]
    assert np.mean(covered) >= 0.9


def test_undecided_hypotheses_give_no_end_of_life() -> None:
    """When neither the filters nor the network can separate m from b, the chain says so: no confident
    suspect, the belief split, no End of Life (although the filters' drift would give one)."""
    chain = build_chain(MODEL, PHMConfig(timing=ChainTiming(noise=0.01)), load_shipped_classifier(MODEL.name), np.random.default_rng(0), n_systems=1)
    m, b = chain.classes.index("m"), chain.classes.index("b")
    chain.isolation.state.probability_average[:] = 0.0
    chain.isolation.state.probability_average[0, [m, b]] = 0.5
    log_evidence = np.array([[-500.0, -400.0, -3.0, -3.0]])  # "none" and k far behind, m and b alike
    alarm = np.ones(1, dtype=bool)
    fusion = chain.isolation.fuse(alarm, log_evidence, np.ones((1, 3), dtype=bool), np.zeros((1, 4)))
    assert not fusion.confident[0] and fusion.belief[0, m] == pytest.approx(fusion.belief[0, b])
    value = np.array([[100.0, 10.0, 0.55]])
    drift = np.array([[0.0, 0.01, 0.001]])
    record = estimates(value, drift, np.full((1, 3), 1e-6), np.full((1, 3), 1e-10), np.zeros((1, 3)), np.full(1, 40.0))
    out = chain.prognosis.update(record, fusion.isolated, fusion.confident, np.full(1, 40.0))
    assert out.end_of_life[0] is None and math.isinf(out.eol[0])


def test_corrective_actions_move_the_tracked_estimate_once() -> None:
    """The environment logs a corrective action's change; the filter, whose signals see the plant move
    too, follows it without counting it twice."""
    import gymnasium as gym

    import ea_gym  # noqa: F401 - registers the environments
    from ea_gym.degradation import WearConfig

    wear = {"k": WearConfig(direction=-1, rate=(0.0, 0.0), arrival=(0.0, 0.0))}
    env = gym.make("ea_gym/SpringMassDamper-v0", wear=wear, corrective_rate=0.02)
    env.reset(seed=0)
    chain = env.unwrapped.core.chain
    k = chain.degradable.index("k")
    for _ in range(3):
        env.step(1 + env.unwrapped.maintainable_components.index("k"))
    for _ in range(5):
        env.step(0)
    assert chain.estimator.estimates(np.zeros(1)).value[0, k] == pytest.approx(101.2, abs=0.1)
