"""A hash of everything the environments return over fixed seeds: two commits that print the same
``final`` line behave the same, bit for bit, in this regime.

What it hashes: for each obs_mode ("phm", "sensors", "oracle"), three single-env episodes of 120 steps
(seeds 100..102; action 0, or a random action with probability 0.1 from a seeded generator) and 300
steps of the native vector env with 8 systems (seed 7): every observation, reward, flag and info.
Faults arrive late in so short episodes: the chain's estimation and prognosis stages are exercised
by ``ea-gym phm`` and ``ea-gym reproduce``, whose outputs should be compared too.

Run from a checkout's root: ``python experiments/benchmarks/env_fingerprint.py``; ``--smoke`` hashes one
episode of 10 steps and 10 vector steps per obs_mode (a different hash, for checking that it runs).
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's ea_gym and experiments.common, installed or not

from ea_gym.env import ENV_ID
from experiments.common import parse_with_smoke

#: the smoke run: the same hashing on a few steps
SMOKE = {"episodes": 1, "horizon": 10, "vector_steps": 10}


def feed(digest: Any, value: Any) -> None:
    """Add ``value`` (nested dicts, sequences, arrays, scalars) to the running ``digest``."""
    if isinstance(value, dict):
        for key in sorted(value):
            digest.update(str(key).encode())
            feed(digest, value[key])
    elif isinstance(value, (list, tuple)):
        for item in value:
            feed(digest, item)
    elif isinstance(value, np.ndarray) and value.dtype == object:
        for item in value.ravel():
            feed(digest, item)
    elif isinstance(value, np.ndarray):
        digest.update(np.ascontiguousarray(value).tobytes())
        digest.update(str(value.dtype).encode())
    else:
        digest.update(repr(value).encode())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=3, help="single-env episodes per obs_mode (default 3)")
    parser.add_argument("--horizon", type=int, default=120, help="steps per episode (default 120)")
    parser.add_argument("--vector-steps", type=int, default=300, help="steps of the vector env per obs_mode (default 300)")
    args = parse_with_smoke(parser, argv, SMOKE)
    digest = hashlib.sha256()
    for mode in ("phm", "sensors", "oracle"):
        env = gym.make(ENV_ID, obs_mode=mode, horizon=args.horizon)
        rng = np.random.default_rng(0)
        n_actions = int(env.action_space.n)  # type: ignore[attr-defined]
        for episode in range(args.episodes):
            feed(digest, env.reset(seed=100 + episode))
            done = False
            while not done:
                action = int(rng.integers(n_actions)) if rng.random() < 0.1 else 0
                observation, reward, terminated, truncated, info = env.step(action)
                feed(digest, (observation, reward, terminated, truncated, info))
                done = terminated or truncated
        print(mode, "single", digest.hexdigest()[:16], flush=True)
        vector = gym.make_vec(ENV_ID, num_envs=8, vectorization_mode="vector_entry_point", obs_mode=mode, horizon=args.horizon)
        feed(digest, vector.reset(seed=7))
        rng = np.random.default_rng(1)
        for _ in range(args.vector_steps):
            feed(digest, vector.step(np.where(rng.random(8) < 0.1, rng.integers(n_actions, size=8), 0)))
        print(mode, "vector", digest.hexdigest()[:16], flush=True)
    print("final", digest.hexdigest())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
