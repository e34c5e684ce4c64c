"""RLlib and Ray (the optional extra ea-gym[rllib]).

Without ray (CI's .venv): the rllib backend is refused in one line. With it (``bash scripts/test_ray.sh``,
its own virtual environment): the env creator RLlib's env runners call, and a PPO iteration on an env
runner process whose episodes all end at the horizon.
"""

import importlib.util
import re
from pathlib import Path

import pytest

from ea_gym.cli import main

HAS_RLLIB = importlib.util.find_spec("ray") is not None and importlib.util.find_spec("ray.rllib") is not None
needs_rllib = pytest.mark.skipif(not HAS_RLLIB, reason="needs the rllib extra: bash scripts/test_ray.sh")
#: the committed PPO agent (agents/data/ppo_phm)
PPO_AGENT = Path(__file__).resolve().parents[1] / "agents" / "data" / "ppo_phm"


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


def rllib_recipe() -> str:
    """The RLlib block of docs/rl-libraries.md (a ``{code-block} python``: tests/test_docs.py runs only ``python`` blocks)."""
    page = (Path(__file__).resolve().parents[1] / "docs" / "rl-libraries.md").read_text()
    blocks = re.findall(r"^```\{code-block\} python\n(.*?)^```$", page, re.M | re.S)
    assert len(blocks) == 1 and "PPOConfig" in blocks[0]
    return blocks[0]


@needs_rllib
def test_the_rllib_recipe_of_the_docs_runs_as_written():
    """docs/rl-libraries.md's RLlib recipe, run as written: RLlib's own env creation on an env runner process,
    which imports ea_gym through the ``ea_gym:`` prefix of the id (gymnasium's ``module:id``), and RLlib's
    FlattenObservations connector for the Dict observation (RLlib has no default encoder for it). Episodes of
    the horizon's 20 steps, none of another length."""
    namespace: dict[str, object] = {}
    exec(compile(rllib_recipe(), "docs/rl-libraries.md[RLlib]", "exec"), namespace)
    runners = namespace["result"]["env_runners"]  # type: ignore[index]
    assert runners["num_env_steps_sampled_lifetime"] >= 80
    assert runners["episode_len_min"] == runners["episode_len_max"] == 20


@pytest.mark.skipif(HAS_RLLIB, reason="the message shown where ray is missing")
def test_benchmark_ray_without_ray_is_one_line_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "benchmark"
    assert main(["benchmark", "--ray", "--episodes", "2", "--no-ppo", "--no-progress", "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "--ray" in error and "'.[rllib]'" in error
    assert not out.exists()


def test_batches_split_into_chunks_per_worker_give_the_same_records():
    """The seam RayRunner uses: 5 seeds in chunks for 3 workers (2 + 2 + 1), records equal one chunk's."""
    from agents.benchmark.batches import evaluate_side_by_side
    from agents.benchmark.runners import LocalRunner
    from agents.benchmark.settings import env_factory, vector_env_factory
    from agents.policies import ActionMap, Periodic, RunToFailure

    class ThreeWorkers(LocalRunner):
        workers = 3

        def chunk(self, seeds: int, max_envs: int) -> int:
            return -(-seeds // self.workers)

    make = vector_env_factory("sensors", horizon=40)
    probe = env_factory("sensors", horizon=40)()
    actions = ActionMap.from_env(probe)
    probe.close()
    policies = {"periodic": Periodic(actions, 10.0), "run_to_failure": RunToFailure(actions)}
    whole = evaluate_side_by_side(policies, make, range(7, 12), False, 100)
    split = evaluate_side_by_side(policies, make, range(7, 12), False, 100, runner=ThreeWorkers())
    for name in policies:
        assert split[name].seeds.tolist() == whole[name].seeds.tolist() == [7, 8, 9, 10, 11]
        assert set(split[name].per_episode) == set(whole[name].per_episode)
        for key, values in whole[name].per_episode.items():
            assert split[name].per_episode[key].tolist() == values.tolist(), (name, key)
    assert whole["periodic"].per_episode["cost"].tolist() != whole["run_to_failure"].per_episode["cost"].tolist()


@needs_rllib
def test_benchmark_on_ray_records_equal_the_local_run(tmp_path):
    """Tuning, evaluation and timelines, the committed PPO agent's among them, as Ray tasks on a local Ray
    of 2 CPUs (3 seeds: chunks of 2 and 1) against this process."""
    from agents.benchmark.run import run_benchmark
    from agents.benchmark.runners import RayRunner

    grids = {"oracle": [5, 20], "rul_threshold": [5], "corrective_band": [{"k": 0.8, "m": 0.8, "b": 0.4}], "periodic": [20, 60]}
    kwargs = {"tune_episodes": 3, "progress": False, "tune": True, "grids": grids, "env_kwargs": {"horizon": 60}}
    local = run_benchmark(3, 0, tmp_path / "local", PPO_AGENT, **kwargs)
    assert RayRunner(None, num_cpus=2).workers == 2  # the local Ray that ray="local" joins
    remote = run_benchmark(3, 0, tmp_path / "ray", PPO_AGENT, ray="local", **kwargs)
    assert "ppo" in local["policies"] and local["skipped"] == remote["skipped"] == {}
    for key in ("policies", "ranking", "tuning", "value_of_information", "seeds"):
        assert remote[key] == local[key], key
    assert (tmp_path / "ray" / "timelines.json").read_text() == (tmp_path / "local" / "timelines.json").read_text()


@needs_rllib
def test_benchmark_on_a_cluster_of_two_nodes_joined_by_address_records_equal_the_local_run(tmp_path):
    """--ray ADDRESS: a Ray cluster of a head and a second node (1 CPU each, both on this machine), joined by
    its address as a real cluster's would be; the PPO agent's and the rules' records and timelines equal
    this process's (3 seeds: chunks of 2 and 1)."""
    import ray
    from ray.cluster_utils import Cluster

    from agents.benchmark.run import run_benchmark
    from agents.benchmark.runners import RayRunner

    ray.shutdown()  # a Ray joined by an earlier test
    kwargs = {"progress": False, "allow_stale": True, "env_kwargs": {"horizon": 60}}
    local = run_benchmark(3, 0, tmp_path / "local", PPO_AGENT, **kwargs)
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    try:
        cluster.add_node(num_cpus=1)
        assert RayRunner(cluster.address).workers == 2 and len([n for n in ray.nodes() if n["Alive"]]) == 2
        remote = run_benchmark(3, 0, tmp_path / "cluster", PPO_AGENT, ray=cluster.address, **kwargs)
    finally:
        ray.shutdown()
        cluster.shutdown()
    assert "ppo" in local["policies"]
    for key in ("policies", "ranking", "value_of_information", "seeds"):
        assert remote[key] == local[key], key
    assert (tmp_path / "cluster" / "timelines.json").read_text() == (tmp_path / "local" / "timelines.json").read_text()


def test_a_trained_agent_travels_as_its_files_and_acts_as_loaded_here(tmp_path):
    """What a Ray task receives: the batch pickled (cloudpickle, as Ray sends it) and unpickled. The agent
    arrives as its files' bytes and loads again without its directory: the same weights, normalisation and
    actions, and a side-by-side evaluation with a rule gives the local records."""
    import shutil

    import cloudpickle
    import numpy as np
    import torch

    from agents.benchmark.batches import evaluate_side_by_side
    from agents.benchmark.runners import LocalRunner
    from agents.benchmark.settings import env_factory, vector_env_factory
    from agents.policies import ActionMap, RulThreshold
    from agents.portable_agent import PortableAgent
    from agents.training import load_policy

    directory = tmp_path / "ppo_phm"
    shutil.copytree(PPO_AGENT, directory)
    agent = PortableAgent(directory)
    shutil.rmtree(directory)  # a worker on another machine has no such directory
    arrived = cloudpickle.loads(cloudpickle.dumps(agent))
    assert len(cloudpickle.dumps(agent)) < 2 * sum(map(len, agent.files.values()))  # the bytes, no environment
    here, there = load_policy(PPO_AGENT), arrived.policy()
    assert there is not agent.policy() and arrived.obs_mode == agent.obs_mode == "phm"
    assert set(here.policy.state_dict()) == set(there.policy.state_dict())
    assert all(torch.equal(tensor, there.policy.state_dict()[name]) for name, tensor in here.policy.state_dict().items())
    assert here.normalization.observations.keys() == there.normalization.observations.keys()

    class Journey(LocalRunner):
        """Each batch pickled and unpickled before it runs."""

        def run(self, batches):
            return [cloudpickle.loads(cloudpickle.dumps(batch))() for batch in batches]

    probe = env_factory("phm")()
    actions = ActionMap.from_env(probe)
    observations = [probe.reset(seed=3)[0]]
    for _ in range(499):  # never maintained, the machine wears: the agent acts from step 202 on
        observations.append(probe.step(0)[0])
    probe.close()
    batch = {key: np.stack([o[key] for o in observations]) for key in observations[0]}
    chosen = arrived.predict(batch)[0]
    assert np.array_equal(chosen, here.predict(batch)[0]) and len(set(chosen.tolist())) > 1
    make = vector_env_factory("phm", horizon=40)
    policies = {"ppo": agent, "rul_threshold": RulThreshold(actions, 5.0, action="corrective")}
    local = evaluate_side_by_side(policies, make, range(20, 23), False, 100)
    sent = evaluate_side_by_side(policies, make, range(20, 23), False, 100, runner=Journey())
    for name in policies:
        for key, values in local[name].per_episode.items():
            assert sent[name].per_episode[key].tolist() == values.tolist(), (name, key)


def test_benchmark_ray_refuses_an_agent_of_pickled_files_before_any_work(tmp_path, capsys):
    """stable-baselines3's files would be unpickled on the workers: refused with Ray, even when trusted here."""
    agent = tmp_path / "agent"
    agent.mkdir()
    (agent / "model.zip").write_bytes(b"PK\x03\x04")
    (agent / "vecnormalize.pkl").write_bytes(b"\x80\x04")
    out = tmp_path / "benchmark"
    assert main(["benchmark", "--ray", "--episodes", "2", "--ppo", str(agent), "--trust-pickle", "--no-progress", "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "convert-agent" in error and "--ray" in error
    assert not out.exists()
