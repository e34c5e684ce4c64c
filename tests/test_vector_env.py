"""The batched environment is Gymnasium's SyncVectorEnv of single environments, step for step: autoreset
modes, infos layout, partial resets, vector wrappers; spaces, seeding, errors; the SB3 adapter."""

import random

import gymnasium as gym
import numpy as np
import pytest
import torch
from gymnasium.vector import AutoresetMode, SyncVectorEnv
from gymnasium.wrappers import vector as vector_wrappers
from stable_baselines3.common.vec_env import DummyVecEnv

import ea_gym  # noqa: F401 - registers the environments
from ea_gym.degradation import WearConfig
from ea_gym.diagnosis.classifier import FaultClassifier, TrainingConfig
from ea_gym.env import ENV_ID
from ea_gym.env.sb3 import MaintenanceVecEnv
from ea_gym.env.vector import BondGraphMaintenanceVectorEnv
from ea_gym.threads import MIN_ROWS_PER_THREAD, kernel_threads, set_kernel_threads

# faults from the first seconds, fast: failures (terminations) within ~10 steps, and truncations at the
# 12-step horizon for the episodes whose fault comes late or whose part is replaced in time
FAST_WEAR = {
    "k": WearConfig(process="linear", rate=(0.1, 0.2), arrival=(0.0, 6.0)),
    "m": WearConfig(process="gamma", rate=(0.1, 0.2), arrival=(0.0, 6.0)),
    "b": WearConfig(process="wiener", rate=(0.1, 0.2), arrival=(0.0, 6.0)),
}
SHORT = {"horizon": 12, "wear": FAST_WEAR}


def _vector(n, **kwargs):
    return gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


def _pair(n, mode, **kwargs):
    """The native env and the SyncVectorEnv of single envs, both in autoreset ``mode``."""
    native = _vector(n, autoreset_mode=mode, **kwargs)
    reference = SyncVectorEnv([lambda: gym.make(ENV_ID, **kwargs) for _ in range(n)], autoreset_mode=mode)
    return native, reference


def assert_same(a, b, where="result"):
    """Equal to the bit: same keys, types, dtypes and shapes, same values (object arrays element by element)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), f"{where}: keys {sorted(a)} != {sorted(b)}"
        for key in a:
            assert_same(a[key], b[key], f"{where}[{key!r}]")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and (a.dtype, a.shape) == (b.dtype, b.shape), f"{where}: {a!r} != {b!r}"
        if a.dtype == object:
            for i, (x, y) in enumerate(zip(a, b)):
                assert_same(x, y, f"{where}[{i}]")
        else:
            np.testing.assert_array_equal(a, b, err_msg=where)
    elif isinstance(a, (tuple, list)):
        assert type(a) is type(b) and len(a) == len(b), f"{where}: {a!r} != {b!r}"
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{i}]")
    else:
        assert type(a) is type(b) and a == b, f"{where}: {a!r} != {b!r}"


def _random_actions(rng, n):
    actions = rng.integers(0, 7, n)
    actions[rng.random(n) < 0.8] = 0  # mostly carry on: faults grow into failures
    return actions


@pytest.mark.parametrize("obs_mode", ["phm", "sensors", "oracle"])
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP, AutoresetMode.DISABLED])
def test_native_env_equals_sync_vector_env_of_single_envs_step_for_step(mode, obs_mode):
    n = 3
    native, reference = _pair(n, mode, obs_mode=obs_mode, **SHORT)
    assert native.metadata["autoreset_mode"] is reference.metadata["autoreset_mode"] is mode
    assert_same(native.reset(seed=7), reference.reset(seed=7), "reset")
    rng = np.random.default_rng(0)
    terminations = truncations = 0
    for step in range(40):
        actions = _random_actions(rng, n)
        result = native.step(actions)
        assert_same(result, reference.step(actions), f"step {step}")
        terminated, truncated = result[2], result[3]
        terminations += int(terminated.sum())
        truncations += int(truncated.sum())
        if mode is AutoresetMode.DISABLED and np.any(terminated | truncated):
            mask = terminated | truncated
            seeds = [100 + step if i % 2 else None for i in range(n)]  # a new seed, or the generator going on
            assert_same(
                native.reset(seed=seeds, options={"reset_mask": mask}),
                reference.reset(seed=seeds, options={"reset_mask": mask.copy()}),
                f"reset after step {step}",
            )
    assert terminations >= 3 and truncations >= 3


def test_same_step_final_obs_and_final_info_are_gymnasiums():
    venv = _vector(2, obs_mode="sensors", horizon=3, autoreset_mode=AutoresetMode.SAME_STEP)
    venv.reset(seed=0)
    for _ in range(2):
        *_, infos = venv.step(np.zeros(2, dtype=int))
        assert "final_obs" not in infos and "final_info" not in infos
    observation, _, terminated, truncated, infos = venv.step(np.zeros(2, dtype=int))
    assert truncated.all() and not terminated.any()
    assert infos["_final_obs"].all() and infos["_final_info"].all()
    assert np.all(observation["time_since_maintenance"] == 0.0)  # the new episodes' first observations
    assert all(obs["time_since_maintenance"][0] == 3.0 for obs in infos["final_obs"])
    assert infos["final_info"]["cost"]["total"].shape == (2,) and infos["final_info"]["cost"]["_total"].all()
    assert infos["final_info"]["true_rul"].dtype == np.float64 and infos["final_info"]["_true_rul"].all()
    assert np.all(infos["cost"]["total"] == 0.0)  # the top level holds the reset's info


def test_next_step_restarts_at_the_step_after_the_end():
    venv = _vector(2, obs_mode="sensors", horizon=3)
    assert venv.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    venv.reset(seed=0)
    for _ in range(3):
        observation, rewards, terminated, truncated, infos = venv.step(np.zeros(2, dtype=int))
    assert truncated.all() and "final_obs" not in infos
    assert np.all(observation["time_since_maintenance"] == 3.0)  # the ended episodes' last observations
    observation, rewards, terminated, truncated, infos = venv.step(np.full(2, 4))  # orders ignored
    assert np.all(observation["time_since_maintenance"] == 0.0) and np.all(rewards == 0.0)
    assert not (terminated | truncated).any() and np.all(infos["cost"]["replacement"] == 0.0)


def test_partial_reset_in_next_step_mode_equals_sync_vector_env():
    native, reference = _pair(3, AutoresetMode.NEXT_STEP, obs_mode="oracle", **SHORT)
    assert_same(native.reset(seed=3), reference.reset(seed=3), "reset")
    rng = np.random.default_rng(2)
    for step in range(20):
        actions = _random_actions(rng, 3)
        assert_same(native.step(actions), reference.step(actions), f"step {step}")
        if step % 5 == 4:
            mask = np.array([True, False, step % 10 == 9])
            assert_same(
                native.reset(options={"reset_mask": mask}), reference.reset(options={"reset_mask": mask.copy()}), f"reset {step}"
            )


def _wrapped(env):
    """Gymnasium's vector wrappers; its observation wrappers refuse SAME_STEP (Gymnasium's own rule)."""
    if env.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP:
        env = vector_wrappers.NormalizeObservation(vector_wrappers.FlattenObservation(env))
    env = vector_wrappers.NormalizeReward(env)
    return vector_wrappers.RecordEpisodeStatistics(env)


def _without_wall_time(infos):
    if "episode" in infos:
        infos = {**infos, "episode": {key: value for key, value in infos["episode"].items() if key not in ("t", "_t")}}
    return infos


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_gymnasium_vector_wrappers_give_what_they_give_on_sync_vector_env(mode):
    native, reference = (_wrapped(env) for env in _pair(3, mode, obs_mode="phm", **SHORT))
    assert_same(native.reset(seed=1), reference.reset(seed=1), "reset")
    rng = np.random.default_rng(4)
    episodes = finals = 0
    for step in range(30):
        actions = _random_actions(rng, 3)
        *result, infos = native.step(actions)
        finals += "final_obs" in infos  # SAME_STEP: compared below
        *expected, expected_infos = reference.step(actions)
        assert_same(tuple(result), tuple(expected), f"step {step}")
        assert_same(_without_wall_time(infos), _without_wall_time(expected_infos), f"step {step} infos")
        episodes += int(infos.get("_episode", np.zeros(3, dtype=bool)).sum())
    assert episodes >= 3  # RecordEpisodeStatistics saw episodes end
    assert (finals > 0) == (mode is AutoresetMode.SAME_STEP)


def test_dict_info_to_list_gives_each_system_its_single_env_info():
    single = gym.make(ENV_ID, obs_mode="sensors")
    as_list = vector_wrappers.DictInfoToList(_vector(2, obs_mode="sensors"))
    _, infos = as_list.reset(seed=0)
    assert infos[1] == single.reset(seed=1)[1]
    *_, infos = as_list.step(np.array([0, 4]))
    assert infos[1] == single.step(4)[-1]


def _global_random_state():
    return random.getstate(), np.random.get_state()[1].tobytes(), torch.random.get_rng_state().numpy().tobytes()


def test_making_resetting_and_stepping_touch_no_global_random_state():
    before = _global_random_state()
    single = gym.make(ENV_ID, obs_mode="phm")
    single.reset(seed=0)
    single.step(0)
    native = _vector(2, obs_mode="phm")
    native.reset(seed=0)
    native.step(np.zeros(2, dtype=int))
    adapter = MaintenanceVecEnv(2, obs_mode="phm")
    adapter.seed(0)
    adapter.reset()
    adapter.step(np.zeros(2, dtype=int))
    assert _global_random_state() == before


def test_isolation_network_training_draws_from_its_generator_only():
    rng = np.random.default_rng(0)
    features, labels = rng.standard_normal((40, 5)), rng.integers(0, 3, 40)
    before = _global_random_state()
    fitted = []
    for _ in range(2):
        classifier = FaultClassifier(["none", "k", "m"], "strong", 5)
        classifier.fit(features, labels, (features, labels), np.random.default_rng(1), TrainingConfig(epochs=3))
        fitted.append(classifier.predict_proba(features))
    assert _global_random_state() == before
    np.testing.assert_array_equal(fitted[0], fitted[1])


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


def test_autoreset_mode_by_name_and_bad_arguments_are_clear_errors():
    assert _vector(1, obs_mode="sensors", autoreset_mode="SameStep").metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
    with pytest.raises(ValueError, match="autoreset_mode must be a gymnasium.vector.AutoresetMode or one of"):
        BondGraphMaintenanceVectorEnv(1, autoreset_mode="same_step")
    venv = _vector(2, obs_mode="sensors")
    with pytest.raises(RuntimeError, match="before reset"):
        venv.step(np.zeros(2, dtype=int))
    with pytest.raises(RuntimeError, match="needs a first reset"):
        venv.reset(options={"reset_mask": np.array([True, False])})
    venv.reset(seed=0)
    with pytest.raises(ValueError, match=r"actions must be 2 ints in \[0, 6\]"):
        venv.step(np.array([0, 7]))
    with pytest.raises(ValueError, match="actions must be 2 ints"):
        venv.step(np.array([0.5, 1.0]))
    with pytest.raises(ValueError, match="num_envs must be an int in"):
        BondGraphMaintenanceVectorEnv(0)
    with pytest.raises(ValueError, match="list of 2 seeds"):
        venv.reset(seed=[1, 2, 3])
    with pytest.raises(TypeError, match="seed must be an int, None or a list"):
        venv.reset(seed=1.5)
    with pytest.raises(ValueError, match=r"reset_mask'\] must be a numpy bool array of shape \(2,\)"):
        venv.reset(options={"reset_mask": [True, False]})
    with pytest.raises(ValueError, match="at least one True"):
        venv.reset(options={"reset_mask": np.zeros(2, dtype=bool)})
    with pytest.raises(TypeError, match="unexpected keyword argument"):
        BondGraphMaintenanceVectorEnv(2, speed=3)


def test_disabled_mode_refuses_to_step_an_ended_episode():
    venv = _vector(2, obs_mode="sensors", horizon=2, autoreset_mode=AutoresetMode.DISABLED)
    venv.reset(seed=0)
    venv.step(np.zeros(2, dtype=int))
    *_, truncated, _ = venv.step(np.zeros(2, dtype=int))
    assert truncated.all()
    with pytest.raises(RuntimeError, match=r"systems \[0, 1\] ended their episodes"):
        venv.step(np.zeros(2, dtype=int))
    venv.reset(options={"reset_mask": np.array([True, True])})
    venv.step(np.zeros(2, dtype=int))


def test_sb3_vec_env_equals_dummy_vec_env_of_single_environments():
    kwargs = {"obs_mode": "oracle", **SHORT}
    batched = MaintenanceVecEnv(3, **kwargs)
    reference = DummyVecEnv([lambda: gym.make(ENV_ID, **kwargs) for _ in range(3)])
    batched.seed(5)
    reference.seed(5)
    a, b = batched.reset(), reference.reset()
    assert batched.reset_infos == reference.reset_infos
    rng = np.random.default_rng(1)
    ended = 0
    for _ in range(40):
        actions = _random_actions(rng, 3)
        a, ra, da, ia = batched.step(actions)
        b, rb, db, ib = reference.step(actions)
        assert all(np.array_equal(a[k], b[k]) for k in a)
        np.testing.assert_array_equal(ra, rb)
        np.testing.assert_array_equal(da, db)
        assert batched.reset_infos == reference.reset_infos
        for mine, theirs in zip(ia, ib):
            terminal, expected_terminal = mine.pop("terminal_observation", None), theirs.pop("terminal_observation", None)
            assert mine == theirs
            if expected_terminal is not None:
                ended += 1
                assert all(np.array_equal(terminal[k], expected_terminal[k]) for k in a)
    assert ended >= 6


def test_native_env_equals_single_envs_with_every_system_in_alarm():
    # every fault from the first second, no maintenance: the alarms rise within a few steps and the
    # isolation (features, network, balance) and the tracking filters' fault evidence run for all systems
    n = 3
    wear = {name: WearConfig(arrival=(0.0, 1.0)) for name in FAST_WEAR}
    native, reference = _pair(n, AutoresetMode.NEXT_STEP, obs_mode="phm", continue_after_failure=True, wear=wear)
    assert_same(native.reset(seed=11), reference.reset(seed=11), "reset")
    chain = native.unwrapped.core.chain
    carry_on = np.zeros(n, dtype=int)
    classified = 0
    for step in range(30):
        assert_same(native.step(carry_on), reference.step(carry_on), f"step {step}")
        classified += int(chain.isolation.counted(chain.history, chain.detector.state.alarm).sum())
    assert chain.detector.state.alarm.all() and classified >= n * 5


def test_native_env_is_the_same_on_one_kernel_thread_and_on_two():
    # enough systems in alarm that every stage's rows split over the threads (``over_rows``); random
    # maintenance and failures restart some of them on the way
    n = 2 * MIN_ROWS_PER_THREAD
    wear = {name: WearConfig(arrival=(0.0, 1.0)) for name in FAST_WEAR}
    envs = {threads: _vector(n, obs_mode="phm", continue_after_failure=True, wear=wear) for threads in (1, 2)}
    rng = np.random.default_rng(5)
    previous = kernel_threads()
    try:
        results = {}
        for threads, env in envs.items():
            set_kernel_threads(threads)
            results[threads] = env.reset(seed=3)
        assert_same(results[1], results[2], "reset")
        chain = envs[2].unwrapped.core.chain
        in_alarm = []
        for step in range(25):
            actions = _random_actions(rng, n)
            for threads, env in envs.items():
                set_kernel_threads(threads)
                results[threads] = env.step(actions)
            assert_same(results[1], results[2], f"step {step}")
            in_alarm.append(chain.detector.state.alarm.mean())
        assert max(in_alarm) >= 0.5
    finally:
        set_kernel_threads(previous)
