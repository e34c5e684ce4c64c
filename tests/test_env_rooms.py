"""The environment's rooms: EnvConfig validated in itself with keyword overrides, typed actions and
events whose text is the infos', one info builder, the core's public accessors."""

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import ea_gym  # noqa: F401 - registers the environments
from ea_gym.env.config import EnvConfig, env_config
from ea_gym.env.costs import CostModel
from ea_gym.env.events import (
    Action,
    ActionKind,
    CorrectiveStep,
    Failure,
    Replacement,
    action_table,
    parse_action,
    parse_event,
)
from ea_gym.env.observations import OBSERVATION_BOUND, PARAMETER_POSITION_BOUNDS
from ea_gym.phm import ChainTiming, IsolationConfig, JointFilterConfig, ModelFitConfig, PHMConfig

ENV_ID = "ea_gym/SpringMassDamper-v0"


@pytest.mark.parametrize(
    "field, value, error, match",
    [
        ("step_seconds", -1.0, ValueError, "step_seconds must be a positive number"),
        ("window_seconds", 0.0, ValueError, "window_seconds must be a positive number"),
        ("sample_rate", float("nan"), ValueError, "sample_rate must be a positive number"),
        ("noise", 1.0, ValueError, r"noise must be in \[0, 1\)"),
        ("horizon", 2.5, ValueError, "horizon must be an int in"),
        ("horizon", True, ValueError, "horizon must be an int in"),
        ("obs_mode", "full", ValueError, "obs_mode must be one of"),
        ("costs", [1.0], TypeError, "costs must be a CostModel"),
        ("wear", {"k": 1.0}, TypeError, "wear must be None or a dict"),
        ("corrective_rate", 0, ValueError, "corrective_rate must be a positive number"),
        ("continue_after_failure", 1, TypeError, "continue_after_failure must be a bool"),
        ("rul_max", -5.0, ValueError, "rul_max must be a positive number"),
        ("load_std", (0.4, 0.2), ValueError, "load_std must be a tuple"),
        ("phm", {"frame": 20.0}, TypeError, "phm must be None or a PHMConfig"),
    ],
)
def test_env_config_refuses_bad_fields_by_name(field, value, error, match):
    with pytest.raises(error, match=match):
        EnvConfig(**{field: value})
    with pytest.raises(error, match=match):
        env_config(**{field: value})


def test_env_config_overrides_and_phm_settings():
    base = EnvConfig(obs_mode="sensors", horizon=50)
    assert env_config(base, noise=0.02) == dataclasses.replace(base, noise=0.02)
    assert env_config(base) is base and env_config() == EnvConfig()
    assert env_config(costs=None).costs == CostModel()
    assert env_config(costs={"failure": 1.0}).costs == CostModel(failure=1.0)
    with pytest.raises(TypeError, match="unexpected keyword argument 'speed'"):
        env_config(base, speed=2)
    chain = EnvConfig(step_seconds=5.0, window_seconds=1.0, noise=0.02).phm_config
    no_fit = ModelFitConfig(enabled=False)  # the v0 environments run without the model-fit test
    alone = JointFilterConfig(beside=False)  # and without a joint filter beside their estimator
    timing = ChainTiming(step=1.0, step_time=5.0, sample_rate=100.0, noise=0.02)
    assert chain == PHMConfig(timing=timing, fit=no_fit, joint=alone)
    custom = EnvConfig(phm=PHMConfig(isolation=IsolationConfig(frame=10.0), timing=ChainTiming(noise=0.5))).phm_config
    assert custom.isolation.frame == 10.0 and custom.timing.noise == 0.01  # the env's noise is the chain's
    assert custom.fit == no_fit and custom.joint == alone
    # where every part ages: the joint filter with every part's End of Life, the model-fit test on, the settings given kept
    every = EnvConfig(step_seconds=5.0, window_seconds=1.0, noise=0.02, concurrent_wear=True)
    assert every.phm_config == PHMConfig(timing=timing, estimator_kind="joint", joint=JointFilterConfig(end_of_life="every"))
    assert dataclasses.replace(every, phm=PHMConfig(isolation=IsolationConfig(frame=10.0))).phm_config.estimator_kind == "tracking"


def test_a_config_and_its_keywords_give_the_same_episode():
    by_config = gym.make(ENV_ID, config=EnvConfig(obs_mode="sensors", horizon=30))
    by_keywords = gym.make(ENV_ID, obs_mode="sensors", horizon=30)
    mixed = gym.make(ENV_ID, config=EnvConfig(obs_mode="phm", horizon=30), obs_mode="sensors")
    runs = []
    for env in (by_config, by_keywords, mixed):
        observation, _ = env.reset(seed=3)
        trace = [observation["ea"].copy()]
        for t in range(30):
            observation, reward, terminated, truncated, info = env.step(3 if t == 10 else 0)
            trace += [observation["ea"].copy(), reward, info["events"]]
            if terminated or truncated:
                break
        runs.append(trace)
    for other in runs[1:]:
        assert len(other) == len(runs[0])
        for a, b in zip(runs[0], other):
            np.testing.assert_array_equal(a, b)


def test_actions_are_typed_and_their_meanings_round_trip():
    env = gym.make(ENV_ID, obs_mode="sensors")
    actions, meanings = env.unwrapped.actions, env.unwrapped.action_meanings
    assert actions == action_table(env.unwrapped.maintainable_components, (ActionKind.CARRY_ON, ActionKind.CORRECTIVE, ActionKind.REPLACE))
    assert meanings == tuple(map(str, actions)) and meanings[0] == "carry on"
    assert [parse_action(m) for m in meanings] == list(actions)
    assert str(Action(ActionKind.REPLACE, "k")) == "replace k" and str(Action(ActionKind.CORRECTIVE, "b")) == "corrective action on b"
    for bad in ("replace", "repair k", ""):
        with pytest.raises(ValueError, match="not an action meaning"):
            parse_action(bad)
    with pytest.raises(ValueError, match="a component is needed"):
        Action(ActionKind.REPLACE)


def test_events_are_typed_and_their_text_is_the_infos():
    assert str(CorrectiveStep("k")) == "corrective action on k"
    assert str(Replacement("b", 3)) == "replacement of b (3 steps down)"
    failure = Failure("k", np.float64(30.123456), (np.float64(5.0), np.float64(30.0)))
    assert str(failure).startswith("failure: k = 30.12 outside (")
    for event in (CorrectiveStep("k"), Replacement("b", 3)):
        assert parse_event(str(event)) == event
    assert parse_event(str(failure)) == Failure("k", 30.12, (5.0, 30.0))
    with pytest.raises(ValueError, match="not an event"):
        parse_event("maintenance")
    # every event an episode shows reads back
    env = gym.make(ENV_ID, obs_mode="sensors", continue_after_failure=True, horizon=200)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    kinds = set()
    for _ in range(200):
        _, _, _, _, info = env.step(int(rng.integers(env.action_space.n)))
        for text in info["events"]:
            event = parse_event(text)
            assert str(event) == text or isinstance(event, Failure)
            kinds.add(type(event))
    assert {CorrectiveStep, Replacement} <= kinds


def test_one_info_builder_for_single_and_vector_envs():
    single = gym.make(ENV_ID, obs_mode="oracle", horizon=40)
    vector = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", obs_mode="oracle", horizon=40)
    _, info = single.reset(seed=5)
    _, infos = vector.reset(seed=5)
    assert info == vector.unwrapped.step_info.system(0)
    assert info["true_rul"] == infos["true_rul"][0]
    for _ in range(5):
        _, _, _, _, info = single.step(0)
        _, _, _, _, infos = vector.step(np.zeros(2, dtype=np.int64))
        assert info == vector.unwrapped.step_info.system(0)
        assert info["cost"] == {key: float(values[0]) for key, values in infos["cost"].items() if not key.startswith("_")}
        assert all(infos["cost"][f"_{key}"].all() for key in info["cost"])
        # plain Python numbers, as json and users' comparisons expect them
        assert type(info["true_rul"]) is float and type(info["failed"]) is bool
        assert {type(value) for value in (*info["cost"].values(), *info["true_parameters"].values())} == {float}


def test_core_public_accessors():
    env = gym.make_vec(ENV_ID, num_envs=3, vectorization_mode="vector_entry_point", obs_mode="oracle")
    env.reset(seed=1)
    core = env.unwrapped.core
    theta = core.true_parameters
    theta += 1.0  # a copy: the truth is read-only from outside
    np.testing.assert_array_equal(core.true_parameters, np.tile(core.nominal, (3, 1)))
    assert core.true_rul().shape == (3,)
    assert all(core.faulty_component(i) in core.components for i in range(3))


def test_observation_bounds_are_the_spaces():
    space = gym.make(ENV_ID, obs_mode="phm").observation_space
    assert space["ea"].high.max() == np.float32(OBSERVATION_BOUND)
    assert (space["parameter_estimate"].low.min(), space["parameter_estimate"].high.max()) == PARAMETER_POSITION_BOUNDS
