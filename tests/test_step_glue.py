"""The step's shared arrays (idle outputs built once, observations merged in place of copies) stay private."""

import numpy as np

from ea_gym.env.vector import BondGraphMaintenanceVectorEnv


def _snapshot(observation):
    return {key: value.copy() for key, value in observation.items()}


def test_observations_are_fresh_arrays_and_idle_outputs_stay_unchanged():
    env = BondGraphMaintenanceVectorEnv(num_envs=4, obs_mode="phm", continue_after_failure=True)
    core = env.core
    idle = {key: value.copy() for key, value in core.observer.idle.items()}
    observation, _ = env.reset(seed=0)
    kept = [(observation, _snapshot(observation))]
    rng = np.random.default_rng(0)
    for step in range(12):
        # replacements put machines down (their rows show idle outputs); carry-on steps have none down
        actions = rng.integers(0, env.single_action_space.n, 4) if step % 3 == 0 else np.zeros(4, dtype=int)
        observation, *_ = env.step(actions)
        for value in observation.values():
            value += 1.0  # a user writing into an observation must not change what the env shows next
        kept.append((observation, _snapshot(observation)))
    for observation, snapshot in kept:
        for key in observation:
            np.testing.assert_array_equal(observation[key], snapshot[key])
    for key, value in core.observer.idle.items():
        np.testing.assert_array_equal(value, idle[key])
