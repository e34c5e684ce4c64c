"""The batched environment: same episodes as single environments, Gymnasium's spaces, seeding, autoreset."""

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.vec_env import DummyVecEnv

import ea_gym  # noqa: F401 - registers the environments
from ea_gym.env import ENV_ID
from ea_gym.env.sb3 import MaintenanceVecEnv
from ea_gym.env.vector import BondGraphMaintenanceVectorEnv


def _vector(n, **kwargs):
    return gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


@pytest.mark.parametrize("mode", ["phm", "oracle"])
def test_batched_episodes_equal_single_environment_episodes(mode):
    n, seed, kwargs = 3, 21, {"obs_mode": mode, "horizon": 60}
    venv = _vector(n, **kwargs)
    assert isinstance(venv.unwrapped, BondGraphMaintenanceVectorEnv)
    envs = [gym.make(ENV_ID, **kwargs) for _ in range(n)]
    observation, _ = venv.reset(seed=seed)
    singles = [env.reset(seed=seed + i)[0] for i, env in enumerate(envs)]
    for i, single in enumerate(singles):
        assert all(np.array_equal(observation[key][i], value) for key, value in single.items())
    rng = np.random.default_rng(0)
    ended = 0
    for _ in range(150):  # two autoresets at the 60-step horizon, and failures from random actions
        actions = rng.integers(0, venv.single_action_space.n, n)
        observation, rewards, terminated, truncated, infos = venv.step(actions)
        for i, env in enumerate(envs):
            single, reward, term, trunc, info = env.step(int(actions[i]))
            assert rewards[i] == pytest.approx(reward, abs=1e-9)
            assert (terminated[i], truncated[i]) == (term, trunc)
            assert infos["true_rul"][i] == pytest.approx(info["true_rul"], abs=1e-9) or info["true_rul"] == np.inf
            if term or trunc:
                ended += 1
                for key, value in single.items():
                    np.testing.assert_allclose(infos["final_obs"][i][key], value, rtol=0, atol=1e-9)
                single, _ = env.reset()
            for key, value in single.items():
                np.testing.assert_allclose(observation[key][i], value, rtol=0, atol=1e-9)
    assert ended >= n * 2


def test_spaces_hold_the_observations_and_actions():
    venv = _vector(4, obs_mode="phm")
    observation, infos = venv.reset(seed=0)
    assert venv.observation_space.contains(observation)
    assert venv.action_space.shape == (4,)
    for _ in range(5):
        observation, rewards, terminated, truncated, infos = venv.step(venv.action_space.sample())
        assert venv.observation_space.contains(observation)
        assert rewards.shape == terminated.shape == truncated.shape == (4,)
        assert infos["_true_rul"].all()


def test_seeding_same_seed_same_and_different_seed_different():
    def first_steps(seed):
        venv = _vector(2, obs_mode="sensors")
        venv.reset(seed=seed)
        return [venv.step(np.zeros(2, dtype=int))[0]["ea"] for _ in range(3)]

    a, b, c = first_steps(1), first_steps(1), first_steps(2)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c))


def test_autoreset_returns_the_next_episode_in_the_same_step():
    venv = _vector(2, obs_mode="sensors", horizon=3)
    venv.reset(seed=0)
    for _ in range(2):
        _, _, terminated, truncated, infos = venv.step(np.zeros(2, dtype=int))
        assert "final_obs" not in infos
    observation, _, terminated, truncated, infos = venv.step(np.zeros(2, dtype=int))
    assert truncated.all() and not terminated.any()
    assert infos["_final_obs"].all()
    assert np.all(observation["time_since_maintenance"] == 0.0)  # the new episode's first observation
    assert all(obs["time_since_maintenance"][0] == 3.0 for obs in infos["final_obs"])
    _, _, _, truncated, _ = venv.step(np.zeros(2, dtype=int))
    assert not truncated.any()


def test_bad_actions_and_arguments_are_clear_errors():
    venv = _vector(2, obs_mode="sensors")
    venv.reset(seed=0)
    with pytest.raises(ValueError, match=r"actions must be 2 ints in \[0, 6\]"):
        venv.step(np.array([0, 7]))
    with pytest.raises(ValueError, match="actions must be 2 ints"):
        venv.step(np.array([0.5, 1.0]))
    with pytest.raises(ValueError, match="num_envs must be a positive int"):
        BondGraphMaintenanceVectorEnv(0)
    with pytest.raises(ValueError, match="list of 2 seeds"):
        venv.reset(seed=[1, 2, 3])
    with pytest.raises(TypeError, match="unexpected keyword argument"):
        BondGraphMaintenanceVectorEnv(2, speed=3)


def test_sb3_vec_env_equals_dummy_vec_env_of_single_environments():
    kwargs = {"obs_mode": "oracle", "horizon": 40}
    batched = MaintenanceVecEnv(3, **kwargs)
    reference = DummyVecEnv([lambda: gym.make(ENV_ID, **kwargs) for _ in range(3)])
    batched.seed(5)
    reference.seed(5)
    a, b = batched.reset(), reference.reset()
    rng = np.random.default_rng(1)
    for _ in range(90):
        actions = rng.integers(0, 7, 3)
        a, ra, da, ia = batched.step(actions)
        b, rb, db, ib = reference.step(actions)
        assert all(np.array_equal(a[k], b[k]) for k in a)
        np.testing.assert_array_equal(ra, rb)
        np.testing.assert_array_equal(da, db)
        for i in np.flatnonzero(da):
            assert ia[i]["TimeLimit.truncated"] == ib[i]["TimeLimit.truncated"]
            assert all(np.array_equal(ia[i]["terminal_observation"][k], ib[i]["terminal_observation"][k]) for k in a)
