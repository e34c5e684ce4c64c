"""The wear shaping adds gamma * Phi(s') - Phi(s), Phi = -failure cost * the true wear past the onset
(rescaled to [0, 1]), to the training rewards only."""

import numpy as np
import pytest

from agents.shaping import WearShaping, true_wear
from agents.training import TrainingRun, make_vec_env
from ea_gym.cli import main

LIMITS = {"k": (85.0, 105.0), "b": (0.4, 0.6)}
NOMINAL = {"k": 100.0, "b": 0.5}


def test_true_wear_is_the_way_from_nominal_to_the_limit_on_its_side():
    assert true_wear({"k": 100.0, "b": 0.5}, NOMINAL, LIMITS).tolist() == [0.0, 0.0]
    assert true_wear({"k": 92.5, "b": 0.55}, NOMINAL, LIMITS) == pytest.approx([0.5, 0.5])
    assert true_wear({"k": 104.0, "b": 0.38}, NOMINAL, LIMITS) == pytest.approx([0.8, 1.0])  # clipped at the limit


def potential(wear: np.ndarray, onset: float) -> float:
    """The potential by hand: -400 per component at its limit, falling linearly from the onset on."""
    return -400.0 * float(sum(max(0.0, (w - onset) / (1.0 - onset)) for w in wear))


@pytest.mark.parametrize("onset", [0.5, 0.0])
def test_shaped_rewards_telescope_to_the_environments_return_minus_the_potential(onset):
    run = TrainingRun(obs_mode="oracle", n_envs=2, shaping_onset=onset, env_kwargs={"horizon": 30, "step_seconds": 10.0})
    raw, shaped = make_vec_env(run, 2, seed=3), make_vec_env(run, 2, seed=3, shaped=True)
    wrapper = shaped.venv
    assert isinstance(wrapper, WearShaping) and wrapper.scale == 400.0 and wrapper.gamma == 0.99 and wrapper.onset == onset
    raw.reset(), shaped.reset()
    rng = np.random.default_rng(0)
    discounted = np.zeros((2, 2))  # raw, shaped per system
    shaped_steps = 0  # steps whose reward the shaping changed
    for t in range(30):
        actions = np.where(rng.random(2) < 0.1, rng.integers(1, 4, 2), 0)  # a few corrective steps
        _, r, dones, infos = raw.step(actions)
        _, s, shaped_dones, shaped_infos = shaped.step(actions)
        np.testing.assert_array_equal(dones, shaped_dones)
        discounted[:, 0] += 0.99**t * r
        discounted[:, 1] += 0.99**t * s
        shaped_steps += int(np.any(np.abs(s - r) > 1e-3))
        last = np.array([potential(true_wear(info["true_parameters"], wrapper.nominal, wrapper.limits), onset) for info in infos])
    assert np.all(dones)  # the horizon ended both episodes
    # sum of gamma^t F_t = gamma^T Phi(s_T) - Phi(s_0), with Phi(s_0) = 0 (every part at nominal)
    np.testing.assert_allclose(discounted[:, 1], discounted[:, 0] + 0.99**30 * last, rtol=1e-4, atol=1e-3)
    assert shaped_steps > 5  # the faults wore parts past the onset: the check is not trivial
    assert make_vec_env(run, 2, seed=3).venv.scale == 0.0  # validation sees the environment's rewards
    assert not isinstance(make_vec_env(TrainingRun(**{**run.__dict__, "wear_shaping": False}), 2, 3, shaped=True).venv, WearShaping)


def test_the_potential_is_zero_below_the_onset_and_the_failure_cost_at_the_limit():
    assert TrainingRun().shaping_onset == 0.3  # the default
    wrapper = make_vec_env(TrainingRun(obs_mode="oracle", n_envs=1), 1, seed=0, shaped=True).venv
    nominal, low_m = dict(wrapper.nominal), wrapper.limits["m"][0]
    worn = {**nominal, "m": nominal["m"] - 0.25 * (nominal["m"] - low_m)}  # a quarter of the way: below the onset
    assert wrapper._potential({"true_parameters": worn}) == 0.0
    worn["m"] = nominal["m"] - 0.65 * (nominal["m"] - low_m)  # half-way from the onset (0.3) to the limit
    assert wrapper._potential({"true_parameters": worn}) == pytest.approx(-200.0)
    worn["k"] = wrapper.limits["k"][1] + 1.0  # past its limit: the failure cost, no more
    assert wrapper._potential({"true_parameters": worn}) == pytest.approx(-600.0)
    with pytest.raises(ValueError, match="shaping onset must be a wear in"):
        WearShaping(wrapper.venv, gamma=0.99, scale=400.0, onset=1.0)


def test_train_command_refuses_a_shaping_onset_outside_0_1(capsys):
    for bad in ("1", "-0.1", "nan", "x"):
        with pytest.raises(SystemExit) as stop:
            main(["train", "--shaping-onset", bad, "--out", "x"])
        assert stop.value.code == 2 and "expected a wear in [0, 1)" in capsys.readouterr().err
