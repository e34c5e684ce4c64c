"""The learner's view of the observations (agents.observations)."""

import math

import numpy as np

from agents.imitation import discounted_returns
from agents.observations import LearnerView, normalised_keys
from agents.training import TrainingRun, make_vec_env


def test_log_rul_separates_the_last_minutes_and_inverts_exactly():
    env = make_vec_env(TrainingRun(obs_mode="phm"), 2, 0)
    assert isinstance(env, LearnerView)
    observation = env.reset()
    assert env.observation_space["rul"].contains(observation["rul"][0])
    rul = np.array([[0.0, 5.0, 150.0], [10.0, 999.0, 1000.0]], np.float32)
    view = env.forward({"rul": rul})["rul"]
    np.testing.assert_allclose(view, np.log1p(rul) / math.log1p(1000.0), rtol=1e-6)
    assert view[0, 2] - view[0, 1] > 0.4  # 5 s and 150 s stand far apart (VecNormalize clipped both to -10)
    np.testing.assert_allclose(env.inverse({"rul": view})["rul"], rul, rtol=1e-5, atol=1e-4)
    # only the unbounded keys are standardised; sensors mode has no RUL and passes unchanged
    assert normalised_keys(env.observation_space) == ["ea", "residual", "time_since_maintenance"]
    sensors = make_vec_env(TrainingRun(obs_mode="sensors"), 1, 0)
    assert "rul" not in sensors.observation_space.spaces and sensors.forward({"ea": rul})["ea"] is rul
    assert "wear" not in sensors.observation_space.spaces


def test_wear_is_the_way_from_nominal_to_the_limit_on_the_estimates_side():
    env = make_vec_env(TrainingRun(obs_mode="phm"), 2, 0)
    assert env.observation_space["wear"].contains(env.reset()["wear"][0])
    # components (k, m, b), nominal positions 0.75, 0.5, 0.5 of their safe ranges
    estimate = np.array([[0.9, 0.1, 0.5], [0.375, 1.0, -0.5]], np.float32)
    view = env.forward({"parameter_estimate": estimate, "rul": np.zeros((2, 3), np.float32)})
    np.testing.assert_allclose(view["wear"], [[0.6, 0.8, 0.0], [0.5, 1.0, 2.0]], rtol=1e-6)
    assert "wear" not in env.inverse(view) and env.inverse(view)["parameter_estimate"] is estimate


def test_suspect_wear_is_each_components_share_of_the_fault_belief_times_its_wear():
    env = make_vec_env(TrainingRun(obs_mode="phm"), 3, 0)
    assert env.observation_space["suspect_wear"].contains(env.reset()["suspect_wear"][0])
    # diagnosis classes (none, k, m, b); components (k, m, b) at nominal positions 0.75, 0.5, 0.5
    diagnosis = np.array([[0.5, 0.1, 0.3, 0.1], [1.0, 0.0, 0.0, 0.0], [0.2, 0.0, 0.0, 0.8]], np.float32)
    estimate = np.array([[0.9, 0.1, 0.5], [0.375, 1.0, -0.5], [0.375, 1.0, -0.5]], np.float32)
    view = env.forward({"diagnosis": diagnosis, "parameter_estimate": estimate})
    # wear (0.6, 0.8, 0), shares of the fault belief 0.5: (0.2, 0.6, 0.2); no fault believed: 0; all on b: b's wear 2
    np.testing.assert_allclose(view["suspect_wear"], [[0.12, 0.48, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 2.0]], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(env.forward({"diagnosis": diagnosis[0], "parameter_estimate": estimate[0]})["suspect_wear"],
                               [0.12, 0.48, 0.0], rtol=1e-6)  # a single observation too
    assert "suspect_wear" not in env.inverse(view)
    # models trained without the key load with a view without it; sensors mode has no diagnosis
    old = make_vec_env(TrainingRun(obs_mode="phm", suspect_wear=False), 1, 0)
    assert "suspect_wear" not in old.observation_space.spaces and "suspect_wear" not in old.reset()
    assert "suspect_wear" not in make_vec_env(TrainingRun(obs_mode="sensors"), 1, 0).observation_space.spaces


def test_activity_is_each_elements_ea_on_a_log_scale_from_a_microjoule_to_a_joule():
    env = make_vec_env(TrainingRun(obs_mode="phm"), 2, 0)
    assert env.observation_space["activity"].contains(env.reset()["activity"][0])
    ea = np.array([[1e-6, 1e-3, 1.0, 10.0], [0.0, 1e-9, 0.003, 0.01]], np.float32)
    view = env.forward({"ea": ea})
    np.testing.assert_allclose(view["activity"], [[0.0, 0.5, 1.0, 1.0], [0.0, 0.0, (math.log10(0.003) + 6) / 6, 2 / 3]], rtol=1e-5)
    assert "activity" not in env.inverse(view) and env.inverse(view)["ea"] is ea
    # models trained without the key load with a view without it
    old = make_vec_env(TrainingRun(obs_mode="phm", activity=False), 1, 0)
    assert "activity" not in old.observation_space.spaces and "activity" not in old.reset()


def test_discounted_returns_stop_at_episode_ends():
    rewards = np.array([[1.0], [2.0], [4.0], [8.0]])
    dones = np.array([[False], [True], [False], [False]])
    # step 1 ends its episode: 2; step 0: 1 + 0.5 * 2; the last two bootstrap on nothing after them
    np.testing.assert_allclose(discounted_returns(rewards, dones, 0.5)[:, 0], [2.0, 2.0, 8.0, 8.0])
