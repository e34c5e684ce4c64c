"""TorchRL on the native vector environment: ``GymWrapper`` specs check and rollouts equal to SyncVectorEnv's.

What it checks
    ``torchrl.envs.GymWrapper`` around ``gymnasium.make_vec(ENV_ID, num_envs=N,
    vectorization_mode="vector_entry_point", autoreset_mode="Disabled")``, the mode TorchRL prefers (it
    resets the ended systems through ``reset(options={"reset_mask": ...})``; it refuses ``NEXT_STEP``;
    with ``SAME_STEP`` its automatic registration of the infos' specs fails on nested info dicts such as
    ``cost``, for SyncVectorEnv as for this env): ``check_env_specs`` passes, with the infos ``true_rul``
    and ``failed`` read into the tensordict (the ``events`` info, lists of texts, is left out: TorchRL
    makes a tensor of every info it reads); a rollout of ``--steps`` steps without stopping
    at the ends (a fast-wearing machine and a short horizon, so episodes end by failure and by
    truncation) equals, tensor for tensor, the rollout of the same ``GymWrapper`` around Gymnasium's
    ``SyncVectorEnv`` of single environments under the same policy; every episode is at most
    ``--horizon`` steps long, those truncated exactly that long.

How to run (from the repository root; torchrl is not a dependency of the project)
    .venv/bin/pip install -c constraints.txt -e '.[torchrl]'   # torchrl 0.14.1, tensordict 0.14.3, torch 2.13.0
    .venv/bin/python experiments/integrations/torchrl_check.py [--envs 4] [--steps 60] [--horizon 12] [--out DIR] [--smoke]

    Writes ``DIR/torchrl_check.json`` (default DIR: experiments/results/torchrl). About a minute.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))  # this checkout's ea_gym and experiments.common, installed or not

import ea_gym  # noqa: F401 - registers the environments
from ea_gym.degradation import WearConfig
from ea_gym.env import ENV_ID
from ea_gym.files import write_atomic
from experiments.common import parse_with_smoke

FAST_WEAR = {c: WearConfig(rate=(0.1, 0.2), arrival=(0.0, 6.0)) for c in ("k", "m", "b")}  # failures within ~10 steps
INFO_KEYS = ("true_rul", "failed")
#: the smoke run: two systems, episodes of 4 steps
SMOKE = {"envs": 2, "steps": 12, "horizon": 4}


class SeededPolicy:
    """Carry on, or now and then a random action: drawn from its own torch generator, the same for every rollout."""

    def __init__(self, n_actions: int, seed: int):
        self.n_actions = n_actions
        self.generator = torch.Generator().manual_seed(seed)

    def __call__(self, tensordict: Any) -> Any:
        shape = tensordict.batch_size
        random = torch.randint(self.n_actions, shape, generator=self.generator)
        act = torch.rand(shape, generator=self.generator) < 0.2
        tensordict["action"] = torch.where(act, random, torch.zeros_like(random))
        return tensordict


class WithoutEvents(gym.vector.VectorWrapper):
    """The infos less ``events``: TorchRL turns every info into a tensor, and the events are lists of texts of
    any length (an object array; ``ea_gym.env.events.parse_event`` reads them)."""

    def __init__(self, env: Any):
        super().__init__(env)
        self.autoreset_mode = env.autoreset_mode  # read by TorchRL (DISABLED: it resets through reset_mask)

    def reset(self, **kwargs: Any) -> Any:
        observation, infos = self.env.reset(**kwargs)
        return observation, without_events(infos)

    def step(self, actions: Any) -> Any:
        *result, infos = self.env.step(actions)
        return (*result, without_events(infos))


def without_events(infos: dict[str, Any]) -> dict[str, Any]:
    kept = {key: value for key, value in infos.items() if key not in ("events", "_events")}
    if "final_info" in kept:
        kept["final_info"] = without_events(kept["final_info"])
    return kept


def wrapped(vector_env: Any) -> Any:
    """``GymWrapper`` reading the infos ``true_rul`` (s) and ``failed``: batched specs, one value per system."""
    from torchrl.data import Categorical, Composite, Unbounded
    from torchrl.envs import GymWrapper
    from torchrl.envs.gym_like import default_info_dict_reader

    env = GymWrapper(WithoutEvents(vector_env), categorical_action_encoding=True)
    n = vector_env.num_envs
    spec = Composite({"true_rul": Unbounded((n,), dtype=torch.float64), "failed": Categorical(2, (n,), dtype=torch.bool)}, shape=[n])
    env.set_info_dict_reader(default_info_dict_reader(list(INFO_KEYS), spec=spec))
    return env


def episode_lengths(rollout: Any) -> tuple[list[int], list[int], int]:
    """Lengths of the episodes that ended in the rollout (ended by termination, by truncation), and the steps."""
    terminated = rollout["next", "terminated"].squeeze(-1).numpy()
    truncated = rollout["next", "truncated"].squeeze(-1).numpy()
    by_failure, by_horizon = [], []
    for row_terminated, row_truncated in zip(terminated, truncated):
        length = 0
        for term, trunc in zip(row_terminated, row_truncated):
            length += 1
            if term or trunc:
                (by_failure if term else by_horizon).append(length)
                length = 0
    return by_failure, by_horizon, int(terminated.size)


def check(mode: str, envs: int, steps: int, horizon: int, seed: int) -> dict[str, Any]:
    from gymnasium.vector import SyncVectorEnv
    from torchrl.envs import check_env_specs

    kwargs = {"obs_mode": "phm", "horizon": horizon, "wear": FAST_WEAR}
    native = wrapped(gym.make_vec(ENV_ID, num_envs=envs, vectorization_mode="vector_entry_point", autoreset_mode=mode, **kwargs))
    reference = wrapped(SyncVectorEnv([lambda: gym.make(ENV_ID, **kwargs) for _ in range(envs)], autoreset_mode=mode))
    started = time.perf_counter()
    rollouts = []
    for env in (native, reference):
        check_env_specs(env, seed=seed)
        env.set_seed(seed)
        rollouts.append(env.rollout(steps, SeededPolicy(7, seed), break_when_any_done=False, auto_reset=True))
    keys = [sorted(map(str, rollout.keys(True, True))) for rollout in rollouts]
    equal = keys[0] == keys[1] and all(torch.equal(rollouts[0][key], rollouts[1][key]) for key in rollouts[0].keys(True, True))
    by_failure, by_horizon, total = episode_lengths(rollouts[0])
    return {
        "autoreset_mode": mode,
        "batch_size": list(native.batch_size),
        "check_env_specs": "passed",
        "rollout_keys": sorted("/".join(key) if isinstance(key, tuple) else key for key in rollouts[0].keys(True, True)),
        "rollout_equals_sync_vector_env": equal,
        "env_steps": total,
        "episodes_terminated": len(by_failure),
        "episodes_truncated": len(by_horizon),
        "terminated_lengths": sorted(by_failure),
        "truncated_lengths_all_equal_horizon": all(length == horizon for length in by_horizon),
        "longest_episode": max(by_failure + by_horizon, default=0),
        "seconds": round(time.perf_counter() - started, 1),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--envs", type=int, default=4, help="N, the vector environment's systems")
    parser.add_argument("--steps", type=int, default=60, help="rollout length (steps of the vector env)")
    parser.add_argument("--horizon", type=int, default=12, help="episode horizon (steps)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=ROOT / "experiments" / "results" / "torchrl")
    args = parse_with_smoke(parser, argv, SMOKE)
    import tensordict
    import torchrl

    results = [check("Disabled", args.envs, args.steps, args.horizon, args.seed)]
    from torchrl.envs import GymWrapper

    try:
        GymWrapper(gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", obs_mode="sensors"))
        next_step = "accepted"
    except RuntimeError as error:
        next_step = f"refused by TorchRL: {error}"
    report = {
        "command": " ".join(["python experiments/integrations/torchrl_check.py", *(argv if argv is not None else sys.argv[1:])]),
        "versions": {
            "torchrl": torchrl.__version__, "tensordict": tensordict.__version__, "torch": torch.__version__,
            "gymnasium": gym.__version__, "numpy": np.__version__, "python": platform.python_version(),
        },
        "settings": {"envs": args.envs, "steps": args.steps, "horizon": args.horizon, "seed": args.seed, "obs_mode": "phm",
                     "info_keys": list(INFO_KEYS), "wear": "fast: rate 0.1-0.2/s, arrival 0-6 s, every component"},
        "modes": results,
        "next_step_mode": next_step,
    }
    for result in results:
        print(
            f"{result['autoreset_mode']}: check_env_specs passed; rollout {result['env_steps']} env-steps equal to SyncVectorEnv's: "
            f"{result['rollout_equals_sync_vector_env']}; {result['episodes_terminated']} episodes failed, "
            f"{result['episodes_truncated']} truncated (all at the horizon: {result['truncated_lengths_all_equal_horizon']}), "
            f"longest {result['longest_episode']} steps"
        )
    print(f"NextStep: {next_step}")
    args.out.mkdir(parents=True, exist_ok=True)
    write_atomic(args.out / "torchrl_check.json", lambda tmp: Path(tmp).write_text(json.dumps(report, indent=2) + "\n"))
    ok = all(r["rollout_equals_sync_vector_env"] and r["truncated_lengths_all_equal_horizon"] for r in results)
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
