"""An estimator defined outside the library, registered with the documented one line, runs in the chain and the env."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ea_gym  # noqa: F401  (registers the environments)
from ea_gym.diagnosis.database import classes_of, draw_loads
from ea_gym.diagnosis.monitor import Monitor
from ea_gym.diagnosis.training import load_shipped_classifier
from ea_gym.models import SystemModel, spring_mass_damper
from ea_gym.phm import (
    ChainTiming,
    EstimationStages,
    ParameterEstimates,
    PHMConfig,
    StepSignals,
    TrendPrognosis,
    build_chain,
    register_estimator,
    registered_estimators,
)
from ea_gym.plant import run_model
from ea_gym.sensors import Sensors

MODEL = spring_mass_damper()
GUESS = 1.1  # the toy's estimate of every degradable parameter, a multiple of its nominal value
VARIANCE = 0.25  # the toy's variance of every estimate


class FixedGuess:
    """A toy estimator: every hypothesis at GUESS x its nominal value with a fixed variance, equal evidence."""

    def __init__(self, model: SystemModel, n_systems: int):
        self.degradable = classes_of(model)[1:]
        self.lag = 0.0
        self.warmup_steps = 0
        self.n = n_systems
        self.value = GUESS * model.parameter_vector()[[model.parameter_names.index(p) for p in self.degradable]]

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Nothing to forget."""

    def record_adjustment(self, systems: np.ndarray, parameters: np.ndarray, changes: np.ndarray) -> None:
        """The guess ignores maintenance."""

    def restart(self, systems: np.ndarray, parameters: np.ndarray) -> None:
        """Nothing learned to forget."""

    def update(self, signals: StepSignals, alarm: np.ndarray, suspects: np.ndarray) -> ParameterEstimates:
        shape = (self.n, len(self.degradable))
        nothing = np.full(shape, np.nan)
        return ParameterEstimates(
            value=np.tile(self.value, (self.n, 1)), variance=np.full(shape, VARIANCE), drift=nothing, drift_variance=nothing,
            covariance=nothing, log_evidence=np.zeros((self.n, shape[1] + 1)), estimated=np.ones(shape, dtype=bool),
            time=np.repeat(signals.t[:, None], shape[1], axis=1),
        )


@register_estimator("fixed_guess")
def fixed_guess_stages(model: SystemModel, monitor: Monitor, config: PHMConfig, n_systems: int) -> EstimationStages:
    estimator = FixedGuess(model, n_systems)
    history_length = int(round(config.extrapolation.span / config.timing.update_time)) + 1
    return EstimationStages(estimator, TrendPrognosis(model, estimator.degradable, config.extrapolation, history_length, n_systems))


def test_a_registered_estimator_runs_in_the_chain_and_its_estimates_reach_the_health_status():
    chain = build_chain(MODEL, PHMConfig(timing=ChainTiming(noise=0.01), estimator_kind="fixed_guess"),
                        load_shipped_classifier(MODEL.name), np.random.default_rng(0))
    assert isinstance(chain.estimator, FixedGuess) and isinstance(chain.prognosis, TrendPrognosis)
    rng = np.random.default_rng(1)
    t = np.arange(501) * chain.h
    load = draw_loads(MODEL, 1, rng)[0]
    plant = run_model(MODEL, t, load)
    signals = Sensors(MODEL).measure(plant.parameters[None], plant.states[None], 0.0, rng)
    step = chain.step_samples
    for start in range(0, len(t) - 1, step):
        part = slice(start, start + step + 1)
        status = chain.update(signals[..., part], signals[..., part], load.value(t[part])[None], load.derivative(t[part])[None])
        np.testing.assert_array_equal(status.estimates, np.tile(chain.estimator.value, (1, 1)))
        np.testing.assert_array_equal(status.estimation.variance, VARIANCE)
    assert status.t[0] == pytest.approx(5.0)


def test_a_registered_estimator_runs_in_the_environment_and_its_estimates_reach_the_observation():
    env = gym.make("ea_gym/SpringMassDamper-v0", phm=PHMConfig(estimator_kind="fixed_guess"))
    env.reset(seed=0)
    chain = env.unwrapped.core.chain
    assert isinstance(chain.estimator, FixedGuess)
    for _ in range(3):
        observation, *_ = env.step(0)
    lower, upper = np.array([MODEL.safe_limits[p] for p in chain.degradable]).T
    # the observation shows each estimate's position in its safe range
    np.testing.assert_allclose(observation["parameter_estimate"], (chain.estimator.value - lower) / (upper - lower), rtol=1e-6)
    env.close()


def test_an_unknown_estimator_is_refused_naming_the_registered_ones():
    registered = registered_estimators()  # other tests of the session (the docs' pages) may have added theirs
    assert {"ea_inversion", "fixed_guess", "joint", "tracking"} <= set(registered)
    with pytest.raises(ValueError, match=rf"no estimator named 'kalman' is registered; registered: {', '.join(sorted(registered))} "):
        build_chain(MODEL, PHMConfig(estimator_kind="kalman"), load_shipped_classifier(MODEL.name), np.random.default_rng(0))
    with pytest.raises(ValueError, match="already registered"):
        register_estimator("tracking")(fixed_guess_stages)
