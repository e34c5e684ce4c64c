"""Agents as JSON and safetensors (agents.agent_files): a saved agent acts exactly as the trained one, and
files that would run code when loaded (SB3 zips, pickles) are refused unless the user trusts them."""

import contextlib
import json
import os
import pickle
import shutil
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pytest
import torch
from payloads import malicious_agent  # tests/payloads.py
from stable_baselines3.common.save_util import load_from_zip_file

from agents.agent_files import ALGORITHMS, build_policy, load_optimizer, read_agent, save_agent
from agents.benchmark.evaluation import plan_policies
from agents.benchmark.run import run_benchmark
from agents.conventions import UntrustedFileError
from agents.policies import ActionMap
from agents.training import TrainingRun, convert_agent, hyperparameters, load_policy, make_vec_env, normalize, train, trained_environment
from ea_gym.cli import main
from ea_gym.env.sb3 import MaintenanceVecEnv
from ea_gym.threads import single_threaded_torch

RUN = TrainingRun(obs_mode="oracle", n_envs=2, activity=True)
#: tiny networks and updates: the point is the files, not the learning
SETTINGS = {
    "ppo": ({"n_steps": 16, "batch_size": 32, "n_epochs": 1}, {"net_arch": {"pi": [16], "vf": [8]}}),
    "a2c": ({"n_steps": 8}, {"net_arch": [16], "activation_fn": torch.nn.ReLU}),
    "dqn": ({"learning_starts": 16, "buffer_size": 1_000, "batch_size": 16, "train_freq": 4}, {"net_arch": [16]}),
}


@pytest.fixture(autouse=True)
def _one_torch_thread():
    """The networks are tiny: more torch threads only wait on each other (and on the environments' BLAS)."""
    with single_threaded_torch():
        yield


def _trained(algo: str):
    """A model trained for 64 steps and its VecNormalize, whose statistics then clip some observations."""
    run = replace(RUN, algo=algo, hyperparameters=SETTINGS[algo][0])
    env = normalize(make_vec_env(run, 2, seed=0))
    model = ALGORITHMS[algo]("MultiInputPolicy", env, seed=0, policy_kwargs=SETTINGS[algo][1], **run.hyperparameters)
    model.learn(64)
    env.obs_rms["ea"].var = env.obs_rms["ea"].var * 1e-6  # standardised EA beyond +-clip_obs: the clip is exercised
    return run, model, env


def _observations(n_steps: int = 40) -> list[dict[str, np.ndarray]]:
    """Raw batched observations of 4 environments under random actions (seeded)."""
    env = MaintenanceVecEnv(4, obs_mode="oracle", continue_after_failure=True)
    env.seed(123)
    rng = np.random.default_rng(0)
    observations = [env.reset()]
    for _ in range(n_steps):
        env.step_async(rng.integers(0, env.action_space.n, size=4))
        observations.append(env.step_wait()[0])
    return observations


def _outputs(policy, learner_view) -> torch.Tensor:
    """The network's outputs before the choice of action: the actor's logits, or DQN's Q-values."""
    tensor, _ = policy.obs_to_tensor(learner_view)
    with torch.no_grad():
        return policy.q_net(tensor) if hasattr(policy, "q_net") else policy.get_distribution(tensor).distribution.logits


def _assert_acts_as(loaded, model, env, observations):
    """``loaded`` (a NormalizedPolicy) gives the trained model's normalised observations, outputs and actions."""
    for observation in observations:
        reference = env.normalize_obs(env.venv.forward(dict(observation)))
        normalised = loaded.normalization.normalize_obs(loaded.view.forward(dict(observation)))
        assert normalised.keys() == reference.keys()
        for key in reference:
            assert normalised[key].dtype == reference[key].dtype and np.array_equal(normalised[key], reference[key]), key
        assert torch.equal(_outputs(loaded.policy, normalised), _outputs(model.policy, reference))
        assert np.array_equal(loaded.predict(observation)[0], model.predict(reference, deterministic=True)[0])


@pytest.fixture(scope="module")
def observations():
    return _observations()


@pytest.mark.parametrize("algo", ["ppo", "a2c", "dqn"])
def test_a_saved_agent_acts_as_the_trained_model(algo, observations, tmp_path):
    run, model, env = _trained(algo)
    save_agent(tmp_path, model, env, trained_environment(run), hyperparameters(run))
    loaded = load_policy(tmp_path)
    clipped = [np.abs(env.normalize_obs(env.venv.forward(dict(o)))["ea"]).max() == env.clip_obs for o in observations]
    assert any(clipped)
    _assert_acts_as(loaded, model, env, observations)
    assert loaded.num_timesteps == model.num_timesteps == 64
    assert loaded.obs_mode == "oracle"
    saved = model.policy.state_dict()
    assert all(torch.equal(tensor, saved[name]) for name, tensor in loaded.policy.state_dict().items())


@pytest.mark.parametrize("algo", ["ppo", "a2c"])
def test_the_optimizer_state_comes_back_for_resuming(algo, tmp_path):
    run, model, env = _trained(algo)
    save_agent(tmp_path, model, env, trained_environment(run), hyperparameters(run))
    description = read_agent(tmp_path)
    fresh = ALGORITHMS[algo](description.policy_class, normalize(make_vec_env(run, 2, seed=0)), policy_kwargs=description.policy_kwargs,
                             **description.hyperparameters)
    load_optimizer(fresh.policy.optimizer, description, tmp_path)
    before, after = model.policy.optimizer.state_dict(), fresh.policy.optimizer.state_dict()
    assert before["state"] and before["state"].keys() == after["state"].keys()
    for index, entries in before["state"].items():
        for name, value in entries.items():
            assert torch.equal(torch.as_tensor(value), torch.as_tensor(after["state"][index][name])), (index, name)
    assert [{k: v for k, v in g.items() if k != "lr"} for g in before["param_groups"]] == \
           [{k: v for k, v in g.items() if k != "lr"} for g in after["param_groups"]]


def test_agent_json_is_numbers_and_names(tmp_path):
    run, model, env = _trained("a2c")
    save_agent(tmp_path, model, env, trained_environment(run), hyperparameters(run))
    data = json.loads((tmp_path / "agent.json").read_text())
    assert data["policy"]["kwargs"]["activation_fn"] == "ReLU" and data["policy"]["kwargs"]["optimizer_class"] == "RMSprop"
    assert data["action_space"] == {"type": "Discrete", "n": 7, "start": 0}
    assert data["environment"] == {"id": "ea_gym/SpringMassDamper-v0", "obs_mode": "oracle", "env_kwargs": {"continue_after_failure": True},
                                   "activity": True, "suspect_wear": True}
    ea = data["normalization"]["obs_rms"]["ea"]
    assert ea["mean"] == env.obs_rms["ea"].mean.tolist() and ea["var"] == env.obs_rms["ea"].var.tolist()
    assert data["normalization"]["norm_obs_keys"] == env.norm_obs_keys


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.update(format="sb3"), "not an ea-gym agent"),
    (lambda d: d["policy"].update({"class": "builtins.eval"}), "policy.class must be one of"),
    (lambda d: d["policy"]["kwargs"].update(activation_fn="os.system"), "policy.kwargs.activation_fn must be one of"),
    (lambda d: d["normalization"]["obs_rms"]["ea"].update(var=[1.0]), "normalization.obs_rms.ea.var must hold 4 numbers"),
    (lambda d: d.update(version=99), "newer than this ea-gym reads"),
    (lambda d: d["environment"].pop("obs_mode"), "field 'obs_mode' is missing"),
    (lambda d: d["normalization"]["obs_rms"]["ea"].update(mean=[float("inf")] * 4), "means must be finite"),
    (lambda d: d.update(deep=json.loads("[" * 100 + "]" * 100)), "nests deeper than"),
])
def test_a_bad_agent_json_is_refused_naming_the_field(edit, message, tmp_path):
    run, model, env = _trained("ppo")
    save_agent(tmp_path, model, env, trained_environment(run), hyperparameters(run))
    data = json.loads((tmp_path / "agent.json").read_text())
    edit(data)
    (tmp_path / "agent.json").write_text(json.dumps(data))
    with pytest.raises(ValueError, match=message) as error:
        load_policy(tmp_path)
    assert "\n" not in str(error.value)


def _malicious_agent(directory: Path, marker: Path) -> Path:
    return malicious_agent(directory, marker, asdict(RUN))


def test_the_payloads_run_when_unpickled(tmp_path):
    """What the refusals below protect from: stable-baselines3 and pickle run the files' code."""
    marker = tmp_path / "ran"
    evil = _malicious_agent(tmp_path / "evil", marker)
    pickle.loads((evil / "vecnormalize.pkl").read_bytes())
    assert marker.is_file()
    marker.unlink()
    with contextlib.suppress(Exception):
        load_from_zip_file(evil / "model.zip")
    assert marker.is_file()


@pytest.mark.parametrize("command", [
    ["train", "--resume", "{evil}/model.zip", "--out", "{out}"],
    ["train", "--resume", "{evil}/vecnormalize.pkl", "--out", "{out}"],
    ["train", "--resume", "{evil}", "--out", "{out}"],
    ["train", "--resume", "{evil}/blob", "--out", "{out}"],
    ["benchmark", "--ppo", "{evil}", "--out", "{out}", "--episodes", "2", "--tune-episodes", "1", "--no-progress"],
    ["convert-agent", "{evil}", "{out}"],
])
def test_every_command_that_loads_an_agent_refuses_pickles(command, tmp_path, capsys):
    marker, out = tmp_path / "ran", tmp_path / "out"
    evil = _malicious_agent(tmp_path / "evil", marker)
    assert main([word.format(evil=evil, out=out) for word in command]) == 2
    error = capsys.readouterr().err
    assert error.startswith(f"ea-gym {command[0]}: error: ") and error.count("\n") == 1
    assert "would run any code it holds" in error and "--trust-pickle" in error
    assert not marker.exists() and not out.exists()


def test_the_library_refuses_pickles_too(tmp_path):
    marker = tmp_path / "ran"
    evil = _malicious_agent(tmp_path / "evil", marker)
    for load in (lambda: load_policy(evil), lambda: train(RUN, tmp_path / "out", resume=evil / "model.zip"),
                 lambda: run_benchmark(2, 0, tmp_path / "out", evil, tune_episodes=1, progress=False),
                 lambda: run_benchmark(2, 0, tmp_path / "out", None, tune_episodes=1, progress=False, ppo_policies={"x": evil}),
                 lambda: convert_agent(evil, tmp_path / "out")):
        with pytest.raises(UntrustedFileError, match="would run any code"):
            load()
    assert not marker.exists() and not (tmp_path / "out").exists()


def test_pickles_beside_or_inside_an_agent_are_never_unpickled(tmp_path, observations):
    marker = tmp_path / "ran"
    run, model, env = _trained("ppo")
    agent = save_agent(tmp_path / "agent", model, env, trained_environment(run), hyperparameters(run))
    evil = _malicious_agent(tmp_path / "evil", marker)
    for name in ("model.zip", "vecnormalize.pkl"):
        shutil.copyfile(evil / name, agent / name)
    _assert_acts_as(load_policy(agent), model, env, observations[:3])  # the agent's own files only
    shutil.copyfile(evil / "blob", agent / "policy.safetensors")
    with pytest.raises(ValueError, match="policy.safetensors: cannot load the policy's weights"):
        build_policy(read_agent(agent), agent)
    assert not marker.exists()
    (agent / "policy.safetensors").unlink()
    os.mkfifo(agent / "policy.safetensors")  # opening it for reading would wait for a writer forever
    with pytest.raises(ValueError, match="policy.safetensors: not a regular file"):
        build_policy(read_agent(agent), agent)


def test_trusted_sb3_files_load_convert_and_resume(tmp_path, observations, capsys):
    """With --trust-pickle stable-baselines3's files work as before, and their conversion acts identically."""
    run, model, env = _trained("ppo")
    legacy = tmp_path / "legacy"
    legacy.mkdir()
    model.save(legacy / "model.zip")
    env.save(str(legacy / "vecnormalize.pkl"))
    (legacy / "training.json").write_text(json.dumps({"run": asdict(run)}))
    _assert_acts_as(load_policy(legacy, trust_pickle=True), model, env, observations)
    plan, skipped = plan_policies({}, {}, ActionMap.from_env(env), {"ppo": legacy}, print, trust_pickle=True)  # the benchmark's
    assert skipped == {} and plan["ppo"]["obs_mode"] == "oracle"
    _assert_acts_as(plan["ppo"]["policy"], model, env, observations)
    assert main(["convert-agent", str(legacy), str(tmp_path / "converted"), "--trust-pickle"]) == 0
    _assert_acts_as(load_policy(tmp_path / "converted"), model, env, observations)
    assert json.loads((tmp_path / "converted" / "training.json").read_text()) == {"run": asdict(run)}
    resume = ["train", "--resume", str(legacy / "model.zip"), "--trust-pickle", "--obs-mode", "oracle", "--n-envs", "2",
              "--timesteps", "32", "--eval-every", "1000", "--eval-episodes", "1", "--no-progress",
              "--out", str(tmp_path / "resumed")]
    assert main(resume) == 0, capsys.readouterr().err
    assert load_policy(tmp_path / "resumed").num_timesteps == 64 + 32


@pytest.mark.parametrize("name", ["ppo_phm", "ppo_oracle", "ppo_sensors"])
def test_the_committed_agents_are_agent_directories_without_pickle(name):
    import agents

    directory = Path(agents.__file__).parent / "data" / name
    assert sorted(p.name for p in directory.iterdir()) == ["agent.json", "optimizer.safetensors", "policy.safetensors", "training.json"]
    description = read_agent(directory)
    summary = json.loads((directory / "training.json").read_text())
    assert f"{description.num_timesteps} steps" == summary["selected"]["checkpoint"]
    assert description.environment.obs_mode == summary["run"]["obs_mode"]
    assert description.environment.activity == summary["run"].get("activity", False)  # runs saved before the field did not see it
    # trained before the suspect's wear: agent.json lacks the field and the loaded view lacks the key (load_policy checks every key's shape)
    assert "suspect_wear" not in json.loads((directory / "agent.json").read_text())["environment"] and not description.environment.suspect_wear
    assert "suspect_wear" not in load_policy(directory).view.observation_space.spaces
    build_policy(description, directory)  # every tensor of the architecture agent.json names, shapes checked
