"""A tiny training run saves an agent that reloads, predicts valid actions and resumes."""

import json

import gymnasium as gym
import numpy as np
import pytest

from agents.conventions import VALIDATION_SEED
from agents.policies import CorrectiveBand, Oracle
from agents.training import TEACHERS, TrainingRun, load_policy, make_teacher, make_vec_env, train
from ea_gym.cli import main


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    out = tmp_path_factory.mktemp("ppo")
    run = TrainingRun(algo="ppo", timesteps=448, obs_mode="oracle", n_envs=4, eval_every=192, eval_episodes=2,
                      env_kwargs={"horizon": 50}, hyperparameters={"n_steps": 32, "batch_size": 64})
    summary = train(run, out, progress_bar=False)
    return out, summary


def test_training_writes_agent_checkpoints_and_summary_without_pickle(trained):
    out, summary = trained
    agent = ("agent.json", "policy.safetensors", "optimizer.safetensors")
    for name in (*agent, "training.json", *(f"last/{n}" for n in agent)):
        assert (out / name).is_file(), name
    # a checkpoint at every evaluation, at the same steps
    assert sorted(p.name for p in (out / "checkpoints").iterdir()) == ["ppo_192_steps", "ppo_384_steps"]
    for checkpoint in (out / "checkpoints").iterdir():
        assert sorted(p.name for p in checkpoint.iterdir()) == sorted(agent)
    assert not [p for p in out.rglob("*") if p.suffix in (".zip", ".pkl")]
    assert json.loads((out / "training.json").read_text())["run"]["timesteps"] == summary["run"]["timesteps"] == 448


def test_reloaded_policy_predicts_valid_actions_for_single_and_batched_observations(trained):
    out, _ = trained
    policy = load_policy(out)
    env = gym.make("ea_gym/SpringMassDamper-v0", obs_mode="oracle")
    obs, _ = env.reset(seed=0)
    action, _ = policy.predict(obs)
    assert env.action_space.contains(int(action))
    batch = {key: np.stack([value, value]) for key, value in obs.items()}
    actions, _ = policy.predict(batch)
    assert actions.shape == (2,) and actions[0] == actions[1] == action  # deterministic, same input


def test_training_resumes_from_a_checkpoint(trained, tmp_path):
    out, _ = trained
    run = TrainingRun(algo="ppo", timesteps=128, obs_mode="oracle", n_envs=4, eval_every=10_000, eval_episodes=1,
                      env_kwargs={"horizon": 50}, hyperparameters={"n_steps": 32, "batch_size": 64})
    summary = train(run, tmp_path, resume=out / "checkpoints" / "ppo_192_steps", progress_bar=False)
    assert summary["resumed_from"].endswith("ppo_192_steps")
    assert load_policy(tmp_path).num_timesteps == 192 + 128
    with pytest.raises(ValueError, match="trained with obs_mode 'oracle', this run has 'phm'"):
        train(TrainingRun(timesteps=64, obs_mode="phm", env_kwargs={"horizon": 50}), tmp_path / "x", resume=out, progress_bar=False)


def test_train_command_rejects_bad_arguments(capsys):
    with pytest.raises(SystemExit):
        main(["train", "--algo", "sac", "--out", "x"])
    assert "invalid choice: 'sac'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["train", "--timesteps", "0", "--out", "x"])
    assert "expected a positive integer" in capsys.readouterr().err


def test_the_selected_model_is_the_best_evaluation_and_the_last_model_is_kept(trained):
    out, summary = trained
    evaluations = summary["evaluations"]
    # the evaluations at 192 and 384 steps, then the last model (3 rollouts of 4 x 32 steps, then one of 4 x 16), not evaluated on the way
    assert [(e["steps"], e["directory"]) for e in evaluations] == [
        (192, "checkpoints/ppo_192_steps"), (384, "checkpoints/ppo_384_steps"), (448, "last")]
    best = max(evaluations, key=lambda e: e["mean_reward"])
    assert summary["selected"]["steps"] == best["steps"] and summary["selected"]["validation_reward"] == best["mean_reward"]
    assert summary["last"] == {"steps": 448, "directory": "last"} and summary["steps"] == 448
    for name in ("agent.json", "policy.safetensors", "optimizer.safetensors"):
        assert (out / name).read_bytes() == (out / best["directory"] / name).read_bytes()
    assert load_policy(out).num_timesteps == best["steps"] and load_policy(out / "last").num_timesteps == 448
    # each evaluation's score is the evaluated checkpoint's: re-evaluated, its validation episodes give the same rewards
    from stable_baselines3.common.evaluation import evaluate_policy

    from agents.training import normalize

    policy = load_policy(out / "checkpoints" / "ppo_192_steps")
    env = normalize(make_vec_env(TrainingRun(obs_mode="oracle", env_kwargs={"horizon": 50}), 2, VALIDATION_SEED, kind="batched"),
                    training=False)
    policy.normalization.restore(env)
    rewards, _ = evaluate_policy(policy.policy, env, n_eval_episodes=2, deterministic=True, return_episode_rewards=True)
    assert np.mean(rewards) == pytest.approx(evaluations[0]["mean_reward"], abs=1e-3)


def test_a_cloned_teacher_is_imitated_and_competes_for_selection(tmp_path):
    run = TrainingRun(algo="ppo", timesteps=128, obs_mode="oracle", n_envs=4, eval_every=128, eval_episodes=1,
                      env_kwargs={"horizon": 50}, hyperparameters={"n_steps": 32, "batch_size": 64},
                      teacher="oracle", teacher_steps=2048)
    summary = train(run, tmp_path, progress_bar=False)
    cloning = summary["cloning"]
    assert sum(cloning["action_counts"]) == cloning["steps"] == 2048
    # an untrained policy agrees with the teacher about 1 step in 7; the clone nearly always
    assert cloning["accuracy"] >= 0.9
    assert (tmp_path / "checkpoints" / "ppo_0_steps" / "agent.json").is_file()  # the clone, before learning
    assert [e["steps"] for e in summary["evaluations"]] == [0, 128]  # the clone competes with the learner
    assert summary["selected"]["checkpoint"] in ("0 steps", "128 steps")
    with pytest.raises(ValueError, match="teacher must be one of"):
        run = TrainingRun(timesteps=64, teacher="guess", n_envs=2, hyperparameters={"n_steps": 32, "batch_size": 64})
        train(run, tmp_path / "x", progress_bar=False)


def test_teachers_are_the_named_rules_with_their_settings():
    env = make_vec_env(TrainingRun(obs_mode="oracle", n_envs=2), 2, seed=0)
    corrective = make_teacher(TrainingRun(obs_mode="oracle", teacher="oracle_corrective", teacher_parameter=3.0), env)
    assert isinstance(corrective, Oracle) and corrective.action == "corrective" and corrective.threshold == 3.0
    band = make_teacher(TrainingRun(obs_mode="oracle", teacher="corrective_band"), env)
    assert isinstance(band, CorrectiveBand) and band.band == TEACHERS["corrective_band"][1]


class _Always:
    """A stand-in learner that always gives one action."""

    def __init__(self, action: int):
        self.action = action

    def predict(self, observation, deterministic=True):
        return np.full(len(observation["time_since_maintenance"]), self.action), None


def test_a_dagger_collection_steps_the_learner_and_records_the_teachers_labels():
    from agents.imitation import collect
    from agents.policies import RunToFailure
    from agents.training import normalize

    run = TrainingRun(obs_mode="oracle", n_envs=2, env_kwargs={"horizon": 20})
    env = normalize(make_vec_env(run, 2, seed=0))
    data = collect(env, RunToFailure(), 40, restore=env.venv.inverse, learner=_Always(1))
    assert data["actions"].shape == data["taken"].shape == (20, 2)
    assert np.all(data["actions"] == 0)  # the teacher never maintains
    assert np.all(data["taken"] == 1)
    # the learner's corrective action on k was carried out at every step: each costs 1 (downtime after a failure 4)
    assert np.all(data["rewards"] <= -1.0)
    teacher_only = collect(env, RunToFailure(), 40, restore=env.venv.inverse)
    assert np.all(teacher_only["taken"] == 0) and np.all(teacher_only["rewards"] == 0.0)


def test_dagger_rounds_label_the_learners_states_and_aggregate_them(tmp_path):
    run = TrainingRun(algo="ppo", timesteps=64, obs_mode="oracle", n_envs=4, eval_every=64, eval_episodes=1,
                      env_kwargs={"horizon": 50}, hyperparameters={"n_steps": 16, "batch_size": 64},
                      teacher="oracle", teacher_steps=1024, dagger_rounds=2)
    cloning = train(run, tmp_path, progress_bar=False)["cloning"]
    assert cloning["steps"] == sum(cloning["action_counts"]) == 3 * 1024  # the teacher's steps, then two rounds'
    assert len(cloning["rounds"]) == 2
    for entry in cloning["rounds"]:
        assert 0.0 <= entry["agreement"] <= 1.0
    # after the cloning the learner already mostly does what the oracle would
    assert cloning["rounds"][0]["agreement"] >= 0.9
    assert cloning["accuracy"] >= 0.9
    with pytest.raises(ValueError, match="needs a teacher"):
        run = TrainingRun(timesteps=64, n_envs=2, dagger_rounds=1, hyperparameters={"n_steps": 32, "batch_size": 64})
        train(run, tmp_path / "x", progress_bar=False)


def test_train_command_rejects_negative_dagger_rounds(capsys):
    with pytest.raises(SystemExit):
        main(["train", "--dagger-rounds", "-1", "--out", "x"])
    assert "expected an integer >= 0" in capsys.readouterr().err


#: a train command line of a few seconds: A2C's rollouts are 16 steps per environment
TINY_TRAIN = ["train", "--algo", "a2c", "--obs-mode", "oracle", "--n-envs", "2", "--timesteps", "64", "--eval-every", "32",
              "--eval-episodes", "1", "--env", "horizon=50", "--no-progress"]


def _files(directory):
    return {str(path.relative_to(directory)): path.read_bytes() for path in sorted(directory.rglob("*")) if path.is_file()}


def test_the_train_command_writes_its_directory_whole_and_continues_it(tmp_path, capsys):
    """--out appears when the run completes, no staging directory left and no staging path recorded; resumed from
    itself, the run adds its checkpoints beside the earlier ones."""
    out = tmp_path / "runs" / "a"
    assert main([*TINY_TRAIN, "--out", str(out)]) == 0, capsys.readouterr().err
    assert [path.name for path in (tmp_path / "runs").iterdir()] == ["a"]  # the staging directory was moved in
    assert sorted(path.name for path in (out / "checkpoints").iterdir()) == ["a2c_32_steps", "a2c_64_steps"]
    selected = json.loads((out / "training.json").read_text())["selected"]["steps"]  # what --resume out continues
    assert main([*TINY_TRAIN, "--resume", str(out), "--out", str(out)]) == 0, capsys.readouterr().err
    assert [path.name for path in (tmp_path / "runs").iterdir()] == ["a"]
    summary = json.loads((out / "training.json").read_text())
    added = {e["directory"].removeprefix("checkpoints/") for e in summary["evaluations"] if e["directory"] != "last"}
    assert added and {path.name for path in (out / "checkpoints").iterdir()} == {"a2c_32_steps", "a2c_64_steps"} | added
    assert summary["resumed_from"] == str(out) and summary["last"] == {"steps": selected + 64, "directory": "last"}
    assert load_policy(out / "last").num_timesteps == selected + 64
    for name, data in _files(out).items():  # no file names the staging directory (.a.XXXX beside out)
        assert f"{out.parent}/.a." not in data.decode("latin-1"), name
    assert "wrote " + str(out) in capsys.readouterr().out


@pytest.mark.parametrize("failure", [RuntimeError("the learner failed"), KeyboardInterrupt()], ids=["exception", "interrupt"])
def test_a_failed_train_command_leaves_out_as_it_was(tmp_path, monkeypatch, capsys, failure):
    """The run fails at its very end (checkpoints and ``last`` written): a new --out does not appear, nor the directories
    above it; a continued --out keeps its earlier files, byte for byte."""
    import agents.training

    def fail(*args, **kwargs):
        raise failure

    assert main([*TINY_TRAIN, "--out", str(tmp_path / "done")]) == 0, capsys.readouterr().err
    before = _files(tmp_path / "done")
    monkeypatch.setattr(agents.training, "write_json", fail)  # training.json, the run's last file
    done = str(tmp_path / "done")
    for argv in ([*TINY_TRAIN, "--out", str(tmp_path / "new" / "out")], [*TINY_TRAIN, "--resume", done, "--out", done]):
        assert main(argv) == (130 if isinstance(failure, KeyboardInterrupt) else 2)
        assert sorted(path.name for path in tmp_path.iterdir()) == ["done"]
        assert _files(tmp_path / "done") == before


def test_the_train_command_refuses_a_non_empty_out_it_does_not_continue(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("kept")
    assert main([*TINY_TRAIN, "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "--out: " in error and "exists and is not empty" in error
    assert [path.name for path in tmp_path.iterdir()] == ["out"] and _files(out) == {"notes.txt": b"kept"}


def test_a_new_ppo_policys_rollout_is_one_whole_episode_of_every_environment():
    from agents.training import hyperparameters

    # the environments start together and every episode lasts the horizon (500 steps by default)
    assert hyperparameters(TrainingRun())["n_steps"] == 500
    assert hyperparameters(TrainingRun(env_kwargs={"horizon": 50}, n_envs=4))["n_steps"] == 50
    assert hyperparameters(TrainingRun(hyperparameters={"n_steps": 128}))["n_steps"] == 128  # a run's own setting wins
    assert hyperparameters(TrainingRun(teacher="oracle", n_envs=16))["n_steps"] == 256  # a clone's fine-tuning keeps 4096 // n_envs


def test_the_default_rollout_of_whole_episodes_makes_a_model_without_a_minibatch_warning(recwarn):
    from agents.training import hyperparameters, make_model

    run = TrainingRun(obs_mode="oracle", n_envs=2, env_kwargs={"horizon": 50})  # rollouts of 2 x 50 steps, minibatches of 256
    model, _ = make_model(run, make_vec_env(run, run.n_envs, 0, shaped=True), hyperparameters(run), None, None, None)
    assert model.n_steps == 50 and not [w for w in recwarn if "mini-batch" in str(w.message)]


def test_every_evaluation_records_the_spread_of_its_episodes_rewards(tmp_path):
    """The last model's evaluation, made outside the callback, too: its std is its episodes', not 0 by construction."""
    from stable_baselines3.common.evaluation import evaluate_policy

    from agents.training import normalize

    run = TrainingRun(algo="a2c", timesteps=32, obs_mode="oracle", n_envs=2, eval_every=10_000, eval_episodes=3,
                      env_kwargs={"horizon": 200}, hyperparameters={"n_steps": 16})
    [last] = train(run, tmp_path, progress_bar=False)["evaluations"]
    policy = load_policy(tmp_path / "last")
    env = normalize(make_vec_env(run, 3, VALIDATION_SEED, kind="batched"), training=False)
    policy.normalization.restore(env)
    rewards, _ = evaluate_policy(policy.policy, env, n_eval_episodes=3, deterministic=True, return_episode_rewards=True)
    assert np.std(rewards) > 0  # failures on some validation seeds, not on others
    assert last["directory"] == "last" and last["std_reward"] == pytest.approx(np.std(rewards), abs=1e-3)


def test_dqn_trains_exactly_the_steps_asked(tmp_path):
    """DQN collects 4 vector steps (16 environment steps) between updates: 100 steps stop within a collection."""
    run = TrainingRun(algo="dqn", timesteps=100, obs_mode="oracle", n_envs=4, eval_every=10_000, eval_episodes=1, env_kwargs={"horizon": 50},
                      hyperparameters={"learning_starts": 16, "buffer_size": 1_000, "batch_size": 16, "train_freq": 4})
    summary = train(run, tmp_path, progress_bar=False)
    assert summary["steps"] == summary["last"]["steps"] == 100 and load_policy(tmp_path / "last").num_timesteps == 100


def test_a_step_count_the_environments_cannot_make_is_refused(tmp_path):
    with pytest.raises(ValueError, match=r"timesteps: 450 is not a multiple of n_envs \(4\), .*expected e.g. 448 or 452"):
        train(TrainingRun(timesteps=450, n_envs=4), tmp_path, progress_bar=False)
    assert not any(tmp_path.iterdir())


def test_training_leaves_nothing_in_the_temporary_directory(tmp_path, monkeypatch, capsys):
    """stable-baselines3's logger, left to itself, makes an empty SB3-<time> directory there on every run."""
    import tempfile

    private = tmp_path / "tmp"
    private.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(private))
    assert main([*TINY_TRAIN, "--out", str(tmp_path / "out")]) == 0, capsys.readouterr().err
    assert "trained a2c for 64 steps" in capsys.readouterr().out
    assert list(private.iterdir()) == []


@pytest.mark.parametrize("algo", ["ppo", "a2c", "dqn"])
def test_the_default_hyperparameters_pass_the_checks_agent_files_get(algo):
    """And every checked name is one the algorithm's constructor takes (a misspelt one would never be settable)."""
    import inspect

    from agents.agent_files import ALGORITHMS
    from agents.hyperparameters import HYPERPARAMETERS, check_hyperparameters
    from agents.training import default_hyperparameters

    for cloned in (False, True):
        check_hyperparameters(algo, default_hyperparameters(algo, 16, cloned=cloned), "hyperparameters")
    assert set(HYPERPARAMETERS[algo]) <= set(inspect.signature(ALGORITHMS[algo]).parameters)
    with pytest.raises(ValueError, match=r"^hyperparameters.gamma must be a finite number in \[0, 1\], got 1.5$"):
        check_hyperparameters(algo, {"gamma": 1.5}, "hyperparameters")
