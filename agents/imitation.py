"""Behaviour cloning of a rule policy into a stable-baselines3 actor-critic, before reinforcement learning.

Random exploration in this environment mostly replaces healthy components (3 actions in 7 replace
something) and a learner soon settles for running to failure: the useful decision, replacing the
diagnosed component shortly before its End of Life, is a rare event it seldom stumbles on. Starting
from a rule's behaviour (kickstarting) puts the learner where that decision is made; reinforcement
learning then improves on the rule.

Cloning from the teacher's own steps alone (behaviour cloning) leaves the learner untrained where its
small mistakes take it and the teacher never goes: a corrective step missed near a band's edge lets a
component wear further than the teacher ever lets it. ``dagger_rounds`` runs DAgger (Ross, Gordon and
Bagnell, 2011) after the cloning: each round the learner acts (its most likely action), the teacher
labels every state the learner visits, the labelled steps join the aggregate, and the policy is fitted
again on all of it.

``clone`` runs the teacher on the training environments, then fits the policy's action distribution
to the teacher's actions (cross-entropy) and its value function to the discounted returns of the
normalised rewards. The maintenance actions are rare (about 1 step in 200) but not weighted up: the
teacher's rule is a sharp function of the RUL and the diagnosis, which the network learns with enough
passes, while up-weighting them made it replace healthy components (1.6 % of the steps against 0.08 %
unweighted, on 100,000 steps of the RUL-threshold rule).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.vec_env import VecNormalize


@dataclass(frozen=True)
class CloningResult:
    """What behaviour cloning did.

    Attributes:
        steps: environment steps collected in all (the teacher's, then each DAgger round's).
        action_counts: how often the teacher chose each action.
        accuracy: share of the collected steps where the cloned policy's most likely action is the teacher's.
        maintenance_recall: the same, over the steps where the teacher chose a maintenance action (None
            if it chose none).
        teacher_mean_return: the teacher's mean episode return (raw rewards) over the completed episodes
            (None if none completed).
        rounds: one entry per DAgger round, measured on the states the learner visited before that
            round's fit: ``agreement`` (share of its actions the teacher would have taken),
            ``maintenance_recall`` (of the teacher's maintenance labels there), ``mean_return`` (the
            learner's mean episode return, raw rewards, None if no episode completed).
    """

    steps: int
    action_counts: list[int]
    accuracy: float
    maintenance_recall: float | None
    teacher_mean_return: float | None
    rounds: list[dict[str, float | None]] = field(default_factory=list)


def collect(
    env: VecNormalize,
    teacher: Any,
    steps: int,
    restore: Callable[[dict], dict] = lambda o: o,
    learner: OnPolicyAlgorithm | None = None,
) -> dict[str, Any]:
    """Run ``steps`` environment steps in total, labelled with ``teacher``'s actions (SB3 ``predict`` on
    environment observations).

    The teacher acts, or with a ``learner`` (an SB3 model on ``env``'s normalised observations) the
    learner acts and the teacher only labels the states it visits (a DAgger round): ``actions`` are
    then the teacher's labels and ``taken`` the learner's actions. The normalisation statistics of
    ``env`` are updated as the steps go; the unnormalised observations and rewards are returned so that
    they can be normalised afterwards with the final statistics. ``restore`` turns an unnormalised
    observation of ``env`` back into the environment's own (see ``agents.observations.LearnerView``),
    which is what the teacher reads.
    """
    n = env.num_envs
    env.reset()
    starts = np.ones(n, dtype=bool)
    state = None
    observations, actions, taken, rewards, dones, returns = [], [], [], [], [], []
    for _ in range(max(steps // n, 1)):
        raw = cast(dict[str, np.ndarray], env.get_original_obs())  # Dict observations
        label, state = teacher.predict(restore(raw), state=state, episode_start=starts, deterministic=True)
        label = np.asarray(label)
        action = label if learner is None else learner.predict(env.normalize_obs(raw), deterministic=True)[0]
        _, _, done, infos = env.step(np.asarray(action))
        observations.append({key: value.copy() for key, value in raw.items()})
        actions.append(label.copy())
        taken.append(np.asarray(action).copy())
        rewards.append(env.get_original_reward().copy())
        dones.append(done.copy())
        returns += [info["episode"]["r"] for info in infos if "episode" in info]
        starts = done
    return {
        "observations": {key: np.stack([o[key] for o in observations]) for key in observations[0]},
        "actions": np.stack(actions),
        "taken": np.stack(taken),
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
    dagger_rounds: int = 0,
) -> CloningResult:
    """Fit ``model``'s policy to ``teacher``'s actions and its value function to the returns, then
    run ``dagger_rounds`` rounds of DAgger (``steps`` more labelled steps each, the policy refitted on
    the aggregate for ``epochs`` passes).

    Args:
        model: a PPO or A2C model on ``env`` (MultiInputPolicy).
        env: the training environments, normalised (their statistics are updated by every collection).
        teacher: a rule policy of ``agents.policies`` built for ``env``'s obs_mode.
        steps: environment steps to collect, for the cloning and again for each DAgger round.
        epochs: passes over the collected steps at each fit.
        batch_size: samples per gradient step.
        learning_rate: of the fitting's own Adam optimizer (the model's is tuned for fine-tuning).
        restore: see ``collect``.
        rng: shuffles the samples (default: seeded from the model's seed).
        dagger_rounds: DAgger rounds after the cloning, >= 0.
    """
    if not (isinstance(dagger_rounds, int) and dagger_rounds >= 0):
        raise ValueError(f"dagger_rounds must be an integer >= 0, got {dagger_rounds!r}")
    rng = rng if rng is not None else np.random.default_rng(model.seed)
    policy = model.policy
    optimizer = th.optim.Adam(policy.parameters(), lr=learning_rate)
    batches = [collect(env, teacher, steps, restore)]
    teacher_returns = batches[0]["episode_returns"]
    rounds = []
    for round_ in range(dagger_rounds + 1):
        if round_ > 0:
            visited = collect(env, teacher, steps, restore, learner=model)
            labels, taken = visited["actions"].reshape(-1), visited["taken"].reshape(-1)
            rounds.append({
                "agreement": float(np.mean(labels == taken)),
                "maintenance_recall": float(np.mean(taken[labels > 0] == labels[labels > 0])) if np.any(labels > 0) else None,
                "mean_return": float(np.mean(visited["episode_returns"])) if len(visited["episode_returns"]) else None,
            })
            batches.append(visited)
        # normalised with the latest statistics, so that every sample matches what the policy will see
        observations, actions, value_targets = _samples(batches, env, model.gamma)
        _fit(policy, optimizer, observations, actions, value_targets, epochs, batch_size, model.vf_coef, model.max_grad_norm, rng)

    predicted = _most_likely(policy, observations)
    maintenance = actions > 0
    return CloningResult(
        steps=int(len(actions)),
        action_counts=np.bincount(actions, minlength=int(cast(spaces.Discrete, model.action_space).n)).tolist(),
        accuracy=float(np.mean(predicted == actions)),
        maintenance_recall=float(np.mean(predicted[maintenance] == actions[maintenance])) if maintenance.any() else None,
        teacher_mean_return=float(np.mean(teacher_returns)) if len(teacher_returns) else None,
        rounds=rounds,
    )


def _samples(batches: list[dict[str, Any]], env: VecNormalize, gamma: float) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
    """The collected steps of every batch, flattened: normalised observations, the teacher's actions and
    the value targets (discounted returns of the normalised rewards along each batch's trajectories)."""
    observations: dict[str, list[np.ndarray]] = {}
    actions, targets = [], []
    for data in batches:
        T, n = data["actions"].shape
        flat = {key: value.reshape((T * n,) + value.shape[2:]) for key, value in data["observations"].items()}
        for key, value in cast(dict[str, np.ndarray], env.normalize_obs(flat)).items():
            observations.setdefault(key, []).append(value)
        actions.append(data["actions"].reshape(-1))
        targets.append(discounted_returns(env.normalize_reward(data["rewards"]), data["dones"], gamma).reshape(-1))
    return {key: np.concatenate(parts) for key, parts in observations.items()}, np.concatenate(actions).astype(np.int64), np.concatenate(targets)


def _fit(
    policy: Any, optimizer: th.optim.Optimizer, observations: dict[str, np.ndarray], actions: np.ndarray, value_targets: np.ndarray,
    epochs: int, batch_size: int, vf_coef: float, max_grad_norm: float, rng: np.random.Generator,
) -> None:
    """Cross-entropy on the actions plus ``vf_coef`` x the value function's squared error, ``epochs`` passes."""
    as_tensor = lambda x: th.as_tensor(x, device=policy.device)  # noqa: E731
    policy.set_training_mode(True)
    for _ in range(epochs):
        order = rng.permutation(len(actions))
        for start in range(0, len(order), batch_size):
            rows = order[start : start + batch_size]
            obs = {key: as_tensor(value[rows]) for key, value in observations.items()}
            values, log_prob, _ = policy.evaluate_actions(obs, as_tensor(actions[rows]))
            policy_loss = -log_prob.mean()
            value_loss = th.nn.functional.mse_loss(values.flatten(), as_tensor(value_targets[rows]).float())
            loss = policy_loss + vf_coef * value_loss
            optimizer.zero_grad()
            loss.backward()
            th.nn.utils.clip_grad_norm_(policy.parameters(), max_grad_norm)
            optimizer.step()
    policy.set_training_mode(False)


def _most_likely(policy: Any, observations: dict[str, np.ndarray]) -> np.ndarray:
    """The policy's most likely action for every sample."""
    rows = len(next(iter(observations.values())))
    with th.no_grad():
        return np.concatenate([
            policy.get_distribution({key: th.as_tensor(value[i : i + 4096], device=policy.device) for key, value in observations.items()})
            .distribution.probs.argmax(-1).cpu().numpy()
            for i in range(0, rows, 4096)
        ])
