"""RLlib and Ray (the optional extra ea-gym[rllib]).

Without ray (CI's .venv): the rllib backend is refused in one line. With it (``bash scripts/test_ray.sh``,
its own virtual environment): the env creator RLlib's env runners call, and a PPO iteration on an env
runner process whose episodes all end at the horizon.
"""

import importlib.util

import pytest

from ea_gym.cli import main

HAS_RLLIB = importlib.util.find_spec("ray") is not None and importlib.util.find_spec("ray.rllib") is not None
needs_rllib = pytest.mark.skipif(not HAS_RLLIB, reason="needs the rllib extra: bash scripts/test_ray.sh")


@pytest.mark.skipif(HAS_RLLIB, reason="the message shown where ray is missing")
def test_rllib_backend_without_ray_is_one_line_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["train", "--backend", "rllib", "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "--backend rllib" in error and "'.[rllib]'" in error
    assert not out.exists()


@pytest.mark.parametrize("flags, named", [(["--teacher", "oracle"], "--teacher"), (["--algo", "dqn"], "--algo"),
                                          (["--vec-env", "subproc"], "--vec-env"), (["--system", "dc_motor"], "--system")])
def test_rllib_backend_refuses_the_sb3_options(tmp_path, capsys, flags, named):
    out = tmp_path / "run"
    assert main(["train", "--backend", "rllib", "--out", str(out), *flags]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and named in error
    assert not out.exists()


@needs_rllib
def test_env_creator_gives_the_native_vector_env_when_rllib_asks_for_a_vector():
    from gymnasium.vector import AutoresetMode

    from agents.rllib_training import env_creator
    from ea_gym.env.maintenance import BondGraphMaintenanceEnv
    from ea_gym.env.vector import BondGraphMaintenanceVectorEnv

    vector = env_creator({"num_envs": 3, "obs_mode": "sensors", "horizon": 5})
    single = env_creator({"obs_mode": "sensors", "horizon": 5})
    try:
        assert isinstance(vector.unwrapped, BondGraphMaintenanceVectorEnv) and vector.num_envs == 3
        assert vector.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP  # what RLlib's env runners assume
        assert vector.unwrapped.core.config.horizon == 5 and vector.unwrapped.core.config.obs_mode == "sensors"
        assert isinstance(single.unwrapped, BondGraphMaintenanceEnv)
    finally:
        vector.close()
        single.close()


@needs_rllib
@pytest.mark.parametrize("vectorize", ["vector_entry_point", "sync"])
def test_ppo_on_an_env_runner_process_sees_whole_episodes(tmp_path, vectorize):
    """One env runner (another process: the creator is found there by name), 2 envs, horizon 20, no
    failures (continue_after_failure): 200 steps are 10 episodes of 20 steps, none of another length."""
    from agents.rllib_training import RLlibRun, train_rllib

    run = RLlibRun(timesteps=200, obs_mode="sensors", num_env_runners=1, envs_per_env_runner=2, vectorize=vectorize,
                   env_kwargs={"horizon": 20}, hyperparameters={"train_batch_size_per_learner": 200, "minibatch_size": 50, "num_epochs": 1})
    summary = train_rllib(run, tmp_path, num_cpus=2, say=lambda line: None, checkpoint=False)
    assert summary["env_steps_sampled"] >= 200
    assert summary["episodes"] == {"episodes_at_horizon": summary["env_steps_sampled"] // 20, "episodes_failed": 0, "episodes_other_length": 0}
    assert summary["iterations"][-1]["episode_len_min"] == summary["iterations"][-1]["episode_len_max"] == 20
