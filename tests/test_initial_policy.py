"""A new policy starts carrying on, the maintenance actions sharing the rest in inverse proportion to their cost."""

import numpy as np
import pytest
import torch

from agents.initial_policy import immediate_costs, initial_probabilities
from agents.training import TrainingRun, make_model, make_vec_env
from ea_gym.cli import main
from ea_gym.env.costs import CostModel

MEANINGS = ("carry on", "corrective action on k", "corrective action on b", "replace k", "replace b")


def test_immediate_costs_count_a_replacements_downtime():
    costs = CostModel(corrective=2.0, replacement=30.0, lost_production=5.0, replace_downtime=4)
    assert immediate_costs(MEANINGS, costs).tolist() == [0.0, 2.0, 2.0, 50.0, 50.0]


def test_initial_probabilities_share_the_rest_by_inverse_cost():
    costs = CostModel(corrective=2.0, replacement=30.0, lost_production=5.0, replace_downtime=4)
    p = initial_probabilities(MEANINGS, costs, carry_on=0.8)
    # the maintenance weights 1/2, 1/2, 1/50, 1/50 sum to 1.04: a corrective action 0.2 * 0.5 / 1.04
    assert p == pytest.approx([0.8, 0.1 / 1.04, 0.1 / 1.04, 0.004 / 1.04, 0.004 / 1.04])
    assert p.sum() == pytest.approx(1.0)
    free = initial_probabilities(MEANINGS, CostModel(corrective=0.0), carry_on=0.6)
    assert free == pytest.approx([0.6, 0.2, 0.2, 0.0, 0.0])  # free actions share the rest
    for bad in (0.0, 1.0, -0.1, float("nan")):
        with pytest.raises(ValueError, match="initial_carry_on must be a probability"):
            initial_probabilities(MEANINGS, CostModel(), carry_on=bad)


def test_a_new_ppo_policy_acts_with_the_initial_probabilities_in_every_state():
    run = TrainingRun(obs_mode="oracle", n_envs=2, env_kwargs={"horizon": 20}, hyperparameters={"n_steps": 16, "batch_size": 32})
    env = make_vec_env(run, 2, seed=0)
    model, normalized = make_model(run, env, {"n_steps": 16, "batch_size": 32}, None, None, None)
    assert run.initial_carry_on == 0.8  # the default
    expected = initial_probabilities(env.get_attr("action_meanings")[0], CostModel(), 0.8)
    observation = normalized.reset()
    for _ in range(3):
        tensor, _ = model.policy.obs_to_tensor(observation)
        with torch.no_grad():
            probabilities = model.policy.get_distribution(tensor).distribution.probs.numpy()
        # the head's weights are tiny (orthogonal, gain 0.01): the bias sets the distribution
        np.testing.assert_allclose(probabilities, np.tile(expected, (2, 1)), rtol=0.05, atol=1e-4)
        observation, *_ = normalized.step(np.array([1, 3]))
    uniform, _ = make_model(TrainingRun(**{**run.__dict__, "initial_carry_on": None}), make_vec_env(run, 2, seed=0),
                        {"n_steps": 16, "batch_size": 32}, None, None, None)
    assert torch.all(uniform.policy.action_net.bias == 0)  # stable-baselines3's own start


def test_train_command_refuses_a_carry_on_probability_outside_0_1(capsys):
    for bad in ("1", "1.5", "-0.2", "nan", "x"):
        with pytest.raises(SystemExit):
            main(["train", "--initial-carry-on", bad, "--out", "x"])
        assert "expected a probability in (0, 1), or 0 for a uniform start" in capsys.readouterr().err
