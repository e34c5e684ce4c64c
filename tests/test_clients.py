"""The RL libraries as their users call them: the environments' spec, the flat info layout TorchRL batches,
stable-baselines3 with VecMonitor and TorchRL's GymEnv (RLlib's recipe: tests/test_ray.py, in scripts/test_ray.sh's
environment). docs/rl-libraries.md shows the same recipes, run by tests/test_docs.py.
"""

from __future__ import annotations

import warnings
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.wrappers import TimeLimit

import ea_gym  # noqa: F401 - registers the environments
from ea_gym.env import ENV_ID
from ea_gym.env.sb3 import MaintenanceVecEnv
from ea_gym.env.vector import BondGraphMaintenanceVectorEnv


def _wrappers(env: gym.Env) -> list[type]:
    chain = []
    while isinstance(env, gym.Wrapper):
        chain.append(type(env))
        env = env.env
    return chain


def _episode(env: gym.Env, seed: int) -> list[tuple[Any, ...]]:
    steps = [env.reset(seed=seed)]
    while True:
        observation, reward, terminated, truncated, info = env.step(0)
        steps.append((observation, reward, terminated, truncated, info))
        if terminated or truncated:
            return steps


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[key], b[key]) for key in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray):
        return isinstance(b, np.ndarray) and a.dtype == b.dtype and (np.array_equal(a, b) if a.dtype != object else _same(list(a), list(b)))
    return bool(a == b)


def test_the_spec_gives_the_horizon_and_make_adds_no_time_limit():
    env = gym.make(ENV_ID)
    assert env.spec.max_episode_steps == 500 and TimeLimit not in _wrappers(env)
    env.close()
    short = gym.make(ENV_ID, horizon=7, obs_mode="sensors")
    assert short.spec.max_episode_steps == 7 and short.spec.kwargs["horizon"] == 7
    episode = _episode(short, seed=3)
    assert len(episode) == 8 and episode[-1][3] and not episode[-1][2]  # truncated at the 7th step
    # made again from its spec: TimeLimit(7) truncates at the env's own step, the episode is the same
    again = gym.make(short.spec)
    assert again.spec.max_episode_steps == 7 and TimeLimit in _wrappers(again)
    assert _same(_episode(again, seed=3), episode)
    short.close()
    again.close()


def test_max_episode_steps_given_to_make_wraps_its_time_limit_and_the_vector_spec_gives_the_horizon():
    env = gym.make(ENV_ID, max_episode_steps=3, obs_mode="sensors")
    assert env.spec.max_episode_steps == 3 and len(_episode(env, seed=0)) == 4
    env.close()
    vector = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", horizon=9, obs_mode="sensors")
    assert vector.spec.max_episode_steps == 9
    vector.close()


def _flattened(info: dict[str, Any]) -> dict[str, Any]:
    """The nested layout's numbers on one level, as ``info_layout="flat"`` names them."""
    flat = {key: info[key] for key in ("true_rul", "failed")}
    for group in ("cost", "true_parameters"):
        flat.update({f"{group}_{key}": value for key, value in info[group].items()})
    return flat


def test_the_flat_layout_holds_the_nested_numbers_and_the_default_is_unchanged():
    nested = gym.make(ENV_ID, obs_mode="sensors", horizon=12, corrective_rate=0.5)
    flat = gym.make(ENV_ID, obs_mode="sensors", horizon=12, corrective_rate=0.5, info_layout="flat")
    for a, b in zip(_episode(nested, seed=5), _episode(flat, seed=5)):
        assert "events" in a[-1] and _same(_flattened(a[-1]), b[-1]) and _same(a[:-1], b[:-1])
    nested.close()
    flat.close()
    with pytest.raises(ValueError, match="info_layout must be one of"):
        gym.make(ENV_ID, info_layout="tensors")


@pytest.mark.parametrize("autoreset_mode", ["NextStep", "SameStep"])
def test_the_flat_layout_of_the_vector_env_is_gymnasiums_batching_of_the_single_ones(autoreset_mode):
    """The native vector env with ``info_layout="flat"`` against gymnasium's SyncVectorEnv of flat single envs,
    episodes of 4 steps ending inside the 6 steps (final infos included)."""
    kwargs = {"obs_mode": "sensors", "horizon": 4, "info_layout": "flat"}
    native = BondGraphMaintenanceVectorEnv(3, autoreset_mode=autoreset_mode, **kwargs)
    sync = gym.vector.SyncVectorEnv([lambda: gym.make(ENV_ID, **kwargs) for _ in range(3)], autoreset_mode=autoreset_mode)
    assert _same(native.reset(seed=11), sync.reset(seed=11))
    rng = np.random.default_rng(0)
    for _ in range(6):
        actions = rng.integers(native.single_action_space.n, size=3)
        ours, theirs = native.step(actions), sync.step(actions)
        assert _same(ours, theirs)
        numbers = {key: value for key, value in ours[-1].items() if not key.startswith("final")}  # final_obs: gymnasium's objects
        assert all(isinstance(value, np.ndarray) and value.dtype != object for value in numbers.values())
    native.close()
    sync.close()


def test_sb3_with_vec_monitor_logs_episodes_and_evaluates_without_a_warning():
    """The docs' SB3 recipe: VecMonitor over MaintenanceVecEnv fills ``info["episode"]``, so PPO logs each
    episode's return and length and ``evaluate_policy`` finds its monitor (no warning)."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.vec_env import VecMonitor

    vec = VecMonitor(MaintenanceVecEnv(2, obs_mode="sensors", horizon=8))
    model = PPO("MultiInputPolicy", vec, n_steps=8, batch_size=16, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=16)
    assert [info["l"] for info in model.ep_info_buffer] == [8, 8]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rewards, lengths = evaluate_policy(model, vec, n_eval_episodes=2, return_episode_rewards=True)
    assert not [w for w in caught if "Monitor" in str(w.message)]
    assert lengths == [8, 8] and all(reward <= 0 for reward in rewards)
    vec.close()


def test_torchrl_gym_env_with_num_envs_batches_the_flat_infos():
    """TorchRL's ``GymEnv(ID, num_envs=N)`` (gymnasium's AsyncVectorEnv of single envs, in spawned processes:
    the ``ea_gym:`` prefix imports ea_gym there) passes check_env_specs; episodes are truncated at the horizon
    and a step's cost is minus its reward."""
    pytest.importorskip("torchrl")
    from torchrl.envs import GymEnv
    from torchrl.envs.utils import check_env_specs

    env = GymEnv("ea_gym:ea_gym/SpringMassDamper-v0", num_envs=2, obs_mode="sensors", horizon=4, info_layout="flat")
    try:
        check_env_specs(env)
        rollout = env.rollout(6, break_when_any_done=False)
    finally:
        env.close()
    assert rollout.batch_size == (2, 6)
    truncated = rollout["next", "truncated"].squeeze(-1)
    assert truncated[:, 3].all() and not truncated[:, :3].any()
    cost, reward = rollout["next", "cost_total"].squeeze(-1).numpy(), rollout["next", "reward"].squeeze(-1).numpy()
    # an episode's last step shows the next episode's first info (TorchRL's autoreset keeps the reset's): not compared
    inside = ~truncated.numpy()
    assert np.array_equal(cost[inside], -reward[inside].astype(np.float64)) and cost[inside].sum() > 0
