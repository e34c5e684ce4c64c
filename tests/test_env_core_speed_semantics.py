"""The batched step's fast paths compute exactly what the plain formulations do."""

import gymnasium as gym
import numpy as np
import pytest

import ea_gym  # noqa: F401 - registers the environments
from ea_gym._kernels.propagation import simulate_hermite
from ea_gym.bondgraph.simulation import (
    Discretization,
    MeasuredSimulation,
    discretize,
    hermite_coefficients,
    propagate,
    simulate_batch,
    simulate_measured,
    unique_rows,
)
from ea_gym.degradation import WearConfig
from ea_gym.diagnosis.monitor import Monitor
from ea_gym.env import ENV_ID
from ea_gym.models import get_model
from ea_gym.sensors import SystemNoise, add_sensor_noise
from ea_gym.threads import MIN_ROWS_PER_THREAD, kernel_threads, set_kernel_threads

MODELS = ("spring_mass_damper", "rlc_circuit", "dc_motor")


def _plain_simulation(space, h, u, du, theta, x0):
    """simulate_batch as it was: every row discretized, Hermite coefficients stored, then propagated."""
    mats = space.matrices(theta)
    step = discretize(mats.A, mats.B, h)
    return propagate(Discretization(step.Phi[:, None], step.Gamma[:, None]), hermite_coefficients(u, du, h), x0)


@pytest.mark.parametrize("name", MODELS)
def test_simulate_batch_equals_the_row_by_row_formulation(name):
    model = get_model(name)
    space = model.state_space
    rng = np.random.default_rng(1)
    n, samples = 40, 60
    theta = np.tile(model.parameter_vector(), (n, 1))
    theta[::4] *= 1.0 + 0.2 * rng.random((len(theta[::4]), theta.shape[1]))  # most rows nominal, some not
    u = rng.standard_normal((n, samples, space.n_inputs))
    du = rng.standard_normal((n, samples, space.n_inputs))
    x0 = rng.standard_normal((n, space.n_states))
    np.testing.assert_array_equal(simulate_batch(space, 0.01, u, du, theta, x0), _plain_simulation(space, 0.01, u, du, theta, x0))


def test_simulate_batch_checks_shapes():
    space = get_model("spring_mass_damper").state_space
    theta = np.tile(get_model("spring_mass_damper").parameter_vector(), (3, 1))
    u = np.zeros((3, 10, 1))
    with pytest.raises(ValueError, match="simulate_batch"):
        simulate_batch(space, 0.01, u, u, theta, np.zeros((2, space.n_states)))
    with pytest.raises(ValueError, match="simulate_batch"):
        simulate_batch(space, 0.01, u[:2], u[:2], theta, np.zeros((3, space.n_states)))


def test_fused_kernel_handles_several_inputs_and_shared_matrices():
    rng = np.random.default_rng(2)
    nx, nu, n, samples, h = 3, 2, 7, 25, 0.02
    Phi = 0.3 * rng.standard_normal((4, nx, nx))
    Gamma = rng.standard_normal((4, nx, 4 * nu))
    index = rng.integers(0, 4, n)
    u, du = rng.standard_normal((2, 3, samples, nu))
    inputs = rng.integers(0, 3, n)  # systems driven by shared input rows
    x0 = rng.standard_normal((n, nx))
    expected = propagate(Discretization(Phi[index][:, None], Gamma[index][:, None]), hermite_coefficients(u[inputs], du[inputs], h), x0)
    signals, last = np.empty((n, nx, samples)), np.empty((n, nx))
    gain = rng.uniform(0.5, 2.0, (n, nx))
    simulate_hermite(Phi, Gamma, index, u, du, inputs, h, x0, gain, signals, last)
    np.testing.assert_array_equal(signals, expected.transpose(0, 2, 1) * gain[:, :, None])
    np.testing.assert_array_equal(last, expected[:, -1])


def test_measured_simulation_is_the_states_times_the_gains_in_the_sensors_layout():
    model = get_model("spring_mass_damper")
    space = model.state_space
    rng = np.random.default_rng(4)
    n, samples = 5, 40
    theta = model.parameter_vector()[None] * rng.uniform(0.8, 1.2, (n, len(space.parameter_names)))
    u, du = rng.standard_normal((2, n, samples, 1))
    x0 = rng.standard_normal((n, space.n_states))
    gain = rng.uniform(0.5, 2.0, (n, space.n_states))
    states = simulate_batch(space, 0.01, u, du, theta, x0)
    signals, last = simulate_measured(space, 0.01, u, du, theta, x0, gain)
    np.testing.assert_array_equal(signals, states.transpose(0, 2, 1) * gain[:, :, None])
    np.testing.assert_array_equal(last, states[:, -1])
    wider = np.full((n, space.n_states + 1, samples), np.nan)  # written in place, the last channel left alone
    simulate_measured(space, 0.01, u, du, theta, x0, gain, out=wider[:, :-1])
    np.testing.assert_array_equal(wider[:, :-1], signals)
    assert np.isnan(wider[:, -1]).all()
    # systems driven by shared rows of u: the same as those rows repeated
    inputs = np.array([1, 0, 1, 1, 0])
    shared = simulate_measured(space, 0.01, u[:2], du[:2], theta, x0, gain, inputs=inputs)
    repeated = simulate_measured(space, 0.01, u[inputs], du[inputs], theta, x0, gain)
    np.testing.assert_array_equal(shared[0], repeated[0])
    np.testing.assert_array_equal(shared[1], repeated[1])
    with pytest.raises(ValueError, match="inputs"):
        simulate_measured(space, 0.01, u[:2], du[:2], theta, x0, gain, inputs=np.array([0, 1, 2, 0, 1]))


def test_a_measured_simulation_keeps_the_discretizations_of_the_rows_that_stay(monkeypatch):
    """Window after window, with rows changing in place, MeasuredSimulation gives simulate_measured's bits and
    discretizes only the distinct rows that changed."""
    model = get_model("spring_mass_damper")
    space = model.state_space
    rng = np.random.default_rng(5)
    n, samples = 4, 30
    inputs = np.tile(np.arange(n), 2)  # plants and references, as an environment's batch
    nominal = np.repeat(model.parameter_vector()[None], 2 * n, axis=0)
    worn = nominal.copy()
    worn[1, 1] *= 1.01
    more = worn.copy()
    more[0, 0] *= 0.99
    more[2, 0] *= 0.98
    signed = more.copy()
    signed[3, 2] = -0.0  # a row differs from its predecessor in a zero's sign only
    more[3, 2] = 0.0
    u, du = rng.standard_normal((2, n, samples, 1))
    x0 = rng.standard_normal((2 * n, space.n_states))
    gain = rng.uniform(0.5, 2.0, (2 * n, space.n_states))
    simulation = MeasuredSimulation(space, 0.01, inputs, n)
    computed: list[int] = []
    matrices = space.matrices
    monkeypatch.setattr(space, "matrices", lambda theta: computed.append(len(theta)) or matrices(theta))
    for theta, rows in ((nominal, 1), (nominal.copy(), 0), (worn, 1), (more, 3), (signed, 1), (signed.copy(), 0), (nominal, 1)):
        computed.clear()
        got = simulation(u, du, theta, x0, gain)
        assert computed == ([rows] if rows else [])
        computed.clear()
        expected = simulate_measured(space, 0.01, u, du, theta, x0, gain, inputs=inputs)
        for a, b in zip(got, expected):
            assert a.tobytes() == b.tobytes()
    with pytest.raises(ValueError, match="inputs"):
        MeasuredSimulation(space, 0.01, inputs, n - 1)


@pytest.mark.parametrize("name", MODELS)
def test_a_rows_discretization_is_the_same_alone_and_in_a_batch(name):
    """numpy's solve and matmul and the compiled exponential work matrix by matrix: what lets a kept row's
    discretization stand for the one a batch would compute."""
    model = get_model(name)
    space = model.state_space
    theta = model.parameter_vector() * np.random.default_rng(6).uniform(0.5, 2.0, (5, len(space.parameter_names)))
    mats = space.matrices(theta)
    batch = discretize(mats.A, mats.B, 0.01)
    for k in range(len(theta)):
        alone = space.matrices(theta[k : k + 1])
        step = discretize(alone.A, alone.B, 0.01)
        assert alone.A.tobytes() == mats.A[k : k + 1].tobytes() and alone.B.tobytes() == mats.B[k : k + 1].tobytes()
        assert step.Phi.tobytes() == batch.Phi[k : k + 1].tobytes() and step.Gamma.tobytes() == batch.Gamma[k : k + 1].tobytes()


def test_unique_rows_maps_every_row_to_an_identical_one():
    rng = np.random.default_rng(3)
    base = rng.standard_normal((5, 3))
    theta = base[rng.integers(0, 5, 50)]
    distinct, index = unique_rows(theta)
    assert len(distinct) == len(np.unique(theta, axis=0))
    np.testing.assert_array_equal(distinct[index], theta)
    one, index = unique_rows(theta[:1])
    np.testing.assert_array_equal(one[index], theta[:1])


def test_unique_rows_of_a_few_rows_are_those_of_np_unique_in_its_order():
    rng = np.random.default_rng(4)
    for n in range(2, 12):  # both sides of the few rows sorted in Python
        for _ in range(50):
            theta = rng.standard_normal((n, 3)) * rng.choice([-1.0, 1.0, 0.0], (n, 3))
            theta[rng.integers(0, n)] = theta[0]
            keys = theta.view(np.dtype((np.void, theta.itemsize * 3))).ravel()
            _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
            distinct, index = unique_rows(theta)
            np.testing.assert_array_equal(distinct, theta[first])
            np.testing.assert_array_equal(index, inverse.reshape(n))


def _plain_powers(monitor: Monitor, signals, start):
    """Monitor.powers as it was: whole-signal filtering, einsum output map, dict of element powers."""
    smooth = monitor.filter(signals)[..., start:]
    inertia_channels = [j for j, _ in monitor._inertance.values()]
    slope = monitor.filter(signals[..., inertia_channels, :], deriv=1)[..., start:]
    u = smooth[..., -1, :]
    states = smooth[..., :-1, :] * monitor._to_state[:, None]
    bonds = np.einsum("bs,...st->...bt", monitor._Cy, states) + monitor._Dy[:, 0][:, None] * u[..., None, :]
    effort, flow = monitor.model.state_space.element_signals(np.moveaxis(bonds, -2, -1))
    power = {name: effort[name] * flow[name] for name in effort}
    for k, (name, (j, inertance)) in enumerate(monitor._inertance.items()):
        power[name] = inertance * smooth[..., j, :] * slope[..., k, :]
    return np.stack([power[name] for name in monitor.elements], axis=-2), smooth


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("start", [0, 10, 51])
def test_powers_equal_the_plain_formulation(name, start):
    model = get_model(name)
    monitor = Monitor(model, 0.01)
    rng = np.random.default_rng(4)
    nx = len(model.state_names)
    signals = rng.standard_normal((12, nx + 1, 180))
    signals[3:6, -1] = signals[2, -1]  # consecutive rows sharing their load, as the inversion's candidates do
    signals[7:, -1] = signals[6, -1]
    for batch in (signals, signals.reshape(3, 4, nx + 1, -1)):
        power, smooth = monitor.powers(batch, start)
        expected_power, expected_smooth = _plain_powers(monitor, batch, start)
        assert power.shape == expected_power.shape and smooth.shape == expected_smooth.shape
        np.testing.assert_allclose(power, expected_power, rtol=1e-13, atol=1e-13 * np.abs(expected_power).max())
        np.testing.assert_allclose(smooth, expected_smooth, rtol=1e-13, atol=1e-13 * np.abs(expected_smooth).max())


def test_element_bonds_agree_with_element_signals():
    space = get_model("dc_motor").state_space
    values = np.random.default_rng(5).standard_normal((6, 2 * space.n_bonds))
    effort, flow = space.element_signals(values)
    for name, e, f, sign in zip(*space.element_bonds()):
        np.testing.assert_array_equal(effort[name], values[..., e])
        np.testing.assert_array_equal(flow[name], sign * values[..., f])


def test_batched_sensor_noise_draws_what_each_system_would():
    env = gym.make_vec(ENV_ID, num_envs=4, vectorization_mode="vector_entry_point", obs_mode="sensors", noise=0.05)
    core = env.unwrapped.core
    clean = np.random.default_rng(6).standard_normal((4, 2, 101))
    rngs = [np.random.default_rng(10 + i) for i in range(4)]
    again = [np.random.default_rng(10 + i) for i in range(4)]
    expected = np.stack([add_sensor_noise(clean[i], 0.05, again[i]) for i in range(4)])
    np.testing.assert_array_equal(core.operation.sensor_noise(clean, rngs), expected)
    assert all(a.random() == b.random() for a, b in zip(rngs, again))  # each generator left in the same state


def test_sensor_noise_is_the_same_on_two_kernel_threads_and_from_a_shared_generator():
    """Rows split over the threads draw what each system would; systems sharing one generator draw from it in turn."""
    n = 2 * MIN_ROWS_PER_THREAD + 8
    clean = np.random.default_rng(8).standard_normal((n, 2, 101))
    noise = SystemNoise(0.05)
    previous = kernel_threads()
    try:
        set_kernel_threads(2)
        rngs = [np.random.default_rng(30 + i) for i in range(n)]
        again = [np.random.default_rng(30 + i) for i in range(n)]
        expected = np.stack([add_sensor_noise(clean[i], 0.05, again[i]) for i in range(n)])
        np.testing.assert_array_equal(noise(clean, rngs), expected)
        shared, shared_again = np.random.default_rng(40), np.random.default_rng(40)
        expected = np.stack([add_sensor_noise(clean[i], 0.05, shared_again) for i in range(n)])
        np.testing.assert_array_equal(noise(clean, [shared] * n), expected)
    finally:
        set_kernel_threads(previous)


def test_compiled_noise_draws_follow_any_bit_generator_and_new_generators():
    """Each bit generator kind gives numpy's numbers; generators replaced between calls are drawn from, not stale ones."""
    env = gym.make_vec(ENV_ID, num_envs=3, vectorization_mode="vector_entry_point", obs_mode="sensors", noise=0.05)
    core = env.unwrapped.core
    clean = np.random.default_rng(7).standard_normal((3, 2, 4001))  # enough draws to reach the ziggurat's tail
    for kind in (np.random.PCG64, np.random.MT19937, np.random.Philox, np.random.SFC64):
        rngs = [np.random.Generator(kind(20 + i)) for i in range(3)]
        again = [np.random.Generator(kind(20 + i)) for i in range(3)]
        for _ in range(2):  # the second call reuses the addresses taken by the first
            expected = np.stack([add_sensor_noise(clean[i], 0.05, again[i]) for i in range(3)])
            np.testing.assert_array_equal(core.operation.sensor_noise(clean, rngs), expected)
        rngs[1], again[1] = np.random.Generator(kind(99)), np.random.Generator(kind(99))
        expected = np.stack([add_sensor_noise(clean[i], 0.05, again[i]) for i in range(3)])
        np.testing.assert_array_equal(core.operation.sensor_noise(clean, rngs), expected)
        assert all(a.random() == b.random() for a, b in zip(rngs, again))


def test_batched_replacements_and_failures_match_single_environments():
    """Random actions replace and fail often; events, costs and state match system by system."""
    components = get_model("spring_mass_damper").safe_limits
    fast = {name: WearConfig(rate=(0.1, 0.2), arrival=(0.0, 5.0)) for name in components}  # failures within ~10 steps
    n, seed, kwargs = 4, 3, {"obs_mode": "oracle", "continue_after_failure": True, "horizon": 400, "wear": fast}
    venv = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    envs = [gym.make(ENV_ID, **kwargs) for _ in range(n)]
    venv.reset(seed=seed)
    for i, env in enumerate(envs):
        env.reset(seed=seed + i)
    rng = np.random.default_rng(0)
    replaced = failed = 0
    for _ in range(120):
        actions = rng.integers(0, venv.single_action_space.n, n)
        actions[rng.random(n) < 0.7] = 0  # let faults grow into failures now and then
        observation, rewards, _, _, infos = venv.step(actions)
        for i, env in enumerate(envs):
            single, reward, _, _, info = env.step(int(actions[i]))
            assert list(infos["events"][i]) == info["events"]
            assert rewards[i] == reward
            for key, value in single.items():
                np.testing.assert_array_equal(observation[key][i], value)
            replaced += sum("replacement" in e for e in info["events"])
            failed += sum("failure" in e for e in info["events"])
    assert replaced > 10 and failed > 5
