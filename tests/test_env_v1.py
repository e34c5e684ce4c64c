"""The v1 environments, where every part ages at once: Gymnasium's checks, the native vector env against
Gymnasium's SyncVectorEnv, the world's draws (tolerances, a wear process per part, background ageing), the
per-part true RUL against a hand computation, and v0 left as it was."""

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode, SyncVectorEnv
from test_vector_env import assert_same

import ea_gym  # noqa: F401 - registers the environments
from ea_gym.degradation import BACKGROUND_WEAR, WearConfig
from ea_gym.env import ENV_IDS, V1_ENV_IDS, V1_SETTINGS, env_id
from ea_gym.env.config import EnvConfig
from ea_gym.models import get_model

V1 = V1_ENV_IDS[0]
MODEL = get_model("spring_mass_damper")
COMPONENTS = ("k", "m", "b")  # the maintainable components, in the action table's order
# every part's fault early and fast: failures within ~15 steps, overlapping; one process of each kind
FAST_WEAR = {
    "k": WearConfig(process="linear", rate=(0.05, 0.1), arrival=(0.0, 8.0)),
    "m": WearConfig(process="gamma", rate=(0.05, 0.1), arrival=(0.0, 8.0)),
    "b": WearConfig(process="wiener", rate=(0.05, 0.1), arrival=(0.0, 8.0)),
}
SHORT = {"horizon": 14, "wear": FAST_WEAR}


def _vector(n, env=V1, **kwargs):
    return gym.make_vec(env, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


def test_v1_ids_are_registered_with_the_v1_settings_and_v0_keeps_none():
    assert env_id(version=1) == V1 and env_id("rlc_circuit", version=1) == V1_ENV_IDS[1]
    assert env_id() == ENV_IDS[0] and env_id("rlc_circuit") == ENV_IDS[1]
    for v0, v1 in zip(ENV_IDS, V1_ENV_IDS):
        assert gym.spec(v0).kwargs == {} and gym.spec(v1).kwargs == V1_SETTINGS
    assert V1_SETTINGS == {"concurrent_wear": True, "background_wear": 2e-4, "tolerance": 0.125, "commission_seconds": 20.0}
    config = gym.make(V1).unwrapped.config
    assert config.concurrent_wear and config.phm_config.estimator_kind == "joint" and config.phm_config.fit.enabled
    assert gym.make(V1, horizon=30).unwrapped.config.horizon == 30  # keywords given to make still override


@pytest.mark.parametrize("env", V1_ENV_IDS)
@pytest.mark.parametrize("mode", ["phm", "sensors", "oracle"])
def test_gymnasium_checker_passes_on_v1_without_warnings(env, mode):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        made = gym.make(env, obs_mode=mode)
        check_env(made.unwrapped, skip_render_check=False)
    assert [str(w.message) for w in caught] == []


def test_v1_observation_layout():
    env = gym.make(V1, obs_mode="phm")
    space = env.observation_space
    sensed = {"ea", "eai", "residual", "time_since_maintenance", "maintenance_in_progress"}
    assert set(space) == sensed | {"degrading", "parameter_estimate", "rul"}
    assert space["rul"].shape == (3, 3) and space["degrading"].shape == (3,) and space["parameter_estimate"].shape == (3,)
    observation, info = env.reset(seed=0)
    assert info["true_rul"].shape == (3,) and info["true_rul"].dtype == np.float64
    for _ in range(5):
        observation, *_, info = env.step(0)
    assert space.contains(observation)
    assert np.all(observation["rul"][:, 1] <= observation["rul"][:, 0]) and np.all(observation["rul"][:, 0] <= observation["rul"][:, 2])
    assert "diagnosis" not in space and "diagnosis" not in gym.make(V1, obs_mode="oracle").observation_space
    assert set(gym.make(V1, obs_mode="sensors").observation_space) == sensed


@pytest.mark.parametrize("obs_mode", ["phm", "oracle"])
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_native_v1_env_equals_sync_vector_env_of_single_envs_step_for_step(mode, obs_mode):
    n = 3
    kwargs = {"obs_mode": obs_mode, **SHORT}
    native = _vector(n, autoreset_mode=mode, **kwargs)
    reference = SyncVectorEnv([lambda: gym.make(V1, **kwargs) for _ in range(n)], autoreset_mode=mode)
    assert_same(native.reset(seed=7), reference.reset(seed=7), "reset")
    rng = np.random.default_rng(0)
    ended = replaced = 0
    for step in range(36):
        actions = rng.integers(0, 7, n)
        actions[rng.random(n) < 0.8] = 0  # mostly carry on: faults grow into failures
        result = native.step(actions)
        assert_same(result, reference.step(actions), f"step {step}")
        ended += int((result[2] | result[3]).sum())
        replaced += sum(len([e for e in events if e.startswith("replacement")]) for events in result[4]["events"] if events)
    assert ended >= 4 and replaced >= 2


def test_a_systems_episode_does_not_depend_on_how_many_are_stepped_with_it():
    """System 2 of five (seed 40 + 2) lives the episode of a single system seeded 42, whatever the others do."""
    alone, crowd = (_vector(n, obs_mode="phm", continue_after_failure=True, **SHORT) for n in (1, 5))
    first_alone, _ = alone.reset(seed=42)
    first_crowd, _ = crowd.reset(seed=40)
    assert_same({k: v[0] for k, v in first_alone.items()}, {k: v[2] for k, v in first_crowd.items()}, "reset")
    rng = np.random.default_rng(3)
    for step in range(20):
        others = rng.integers(0, 7, 5)  # the others maintain at random; system 2 carries on
        others[2] = 0
        a, ra, *_, ia = alone.step(np.zeros(1, dtype=int))
        b, rb, *_, ib = crowd.step(others)
        assert_same({k: v[0] for k, v in a.items()}, {k: v[2] for k, v in b.items()}, f"step {step}")
        assert ra[0] == rb[2]
        np.testing.assert_array_equal(ia["true_rul"][0], ib["true_rul"][2])


def test_starting_values_are_drawn_within_the_stated_tolerance():
    n = 400
    env = _vector(n, obs_mode="sensors")
    env.reset(seed=0)
    core = env.unwrapped.core
    columns = [MODEL.parameter_names.index(c) for c in COMPONENTS]
    values = core.true_parameters[:, columns]
    nominal = np.array([MODEL.nominal[c] for c in COMPONENTS])
    span = np.array([MODEL.safe_limits[c][1] - MODEL.safe_limits[c][0] for c in COMPONENTS])
    offsets = (values - nominal) / span  # uniform on [-1/8, 1/8]
    assert np.all(np.abs(offsets) <= 0.125)
    assert np.all(offsets.min(axis=0) < -0.12) and np.all(offsets.max(axis=0) > 0.12)  # 400 draws reach both ends
    assert np.all(np.abs(offsets.mean(axis=0)) < 0.015)  # the mean's std: 0.125 / sqrt(3 x 400) = 0.0036
    assert len(np.unique(values[:, 0])) == n  # every machine its own
    untouched = [i for i, name in enumerate(MODEL.parameter_names) if name not in COMPONENTS]
    np.testing.assert_array_equal(core.true_parameters[:, untouched], np.tile(core.nominal[untouched], (n, 1)))


def test_every_part_draws_its_own_fault_process():
    n = 300
    env = _vector(n, obs_mode="sensors", wear={c: WearConfig(arrival=(10.0, 50.0), rate=(0.01, 0.02)) for c in COMPONENTS})
    env.reset(seed=1)
    wear = env.unwrapped.core.wear
    arrival, velocity = wear.arrival.reshape(n, 3), wear.velocity.reshape(n, 3)
    assert np.all((arrival >= 10.0) & (arrival <= 50.0))
    assert np.all(np.ptp(arrival, axis=1) > 0)  # no two parts of a machine share a fault
    for d, name in enumerate(COMPONENTS):
        low, high = MODEL.safe_limits[name]
        up, down = velocity[:, d] > 0, velocity[:, d] < 0
        assert 0.35 < up.mean() < 0.65 and np.all(up | down)  # a random direction per part
        distance = np.where(up, high - MODEL.nominal[name], MODEL.nominal[name] - low)
        rate = np.abs(velocity[:, d]) / distance
        assert np.all((rate >= 0.01) & (rate <= 0.02))
        np.testing.assert_allclose(wear.background.reshape(n, 3)[:, d], BACKGROUND_WEAR * np.sign(velocity[:, d]) * distance)


def test_true_rul_per_part_is_the_mean_trend_to_the_limit_by_hand():
    """Linear wear, fixed rates, directions and arrivals, parts at nominal: value and RUL of each part by hand."""
    wear = {
        "k": WearConfig(direction=1, rate=(0.02, 0.02), arrival=(3.0, 3.0)),  # 0.1 N/m/s up from 100 toward 105
        "m": WearConfig(direction=-1, rate=(0.01, 0.01), arrival=(30.0, 30.0)),  # arrives after the run
        "b": WearConfig(direction=-1, rate=(0.05, 0.05), arrival=(0.0, 0.0)),  # 0.005 N s/m/s down from 0.5 toward 0.4
    }
    env = gym.make(V1, obs_mode="oracle", tolerance=0.0, wear=wear, horizon=19)  # b reaches its limit at 19.9 s
    _, info = env.reset(seed=0)
    background = BACKGROUND_WEAR * np.array([5.0, -1.0, -0.1])  # x the distance from nominal to the limit, in its direction
    fault = np.array([0.1, -0.01, -0.005])
    nominal, limit = np.array([100.0, 10.0, 0.5]), np.array([105.0, 9.0, 0.4])
    np.testing.assert_allclose(info["true_rul"], (limit - nominal) / np.array([background[0], background[1], background[2] + fault[2]]))
    for t in range(1, 20):
        observation, _, terminated, truncated, info = env.step(0)
        arrived = np.array([t >= 3.0, False, True])  # the clock, at the step's end, has reached the arrival
        worn = np.array([max(t - 3.0, 0.0), 0.0, t])  # seconds of the fault's wear
        value = nominal + background * t + fault * worn
        np.testing.assert_allclose([info["true_parameters"][c] for c in COMPONENTS], value, rtol=1e-12)
        np.testing.assert_allclose(info["true_rul"], (limit - value) / (background + np.where(arrived, fault, 0.0)), rtol=1e-9)
        np.testing.assert_array_equal(observation["degrading"], arrived.astype(np.float32))
        np.testing.assert_allclose(observation["rul"], np.repeat(np.minimum(info["true_rul"], 1000.0)[:, None], 3, axis=1), rtol=1e-6)
        assert not terminated
    assert truncated


def test_background_ageing_off_leaves_a_part_without_fault_constant_with_an_infinite_rul():
    wear = {c: WearConfig(arrival=(1e5, 1e5)) for c in COMPONENTS}
    env = gym.make(V1, obs_mode="oracle", background_wear=0.0, wear=wear, horizon=5)
    _, info = env.reset(seed=3)
    start = info["true_parameters"]
    for _ in range(5):
        _, _, _, _, info = env.step(0)
    assert info["true_parameters"] == start and np.all(np.isinf(info["true_rul"]))


def test_a_replaced_part_gets_a_new_value_within_tolerance_and_a_new_wear_process():
    env = gym.make(V1, obs_mode="oracle", continue_after_failure=True)
    env.reset(seed=5)
    core = env.unwrapped.core
    for _ in range(10):
        env.step(0)
    before = core.true_parameters.copy()
    arrival, velocity = core.wear.arrival.copy(), core.wear.velocity.copy()
    replace_m = env.unwrapped.action_meanings.index("replace m")
    _, _, _, _, info = env.step(replace_m)
    assert "replacement of m (3 steps down)" in info["events"]
    m = MODEL.parameter_names.index("m")
    after = core.true_parameters
    assert after[0, m] != before[0, m] and abs(after[0, m] - 10.0) <= 0.125 * 2.0 + 1e-12  # no wear while down
    assert arrival[1] != core.wear.arrival[1] and core.wear.arrival[1] >= 10.0  # m's process (k's, b's kept)
    np.testing.assert_array_equal(np.delete(core.wear.arrival, 1), np.delete(arrival, 1))
    np.testing.assert_array_equal(np.delete(core.wear.velocity, 1), np.delete(velocity, 1))


def test_any_part_past_its_limit_is_a_failure():
    env = gym.make(V1, obs_mode="sensors", wear=FAST_WEAR, horizon=200)
    failures = []
    for seed in range(3):
        env.reset(seed=seed)
        terminated = False
        while not terminated:
            _, _, terminated, truncated, info = env.step(0)
            assert not truncated
        failures += [e.split(" = ")[0].removeprefix("failure: ") for e in info["events"]]
        values = np.array([info["true_parameters"][c] for c in COMPONENTS])
        limits = np.array([MODEL.safe_limits[c] for c in COMPONENTS])
        assert np.any((values < limits[:, 0]) | (values > limits[:, 1]))
    assert set(failures) <= set(COMPONENTS) and failures


@pytest.mark.parametrize(
    "overrides, match",
    [
        ({"background_wear": -1e-4}, "background_wear must be a number >= 0"),
        ({"tolerance": float("nan")}, "tolerance must be a number >= 0"),
        ({"concurrent_wear": 1}, "concurrent_wear must be a bool"),
    ],
)
def test_bad_v1_settings_are_one_line_errors_naming_the_field(overrides, match):
    with pytest.raises((TypeError, ValueError), match=match):
        gym.make(V1, **overrides)


def test_the_world_settings_need_the_world_where_every_part_ages():
    with pytest.raises(ValueError, match="tolerance needs concurrent_wear=True"):
        EnvConfig(tolerance=0.1)
    with pytest.raises(ValueError, match="background_wear needs concurrent_wear=True"):
        gym.make(ENV_IDS[0], background_wear=1e-4)
    with pytest.raises(ValueError, match=r"tolerance 0.3 starts k anywhere in \[94, 106\], not inside its safe limits"):
        gym.make(V1, tolerance=0.3)
    with pytest.raises(ValueError, match="commission_seconds needs concurrent_wear=True"):
        EnvConfig(commission_seconds=20.0)
    with pytest.raises(ValueError, match=r"commission_seconds must be 0 \(none\) or within \[1, "):
        gym.make(V1, commission_seconds=0.5)


def _reference(env):
    core = env.unwrapped.core
    return core.operation.reference_parameters[:, core._component_index], core.true_parameters[:, core._component_index]


@pytest.mark.parametrize("obs_mode", ["phm", "sensors"])
def test_each_machine_is_commissioned_at_its_reset_its_reference_its_own_parts(obs_mode):
    """The fitted values are each machine's (within 2 % of the span of its drawn values, which lie up to 12.5 % off
    nominal) in every mode; in "phm" the chain's reference is the same and the first observation shows them."""
    n = 8
    env = _vector(n, obs_mode=obs_mode)
    observation, _ = env.reset(seed=2)
    reference, truth = _reference(env)
    span = np.array([MODEL.safe_limits[c][1] - MODEL.safe_limits[c][0] for c in COMPONENTS])
    nominal = np.array([MODEL.nominal[c] for c in COMPONENTS])
    assert np.all(np.abs(reference - truth) <= 0.02 * span)
    assert np.median(np.abs(truth - nominal) / span) > 0.03  # so the catalogue values would not have done
    core = env.unwrapped.core
    if obs_mode == "phm":
        np.testing.assert_array_equal(core.chain.reference_parameters, core.operation.reference_parameters)
        low = np.array([MODEL.safe_limits[c][0] for c in COMPONENTS])
        np.testing.assert_allclose(observation["parameter_estimate"], (reference - low) / span, rtol=1e-6)
    # the commissioning ran before the episode: no wear yet, the loads' clocks 20 s on
    np.testing.assert_array_equal(core.operation.elapsed, np.full(n, 20.0))
    assert np.all(core.wear.arrival >= 0.0) and np.all(core._clock == 0.0)


def test_a_commissioned_healthy_machine_raises_no_alarm_that_the_nominal_reference_does():
    """Healthy machines off nominal (no fault in the run, background ageing off): commissioned, the chain sees no
    fault; against the catalogue values it alarms on most."""
    healthy = {"wear": {c: WearConfig(arrival=(1e5, 1e5)) for c in COMPONENTS}, "background_wear": 0.0, "horizon": 40}
    alarms = {}
    for seconds in (20.0, 0.0):
        env = _vector(8, obs_mode="phm", commission_seconds=seconds, **healthy)
        env.reset(seed=4)
        chain = env.unwrapped.core.chain
        for _ in range(40):
            observation, *_ = env.step(np.zeros(8, dtype=int))
        alarms[seconds] = chain.detector.state.alarm.mean()
        if seconds:
            assert np.all(observation["rul"] == 1000.0)  # no part named, no End of Life
    assert alarms[20.0] == 0.0 and alarms[0.0] >= 0.5


def test_a_replacement_commissions_the_machine_again():
    env = gym.make(V1, obs_mode="phm", continue_after_failure=True)
    env.reset(seed=5)
    core = env.unwrapped.core
    for _ in range(10):
        env.step(0)
    before = core.operation.reference_parameters.copy()
    env.step(env.unwrapped.action_meanings.index("replace m"))
    reference, truth = _reference(env)
    m = COMPONENTS.index("m")
    assert reference[0, m] != before[0, MODEL.parameter_names.index("m")]
    assert abs(reference[0, m] - truth[0, m]) <= 0.02 * 2.0  # the new part's own value
    np.testing.assert_array_equal(core.chain.reference_parameters, core.operation.reference_parameters)


def test_v1_renders_every_part():
    env = gym.make(V1, render_mode="ansi", obs_mode="oracle")
    env.reset(seed=0)
    env.step(0)
    text = env.render()
    assert all(f"{c}: degrading " in text for c in COMPONENTS) and "true RUL=" in text
    env = gym.make(V1, render_mode="rgb_array")
    env.reset(seed=0)
    for _ in range(3):
        env.step(0)
    image = env.render()
    assert image.ndim == 3 and image.shape[2] == 3 and image.std() > 0


def test_the_sb3_vec_env_takes_the_v1_settings():
    from ea_gym.env.sb3 import MaintenanceVecEnv

    vec = MaintenanceVecEnv(2, obs_mode="oracle", **V1_SETTINGS)
    vec.seed(3)
    observation = vec.reset()
    assert observation["rul"].shape == (2, 3, 3) and observation["degrading"].shape == (2, 3)
    _, _, _, infos = vec.step(np.zeros(2, dtype=int))
    single = gym.make(V1, obs_mode="oracle")
    single.reset(seed=4)
    _, _, _, _, info = single.step(0)
    np.testing.assert_array_equal(infos[1]["true_rul"], info["true_rul"])  # system 1 of the batch is the env seeded 3 + 1
