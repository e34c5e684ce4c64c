"""Behaviour cloning of a rule policy into a stable-baselines3 actor-critic, before reinforcement learning.

Random exploration in this environment mostly replaces healthy components (3 actions in 7 replace
something) and a learner soon settles for running to failure: the useful decision, replacing the
diagnosed component shortly before its End of Life, is a rare event it seldom stumbles on. Starting
from a rule's behaviour (kickstarting) puts the learner where that decision is made; reinforcement
learning then improves on the rule.

``clone`` runs the teacher on the training environments, then fits the policy's action distribution
to the teacher's actions (cross-entropy) and its value function to the discounted returns of the
normalised rewards. The maintenance actions are rare (about 1 step in 200) but not weighted up: the
teacher's rule is a sharp function of the RUL and the diagnosis, which the network learns with enough
passes, while up-weighting them made it replace healthy components (1.6 % of the steps against 0.08 %
unweighted, on 100,000 steps of the RUL-threshold rule).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.vec_env import VecNormalize


@dataclass(frozen=True)
class CloningResult:
    """What behaviour cloning did.

    Attributes:
        steps: environment steps run by the teacher.
        action_counts: how often the teacher chose each action.
        accuracy: share of the collected steps where the cloned policy's most likely action is the teacher's.
        maintenance_recall: the same, over the steps where the teacher chose a maintenance action (None
            if it chose none).
        teacher_mean_return: the teacher's mean episode return (raw rewards) over the completed episodes
            (None if none completed).
    """

    steps: int
    action_counts: list[int]
    accuracy: float
    maintenance_recall: float | None
    teacher_mean_return: float | None


def collect(env: VecNormalize, teacher: Any, steps: int, restore: Callable[[dict], dict] = lambda o: o) -> dict[str, np.ndarray]:
    """Run ``teacher`` (SB3 ``predict`` on environment observations) for ``steps`` environment steps in total.

    The normalisation statistics of ``env`` are updated as the steps go; the unnormalised observations
    and rewards are returned so that they can be normalised afterwards with the final statistics.
    ``restore`` turns an unnormalised observation of ``env`` back into the environment's own (see
    ``agents.observations.LearnerView``), which is what the teacher reads.
    """
    n = env.num_envs
    env.reset()
    starts = np.ones(n, dtype=bool)
    state = None
    observations, actions, rewards, dones, returns = [], [], [], [], []
    for _ in range(max(steps // n, 1)):
        raw = env.get_original_obs()
        action, state = teacher.predict(restore(raw), state=state, episode_start=starts, deterministic=True)
        _, _, done, infos = env.step(np.asarray(action))
        observations.append({key: value.copy() for key, value in raw.items()})
        actions.append(np.asarray(action).copy())
        rewards.append(env.get_original_reward().copy())
        dones.append(done.copy())
        returns += [info["episode"]["r"] for info in infos if "episode" in info]
        starts = done
    return {
        "observations": {key: np.stack([o[key] for o in observations]) for key in observations[0]},
        "actions": np.stack(actions),
        "rewards": np.stack(rewards),
        "dones": np.stack(dones),
        "episode_returns": np.array(returns),
    }


def discounted_returns(rewards: np.ndarray, dones: np.ndarray, gamma: float) -> np.ndarray:
    """Return-to-go of every step (T, N), cut at episode ends; the last steps bootstrap on nothing."""
    out = np.zeros_like(rewards, dtype=float)
    running = np.zeros(rewards.shape[1])
    for t in range(len(rewards) - 1, -1, -1):
        running = rewards[t] + gamma * running * (1.0 - dones[t])
        out[t] = running
    return out


def clone(
    model: OnPolicyAlgorithm,
    env: VecNormalize,
    teacher: Any,
    steps: int,
    epochs: int = 40,
    batch_size: int = 512,
    learning_rate: float = 1e-3,
    restore: Callable[[dict], dict] = lambda o: o,
    rng: np.random.Generator | None = None,
) -> CloningResult:
    """Fit ``model``'s policy to ``teacher``'s actions and its value function to the teacher's returns.

    Args:
        model: a PPO or A2C model on ``env`` (MultiInputPolicy).
        env: the training environments, normalised (their statistics are updated by the teacher's run).
        teacher: a rule policy of ``agents.policies`` built for ``env``'s obs_mode.
        steps: environment steps to collect.
        epochs: passes over the collected steps.
        batch_size: samples per gradient step.
        learning_rate: of the cloning's own Adam optimizer (the model's is tuned for fine-tuning).
        restore: see ``collect``.
        rng: shuffles the samples (default: seeded from the model's seed).
    """
    rng = rng if rng is not None else np.random.default_rng(model.seed)
    data = collect(env, teacher, steps, restore)
    T, n = data["actions"].shape
    flat = {key: value.reshape((T * n,) + value.shape[2:]) for key, value in data["observations"].items()}
    observations = env.normalize_obs(flat)
    actions = data["actions"].reshape(-1)
    value_targets = discounted_returns(env.normalize_reward(data["rewards"]), data["dones"], model.gamma).reshape(-1)
    counts = np.bincount(actions, minlength=model.action_space.n)

    policy = model.policy
    device = policy.device
    as_tensor = lambda x: th.as_tensor(x, device=device)  # noqa: E731
    optimizer = th.optim.Adam(policy.parameters(), lr=learning_rate)
    policy.set_training_mode(True)
    for _ in range(epochs):
        order = rng.permutation(len(actions))
        for start in range(0, len(order), batch_size):
            rows = order[start : start + batch_size]
            obs = {key: as_tensor(value[rows]) for key, value in observations.items()}
            values, log_prob, _ = policy.evaluate_actions(obs, as_tensor(actions[rows]))
            policy_loss = -log_prob.mean()
            value_loss = th.nn.functional.mse_loss(values.flatten(), as_tensor(value_targets[rows]).float())
            loss = policy_loss + model.vf_coef * value_loss
            optimizer.zero_grad()
            loss.backward()
            th.nn.utils.clip_grad_norm_(policy.parameters(), model.max_grad_norm)
            optimizer.step()
    policy.set_training_mode(False)

    with th.no_grad():
        predicted = np.concatenate([
            policy.get_distribution({key: as_tensor(value[i : i + 4096]) for key, value in observations.items()})
            .distribution.probs.argmax(-1).cpu().numpy()
            for i in range(0, len(actions), 4096)
        ])
    maintenance = actions > 0
    return CloningResult(
        steps=int(T * n),
        action_counts=counts.tolist(),
        accuracy=float(np.mean(predicted == actions)),
        maintenance_recall=float(np.mean(predicted[maintenance] == actions[maintenance])) if maintenance.any() else None,
        teacher_mean_return=float(np.mean(data["episode_returns"])) if len(data["episode_returns"]) else None,
    )
