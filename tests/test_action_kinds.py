"""Actions by kind: the default table, meanings and costs are today's, and a kind defined here, outside
the library, extends the environment (its actions, cost, event) and the agents with nothing else changed."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import ea_gym  # noqa: F401 - registers the environments
from agents.evaluation import evaluate
from agents.initial_policy import immediate_costs
from agents.policies import ActionMap
from ea_gym.env.actions import DEFAULT_ACTION_KINDS, ActionHandler, Orders
from ea_gym.env.costs import CostModel
from ea_gym.env.events import Action, ActionKind, ComponentEvent, Event, parse_action, parse_event

ENV_ID = "ea_gym/SpringMassDamper-v0"
SURVEY_PRICE = 2.5

SURVEY = ActionKind("survey", cost_item="survey", price=lambda costs: SURVEY_PRICE, maintains=False)


class Survey(ComponentEvent):
    """A survey of ``component`` (the toy kind's event)."""

    prefix = "survey of"


class Surveyor(ActionHandler):
    """Looks a component over: records it, changes nothing."""

    kind = SURVEY

    def apply(self, orders: Orders, rngs: Sequence[np.random.Generator], events: list[list[Event]]) -> None:
        for system, component in zip(orders.systems.tolist(), orders.components.tolist()):
            events[system].append(Survey(self.machines.components[component]))


def test_the_default_action_table_meanings_and_costs_are_todays():
    env = gym.make(ENV_ID, obs_mode="sensors", horizon=20)
    base = env.unwrapped
    assert base.maintainable_components == ("k", "m", "b")
    assert base.action_meanings == (
        "carry on", "corrective action on k", "corrective action on m", "corrective action on b", "replace k", "replace m", "replace b",
    )
    assert [action.kind for action in base.actions] == [ActionKind.CARRY_ON] + [ActionKind.CORRECTIVE] * 3 + [ActionKind.REPLACE] * 3
    assert env.action_space.n == 7
    _, info = env.reset(seed=1)
    assert tuple(info["cost"]) == ("corrective", "replacement", "failure", "lost_production", "total")
    costs = CostModel()
    _, reward, _, _, info = env.step(3)
    assert info["cost"] == {"corrective": costs.corrective, "replacement": 0.0, "failure": 0.0, "lost_production": 0.0, "total": costs.corrective}
    assert reward == -costs.corrective and info["events"] == ["corrective action on b"]
    _, reward, _, _, info = env.step(5)
    total = costs.replacement + costs.lost_production
    assert info["cost"] == {"corrective": 0.0, "replacement": costs.replacement, "failure": 0.0, "lost_production": costs.lost_production,
                            "total": total}
    assert reward == -total and info["events"] == [f"replacement of m ({costs.replace_downtime} steps down)"]
    assert immediate_costs(base.action_meanings, costs).tolist() == [0.0] + [1.0] * 3 + [52.0] * 3


def _extended(**kwargs: Any) -> Any:
    return gym.make(ENV_ID, obs_mode="sensors", action_kinds=(*DEFAULT_ACTION_KINDS, Surveyor), **kwargs)


def test_a_kind_defined_outside_the_library_extends_the_env_and_leaves_the_others_as_they_were():
    default, extended = gym.make(ENV_ID, obs_mode="sensors", horizon=30), _extended(horizon=30)
    components = default.unwrapped.maintainable_components
    assert extended.action_space.n == default.action_space.n + len(components)
    surveys = tuple(f"survey {c}" for c in components)
    assert extended.unwrapped.action_meanings == default.unwrapped.action_meanings + surveys
    assert parse_action("survey b") == Action(SURVEY, "b") and extended.unwrapped.actions[-1] == Action(SURVEY, "b")
    survey_b = extended.unwrapped.action_meanings.index("survey b")
    default.reset(seed=4)
    extended.reset(seed=4)
    # carry on, a corrective action continued, a survey, a replacement and its downtime
    for action in (0, 1, 1, 1, survey_b, 0, 5, 0, 0, 0, 3, 0):
        surveying = action == survey_b
        expected = default.step(0 if surveying else action)
        observation, reward, terminated, truncated, info = extended.step(action)
        for key, value in expected[0].items():  # a survey changes nothing of the machine
            np.testing.assert_array_equal(observation[key], value)
        assert (terminated, truncated, info["true_parameters"]) == expected[2:4] + (expected[4]["true_parameters"],)
        cost = dict(info["cost"])
        assert cost.pop("survey") == (SURVEY_PRICE if surveying else 0.0)
        if surveying:
            assert reward == expected[1] - SURVEY_PRICE and cost["total"] == expected[4]["cost"]["total"] + SURVEY_PRICE
            assert info["events"] == ["survey of b"] and parse_event("survey of b") == Survey("b")
        else:
            assert (reward, cost, info["events"]) == (expected[1], expected[4]["cost"], expected[4]["events"])
    assert list(info["cost"]) == ["corrective", "replacement", "survey", "failure", "lost_production", "total"]


class _SurveyAtStep:
    """Surveys component b at its third step of each episode, otherwise carries on."""

    def __init__(self, env: Any):
        self.survey = ActionMap.from_env(env).action_meanings.index("survey b")
        self.steps = 0

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True) -> tuple[np.ndarray, None]:
        self.steps = 0 if episode_start is not None and np.asarray(episode_start).any() else self.steps + 1
        return np.array(self.survey if self.steps == 2 else 0), None


def test_the_agents_read_an_added_kind():
    env = _extended(horizon=10)
    meanings = env.unwrapped.action_meanings
    assert immediate_costs(meanings, CostModel()).tolist()[-3:] == [SURVEY_PRICE] * 3
    stats = evaluate(lambda made: _SurveyAtStep(made), lambda: _extended(horizon=10), seeds=[0], progress=False)
    assert stats.per_episode["cost"][0] == SURVEY_PRICE
    assert stats.per_episode["maintenance_actions"][0] == 1 and stats.per_episode["replacements"][0] == 0
    assert stats.per_episode["corrective_steps"][0] == 0


def test_action_kinds_are_checked():
    with pytest.raises(ValueError, match="carrying on first"):
        _ = gym.make(ENV_ID, obs_mode="sensors", action_kinds=DEFAULT_ACTION_KINDS[1:])
    with pytest.raises(ValueError, match="carrying on first"):
        _ = gym.make(ENV_ID, obs_mode="sensors", action_kinds=(*DEFAULT_ACTION_KINDS, DEFAULT_ACTION_KINDS[1]))
    with pytest.raises(ValueError, match="exists already"):
        ActionKind("replace", on_component=False)

    class Unpriced(Surveyor):
        kind = ActionKind("look at", price=lambda costs: 1.0)

    with pytest.raises(ValueError, match="needs a cost_item"):
        _ = gym.make(ENV_ID, obs_mode="sensors", action_kinds=(*DEFAULT_ACTION_KINDS, Unpriced))


def test_the_vector_env_takes_the_added_kind():
    vector = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", obs_mode="sensors", horizon=10,
                          action_kinds=(*DEFAULT_ACTION_KINDS, Surveyor))
    meanings = vector.unwrapped.action_meanings
    assert vector.single_action_space.n == len(meanings) and meanings[-1] == "survey b"
    vector.reset(seed=0)
    _, reward, _, _, info = vector.step(np.array([0, len(meanings) - 1]))
    assert reward.tolist() == [0.0, -SURVEY_PRICE] and info["cost"]["survey"].tolist() == [0.0, SURVEY_PRICE]
    assert info["events"][0] == [] and info["events"][1] == ["survey of b"]
