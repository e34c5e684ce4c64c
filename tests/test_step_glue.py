"""The step's shared arrays (idle outputs built once, observations merged in place of copies) stay private;
its compiled bookkeeping is its numpy form."""

import numpy as np
import pytest

from ea_gym._kernels.ledger import close_step, outside_limits, take_orders
from ea_gym._kernels.reference import ledger as reference
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


@pytest.mark.parametrize("dtype", [np.int64, np.int32, np.uint8, np.uint64])
def test_orders_are_the_actions_of_the_machines_up_and_refuse_any_out_of_range(dtype):
    rng = np.random.default_rng(0)
    actions, down = rng.integers(0, 7, 30).astype(dtype), rng.integers(0, 3, 30)
    orders = np.empty_like(actions)
    assert take_orders(actions, 7, down, orders)
    expected = np.empty_like(actions)
    assert reference.take_orders(actions, 7, down, expected)
    np.testing.assert_array_equal(orders, expected)
    assert orders.dtype == expected.dtype
    for bad in ([7], [-1] if np.dtype(dtype).kind == "i" else [255]):
        assert not take_orders(np.array([0, *bad], dtype=dtype), 7, np.zeros(2, dtype=int), np.empty(2, dtype=dtype))


def test_failure_check_is_its_reference():
    rng = np.random.default_rng(1)
    n, columns = 40, np.array([3, 0, 2])
    low, high = np.array([0.2, -1.0, 0.5]), np.array([0.8, 1.0, 2.5])
    theta = rng.uniform(-2.0, 3.0, (n, 4))
    theta[::7, 0] = np.nan  # NaN is inside the limits, as numpy's comparisons say
    theta[1, 3], theta[2, 3] = low[0], high[0]  # on a limit is inside
    for running in (rng.random(n) < 0.7, np.ones(n, dtype=bool), np.zeros(n, dtype=bool)):
        failed, expected = np.empty(n, dtype=bool), np.empty(n, dtype=bool)
        assert outside_limits(theta, columns, low, high, running, failed) == reference.outside_limits(theta, columns, low, high, running, expected)
        np.testing.assert_array_equal(failed, expected)
        assert expected.any() == running.any()  # failures where running, none where not


@pytest.mark.parametrize("n", [1, 9])
@pytest.mark.parametrize("stop_at_failure", [True, False])
def test_step_close_is_its_reference_to_the_bit(n, stop_at_failure):
    rng = np.random.default_rng(n)
    for _ in range(20):
        costs = rng.uniform(0.0, 1e3, (5, n)) * (rng.random((5, n)) < 0.5)  # the items, the total's row last
        costs[3] = 0.0  # lost production: counted by the close alone
        state = (costs, rng.integers(0, 4, n), rng.uniform(0.0, 50.0, n), rng.integers(0, 12, n))
        maintained, failed = rng.random(n) < 0.3, rng.random(n) < 0.3
        expected = tuple(x.copy() for x in state) + (np.empty(n, dtype=bool), np.empty(n, dtype=bool))
        got = tuple(x.copy() for x in state) + (np.empty(n, dtype=bool), np.empty(n, dtype=bool))
        for close, (costs, down, since, steps, terminated, truncated) in ((close_step, got), (reference.close_step, expected)):
            close(costs, 3, 7.3, down, since, steps, maintained, failed, 0.7, 10, stop_at_failure, terminated, truncated)
        for a, b in zip(got, expected, strict=True):
            np.testing.assert_array_equal(a, b)
            assert a.dtype == b.dtype


def test_infos_and_health_statuses_of_earlier_steps_stay_as_they_were():
    # the step's state lives in arrays updated in place: what a step reported must be copies of it
    env = BondGraphMaintenanceVectorEnv(num_envs=3, obs_mode="phm", continue_after_failure=True)
    chain = env.core.chain
    statuses = []
    update = chain.update

    def recorded(*args):
        statuses.append(update(*args))
        return statuses[-1]

    chain.update = recorded
    env.reset(seed=1)
    kept = []
    for step in range(8):
        env.step(np.full(3, 1 if step % 4 == 0 else 0))  # corrective actions move the true parameters too
        info, status = env.step_info, statuses[-1]
        kept.append((info, _copied(vars(info)), status, _copied(vars(status))))
    for info, info_copy, status, status_copy in kept:
        for record, copy in ((info, info_copy), (status, status_copy)):
            for name, value in copy.items():
                if isinstance(value, np.ndarray):
                    np.testing.assert_array_equal(getattr(record, name), value, err_msg=name)
                elif isinstance(value, dict):
                    for key, array in value.items():
                        np.testing.assert_array_equal(getattr(record, name)[key], array, err_msg=f"{name}[{key}]")


def _copied(fields):
    return {
        name: value.copy() if isinstance(value, np.ndarray) else {key: array.copy() for key, array in value.items()}
        for name, value in fields.items()
        if isinstance(value, (np.ndarray, dict))
    }
