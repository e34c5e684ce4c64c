"""The wear shaping adds gamma * Phi(s') - Phi(s), Phi = -failure cost * the true wear, to the training rewards only."""

import numpy as np
import pytest

from agents.shaping import WearShaping, true_wear
from agents.training import TrainingRun, make_vec_env

LIMITS = {"k": (85.0, 105.0), "b": (0.4, 0.6)}
NOMINAL = {"k": 100.0, "b": 0.5}


def test_true_wear_is_the_way_from_nominal_to_the_limit_on_its_side():
    assert true_wear({"k": 100.0, "b": 0.5}, NOMINAL, LIMITS).tolist() == [0.0, 0.0]
    assert true_wear({"k": 92.5, "b": 0.55}, NOMINAL, LIMITS) == pytest.approx([0.5, 0.5])
    assert true_wear({"k": 104.0, "b": 0.38}, NOMINAL, LIMITS) == pytest.approx([0.8, 1.0])  # clipped at the limit


def test_shaped_rewards_telescope_to_the_environments_return_minus_the_potential():
    run = TrainingRun(obs_mode="oracle", n_envs=2, env_kwargs={"horizon": 30, "step_seconds": 5.0})
    raw, shaped = make_vec_env(run, 2, seed=3), make_vec_env(run, 2, seed=3, shaped=True)
    wrapper = shaped.venv
    assert isinstance(wrapper, WearShaping) and wrapper.scale == 400.0 and wrapper.gamma == 0.99
    raw.reset(), shaped.reset()
    rng = np.random.default_rng(0)
    discounted = np.zeros((2, 2))  # raw, shaped per system
    for t in range(30):
        actions = np.where(rng.random(2) < 0.3, rng.integers(1, 4, 2), 0)  # some corrective steps
        _, r, dones, infos = raw.step(actions)
        _, s, shaped_dones, shaped_infos = shaped.step(actions)
        np.testing.assert_array_equal(dones, shaped_dones)
        discounted[:, 0] += 0.99**t * r
        discounted[:, 1] += 0.99**t * s
        potential = np.array([-400.0 * true_wear(info["true_parameters"], wrapper.nominal, wrapper.limits).sum() for info in infos])
    assert np.all(dones)  # the horizon ended both episodes
    # sum of gamma^t F_t = gamma^T Phi(s_T) - Phi(s_0), with Phi(s_0) = 0 (every part at nominal)
    np.testing.assert_allclose(discounted[:, 1], discounted[:, 0] + 0.99**30 * potential, rtol=1e-4, atol=1e-3)
    assert np.any(potential < 0)  # the faults wore something: the check is not trivial
    assert make_vec_env(run, 2, seed=3).venv.scale == 0.0  # validation sees the environment's rewards
    assert not isinstance(make_vec_env(TrainingRun(**{**run.__dict__, "wear_shaping": False}), 2, 3, shaped=True).venv, WearShaping)
