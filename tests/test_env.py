"""The Gymnasium maintenance environment: API checks, seeding, the online PHM chain, bad input."""

import tracemalloc
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import ea_gym  # noqa: F401 - registers the environments
from ea_gym.degradation import WearConfig
from ea_gym.env.costs import CostModel
from ea_gym.phm import PHMConfig

ENV_IDS = ("ea_gym/SpringMassDamper-v0", "ea_gym/BondGraphMaintenance-v0")
MODES = ("phm", "sensors", "oracle")


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("mode", MODES)
def test_gymnasium_and_sb3_checkers_pass_without_warnings(env_id, mode):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = gym.make(env_id, obs_mode=mode)
        check_env(env.unwrapped, skip_render_check=False)
        sb3_check_env(env.unwrapped, warn=True)
    # but Gymnasium's own notice that a newer version of the id (v1) exists: its convention for every older id
    assert [str(w.message) for w in caught if not (w.category is DeprecationWarning and "is out of date" in str(w.message))] == []


def _rollout(seed, steps, mode="phm", actions_seed=None):
    env = gym.make("ea_gym/SpringMassDamper-v0", obs_mode=mode, continue_after_failure=True, horizon=steps)
    obs, info = env.reset(seed=seed)
    rng = np.random.default_rng(actions_seed)
    trace = []
    for _ in range(steps):
        action = 0 if actions_seed is None else int(rng.integers(env.action_space.n))
        obs, reward, terminated, truncated, info = env.step(action)
        trace.append((obs, reward, info))
        if terminated or truncated:
            break
    return trace


def _same(a, b):
    return all(
        all(np.array_equal(x[0][k], y[0][k]) for k in x[0]) and x[1] == y[1] and x[2] == y[2] for x, y in zip(a, b)
    ) and len(a) == len(b)


def test_same_seed_same_episode_different_seed_different_episode():
    first = _rollout(7, 500, actions_seed=3)
    assert len(first) == 500
    assert _same(first, _rollout(7, 500, actions_seed=3))
    assert not _same(first, _rollout(8, 500, actions_seed=3))


@pytest.mark.parametrize(
    "component, direction, limit_index, rul_tolerance",
    # the light damper (damping ratio 0.8 %) barely shapes a few seconds of response: its estimate
    # is good to ~0.01 N s/m, too coarse over a 0.1 N s/m range for a trend, so only its estimate is held
    [("k", -1, 0, 0.3), ("m", 1, 1, 0.3), ("b", 1, 1, None)],
)
def test_chain_is_online_diagnosis_and_rul_follow_a_drift(component, direction, limit_index, rul_tolerance):
    # the component drifts from 5 s on at 1 % of its nominal-to-limit distance per second: half way at 55 s
    wear = {component: WearConfig(direction=direction, rate=(0.01, 0.01), arrival=(5.0, 5.0))}
    env = gym.make("ea_gym/SpringMassDamper-v0", wear=wear, noise=0.01)
    env.reset(seed=0)
    unwrapped = env.unwrapped
    nominal = unwrapped.nominal_parameters[component]
    lower, upper = unwrapped.safe_limits[component]
    limit = (lower, upper)[limit_index]
    d = unwrapped.maintainable_components.index(component)
    named, rul_error, estimate_error = [], [], []
    for _ in range(90):
        obs, _, terminated, _, info = env.step(0)
        assert not terminated
        true = info["true_parameters"][component]
        if (true - nominal) / (limit - nominal) >= 0.5:
            named.append(unwrapped.diagnosis_classes[int(np.argmax(obs["diagnosis"]))] == component)
            rul_error.append(abs(obs["rul"][0] - info["true_rul"]) / info["true_rul"])
            estimate_error.append(abs(lower + obs["parameter_estimate"][d] * (upper - lower) - true))
    assert len(named) >= 30
    assert np.mean(named) >= 0.9
    assert np.median(estimate_error) <= 0.1 * (upper - lower)
    if rul_tolerance is not None:
        assert np.median(rul_error) <= rul_tolerance


def test_random_actions_stay_finite_without_memory_growth():
    env = gym.make("ea_gym/SpringMassDamper-v0", obs_mode="phm", continue_after_failure=True, horizon=10_000)
    env.reset(seed=1)
    rng = np.random.default_rng(0)

    def run(steps):
        for _ in range(steps):
            obs, reward, terminated, truncated, info = env.step(int(rng.integers(env.action_space.n)))
            assert all(np.all(np.isfinite(v)) for v in obs.values())
            assert np.isfinite(reward) and reward <= 0
            assert np.isfinite(info["true_rul"]) or info["true_rul"] == np.inf

    run(100)  # warm caches before measuring
    tracemalloc.start()
    before = tracemalloc.get_traced_memory()[0]
    run(300)
    growth = tracemalloc.get_traced_memory()[0] - before
    tracemalloc.stop()
    assert growth < 2_000_000, f"memory grew by {growth} bytes over 300 steps"


def test_costs_add_up_to_minus_the_reward():
    env = gym.make("ea_gym/SpringMassDamper-v0", obs_mode="sensors", costs=CostModel(replace_downtime=2))
    env.reset(seed=0)
    n = len(env.unwrapped.maintainable_components)
    obs, reward, _, _, info = env.step(n + 1)  # replace the first component: down for this step and the next
    assert info["cost"]["replacement"] == 40.0
    assert info["cost"]["lost_production"] == 4.0
    assert reward == -info["cost"]["total"] == -(info["cost"]["replacement"] + info["cost"]["lost_production"])
    assert obs["maintenance_in_progress"][0] == 1.0
    obs, reward, _, _, info = env.step(1)  # ignored while down
    assert info["cost"]["corrective"] == 0.0 and info["cost"]["lost_production"] == 4.0
    assert obs["maintenance_in_progress"][0] == 0.0
    _, reward, _, _, info = env.step(1)  # back up: a corrective action costs
    assert info["cost"]["corrective"] == 1.0 and reward == -1.0


def test_corrective_action_moves_the_parameter_toward_nominal_and_past_it():
    wear = {"k": WearConfig(direction=-1, rate=(0.0, 0.0), arrival=(0.0, 0.0))}
    env = gym.make("ea_gym/SpringMassDamper-v0", obs_mode="sensors", wear=wear, corrective_rate=0.02)
    env.reset(seed=0)
    k_action = 1 + env.unwrapped.maintainable_components.index("k")
    values = [env.step(k_action)[4]["true_parameters"]["k"] for _ in range(3)]
    # no wear; from nominal the action heads up (toward nominal is nowhere) at 2 % of 20 N/m per second
    np.testing.assert_allclose(values, [100.4, 100.8, 101.2])


def test_corrective_actions_are_logged_in_the_chain():
    wear = {"k": WearConfig(direction=-1, rate=(0.0, 0.0), arrival=(0.0, 0.0))}
    # the EA inversion's estimate moves only by the log before an alarm (tests/test_phm_tracking.py: the tracking route's)
    env = gym.make("ea_gym/SpringMassDamper-v0", wear=wear, corrective_rate=0.02, phm=PHMConfig(estimator_kind="ea_inversion"))
    env.reset(seed=0)
    chain = env.unwrapped.core.chain
    k = chain.degradable.index("k")
    for _ in range(3):
        env.step(1 + env.unwrapped.maintainable_components.index("k"))
    # no alarm yet, so no estimate of its own: the chain believes nominal plus what maintenance did
    assert not chain.detector.state.alarm[0]
    assert chain.estimator.state.estimates[0, k] == pytest.approx(101.2)


def test_failure_terminates_or_forces_a_replacement():
    wear = {"k": WearConfig(direction=-1, rate=(0.2, 0.2), arrival=(0.0, 0.0))}
    env = gym.make("ea_gym/SpringMassDamper-v0", obs_mode="sensors", wear=wear)
    env.reset(seed=0)
    terminated, steps = False, 0
    while not terminated:
        _, reward, terminated, _, info = env.step(0)
        steps += 1
    assert steps == 6 and info["failed"] and info["cost"]["failure"] == 400.0  # 15 N/m at 3 N/m/s: past 85 in step 6
    env = gym.make("ea_gym/SpringMassDamper-v0", obs_mode="sensors", wear=wear, continue_after_failure=True)
    env.reset(seed=0)
    for _ in range(6):
        _, _, terminated, _, info = env.step(0)
    assert not terminated and info["failed"] and info["true_parameters"]["k"] == 100.0
    assert any("replacement of k" in e for e in info["events"])


@pytest.mark.parametrize("action", [-1, 7, 2.5, "1", None])
def test_invalid_action_is_a_clear_error(action):
    env = gym.make("ea_gym/SpringMassDamper-v0", obs_mode="sensors")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action must be an int in \[0, 6\]"):
        env.step(action)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"obs_mode": "full"}, "obs_mode must be one of"),
        ({"noise": -0.1}, "noise must be in"),
        ({"step_seconds": 0}, "step_seconds must be a positive number"),
        ({"horizon": 0}, "horizon must be an int in"),
        ({"wear": {"q": WearConfig()}}, r"wear: unknown components \['q'\]"),
        ({"render_mode": "rgb"}, "render_mode must be one of"),
        ({"window_seconds": 0.3}, "longer than the smoothing window"),
    ],
)
@pytest.mark.filterwarnings("ignore:.*not in the possible render_modes")
def test_invalid_keyword_arguments_are_clear_errors(kwargs, match):
    with pytest.raises((ValueError, TypeError), match=match):
        env = gym.make("ea_gym/SpringMassDamper-v0", **kwargs)
        env.reset(seed=0)
        env.step(0)


def test_negative_cost_is_a_clear_error():
    with pytest.raises(ValueError, match="cost model: failure must be finite and >= 0"):
        CostModel(failure=-1.0)


def test_unknown_keyword_and_unknown_system_are_errors():
    with pytest.raises(TypeError, match="unexpected keyword argument 'speed'"):
        gym.make("ea_gym/SpringMassDamper-v0", speed=2)
    with pytest.raises(ValueError, match="system must be one of"):
        gym.make("ea_gym/BondGraphMaintenance-v0", system="pump")


def test_renders_a_picture_and_text():
    env = gym.make("ea_gym/SpringMassDamper-v0", render_mode="rgb_array", obs_mode="oracle")
    env.reset(seed=0)
    for _ in range(5):
        env.step(0)
    image = env.render()
    assert image.ndim == 3 and image.shape[2] == 3 and image.dtype == np.uint8 and image.std() > 0
    env = gym.make("ea_gym/SpringMassDamper-v0", render_mode="ansi", obs_mode="oracle")
    env.reset(seed=0)
    env.step(0)
    text = env.render()
    assert "EA (J)" in text and "true RUL" in text


def test_the_tracking_filters_random_walk_is_the_wears_own():
    """Each wearing component's theta random walk (unit^2/s) is its WearConfig's; linear wear has none,
    a component that does not wear keeps the filter's default, and a setting the chain names itself wins."""
    from ea_gym.phm.config import TrackingConfig

    wear = {"k": WearConfig(), "b": WearConfig(process="wiener", rate=(0.01, 0.01), direction=1)}
    env = gym.make("ea_gym/SpringMassDamper-v0", wear=wear)
    estimator = env.unwrapped.core.chain.estimator
    diffusion = dict(zip(estimator.degradable, estimator.diffusion))
    assert diffusion["k"] == 0.0
    assert diffusion["b"] == pytest.approx(wear["b"].random_walk_std(0.5, (0.4, 0.6)) ** 2, rel=1e-12)
    assert diffusion["m"] == pytest.approx((TrackingConfig().theta_noise * 10.0) ** 2, rel=1e-12)
    named = PHMConfig(tracking=TrackingConfig(parameter_theta_noise=(("k", 1e-3),)))
    estimator = gym.make("ea_gym/SpringMassDamper-v0", wear=wear, phm=named).unwrapped.core.chain.estimator
    assert dict(zip(estimator.degradable, estimator.diffusion))["k"] == pytest.approx((1e-3 * 100.0) ** 2, rel=1e-12)
