"""A CleanRL-style single-file PPO on the native vector environment (torch only).

What it does
    PPO with a clipped objective, GAE, advantage normalisation and a value loss, as CleanRL's ``ppo.py``,
    on ``gymnasium.make_vec(ENV_ID, num_envs=N, vectorization_mode="vector_entry_point",
    autoreset_mode="SameStep")`` with the benchmark's settings (``continue_after_failure=True``: a
    failure forces a replacement and the episode goes on; 500-step episodes). SAME_STEP is the classic
    CleanRL loop: the step that ends an episode returns the next one's first observation, and its done
    flag cuts the returns. The Dict observation is flattened (keys in sorted order) and standardised
    with running statistics; rewards (minus the step's cost) are divided by ``--reward-scale``.
    Every draw comes from the script's own generators (numpy and torch); no global random state.

    After training, the deterministic policy (argmax) and "carry on" (action 0, never maintain) run one
    episode each on ``--eval-episodes`` evaluation seeds (the same for both), on the NEXT_STEP default
    of the vector env; the mean cost per episode of each is printed and written.

How to run (from the repository root)
    .venv/bin/python experiments/integrations/cleanrl_ppo.py [--total-timesteps 16384] [--num-envs 16] [--out DIR] [--smoke]

    Writes ``DIR/cleanrl_ppo.json`` (default DIR: experiments/results/cleanrl_ppo): the settings, each
    update's mean cost of the episodes ended in it, the evaluation costs and the wall times. The
    default is a short run that shows the loop working, not a tuned agent (see the README).
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
from torch import nn

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))  # this checkout's ea_gym and experiments.common, installed or not

import ea_gym  # noqa: F401 - registers the environments
from ea_gym.env import ENV_ID
from ea_gym.files import write_atomic
from experiments.common import parse_with_smoke

EVALUATION_SEED = 100_000  # the benchmark's evaluation seeds start here; training seeds are below
#: the smoke run: two updates of 2 x 16 steps, one minibatch pass each, one evaluation episode
SMOKE = {"total_timesteps": 64, "num_envs": 2, "num_steps": 16, "minibatches": 2, "epochs": 1, "eval_episodes": 1}


def flatten(observation: dict[str, np.ndarray]) -> np.ndarray:
    """(N, D) float32: the Dict observation's arrays side by side, keys in sorted order."""
    return np.concatenate([np.asarray(observation[key], dtype=np.float32).reshape(len(observation[key]), -1) for key in sorted(observation)], axis=1)


class RunningStandardizer:
    """Running mean and variance of the observations (parallel-variance update); clips to +-10 std."""

    def __init__(self, size: int):
        self.mean, self.var, self.count = np.zeros(size), np.ones(size), 1e-4

    def update(self, batch: np.ndarray) -> None:
        mean, var, count = batch.mean(0), batch.var(0), len(batch)
        delta, total = mean - self.mean, self.count + count
        self.mean = self.mean + delta * count / total
        self.var = (self.var * self.count + var * count + delta**2 * self.count * count / total) / total
        self.count = total

    def __call__(self, batch: np.ndarray) -> np.ndarray:
        return np.clip((batch - self.mean) / np.sqrt(self.var + 1e-8), -10.0, 10.0).astype(np.float32)


def layer(inputs: int, outputs: int, std: float = float(np.sqrt(2))) -> nn.Linear:
    linear = nn.Linear(inputs, outputs)
    nn.init.orthogonal_(linear.weight, std)
    nn.init.constant_(linear.bias, 0.0)
    return linear


class Agent(nn.Module):
    """CleanRL's separate actor and critic MLPs (64 tanh units, two layers)."""

    def __init__(self, observations: int, actions: int):
        super().__init__()
        self.critic = nn.Sequential(layer(observations, 64), nn.Tanh(), layer(64, 64), nn.Tanh(), layer(64, 1, std=1.0))
        self.actor = nn.Sequential(layer(observations, 64), nn.Tanh(), layer(64, 64), nn.Tanh(), layer(64, actions, std=0.01))

    def value(self, x: torch.Tensor) -> torch.Tensor:
        return self.critic(x).squeeze(-1)

    def act(
        self, x: torch.Tensor, generator: torch.Generator, action: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """(action, its log-probability, the entropy, the value); samples an action when none is given."""
        logits = self.actor(x)
        log_probs = torch.log_softmax(logits, dim=-1)
        if action is None:
            action = torch.multinomial(log_probs.exp(), 1, generator=generator).squeeze(-1)
        entropy = -(log_probs.exp() * log_probs).sum(-1)
        return action, log_probs.gather(-1, action[:, None]).squeeze(-1), entropy, self.value(x)


def make_env(num_envs: int, obs_mode: str, autoreset_mode: str) -> Any:
    return gym.make_vec(
        ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point", autoreset_mode=autoreset_mode,
        obs_mode=obs_mode, continue_after_failure=True,
    )


def evaluate(choose: Any, obs_mode: str, seeds: list[int]) -> list[float]:
    """Each seed's episode cost under ``choose(observation) -> actions``, one episode per system."""
    env = make_env(len(seeds), obs_mode, "NextStep")
    observation, _ = env.reset(seed=seeds)
    costs, running = np.zeros(len(seeds)), np.ones(len(seeds), dtype=bool)
    while running.any():
        observation, rewards, terminated, truncated, _ = env.step(choose(observation))
        costs -= np.where(running, rewards, 0.0)
        running &= ~(terminated | truncated)
    env.close()
    return costs.tolist()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--total-timesteps", type=int, default=16384)
    parser.add_argument("--num-envs", type=int, default=16)
    parser.add_argument("--num-steps", type=int, default=128, help="steps per environment per update")
    parser.add_argument("--obs-mode", default="phm", choices=["phm", "sensors", "oracle"])
    parser.add_argument("--learning-rate", type=float, default=2.5e-4)
    parser.add_argument("--gamma", type=float, default=0.99)
    parser.add_argument("--gae-lambda", type=float, default=0.95)
    parser.add_argument("--minibatches", type=int, default=4)
    parser.add_argument("--epochs", type=int, default=4)
    parser.add_argument("--clip", type=float, default=0.2)
    parser.add_argument("--entropy-coef", type=float, default=0.01)
    parser.add_argument("--value-coef", type=float, default=0.5)
    parser.add_argument("--max-grad-norm", type=float, default=0.5)
    parser.add_argument("--reward-scale", type=float, default=100.0, help="rewards are divided by it (costs reach 400)")
    parser.add_argument("--eval-episodes", type=int, default=8)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=ROOT / "experiments" / "results" / "cleanrl_ppo")
    args = parse_with_smoke(parser, argv, SMOKE)
    for name in ("total_timesteps", "num_envs", "num_steps", "minibatches", "epochs", "eval_episodes"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")

    started = time.perf_counter()
    rng = np.random.default_rng(args.seed)
    generator = torch.Generator().manual_seed(args.seed)
    n, steps = args.num_envs, args.num_steps
    batch = n * steps
    minibatch = batch // args.minibatches
    env = make_env(n, args.obs_mode, "SameStep")
    observation, _ = env.reset(seed=args.seed * n)  # training seeds, far below the evaluation seeds
    flat = flatten(observation)
    standardize = RunningStandardizer(flat.shape[1])
    standardize.update(flat)
    with torch.random.fork_rng(devices=[]):  # the initial weights from the script's seed, torch's global state untouched
        torch.manual_seed(args.seed)
        agent = Agent(flat.shape[1], int(env.single_action_space.n))
    optimizer = torch.optim.Adam(agent.parameters(), lr=args.learning_rate, eps=1e-5)

    obs_buffer = torch.zeros((steps, n, flat.shape[1]))
    actions, log_probs, rewards, dones, values = (torch.zeros((steps, n)) for _ in range(5))
    next_obs, next_done = torch.from_numpy(standardize(flat)), torch.zeros(n)
    episode_cost, updates_log = np.zeros(n), []
    updates = max(1, args.total_timesteps // batch)
    for update in range(updates):
        for param_group in optimizer.param_groups:  # linear annealing, as CleanRL
            param_group["lr"] = (1.0 - update / updates) * args.learning_rate
        ended_costs: list[float] = []
        for step in range(steps):
            obs_buffer[step], dones[step] = next_obs, next_done
            with torch.no_grad():
                action, log_prob, _, value = agent.act(next_obs, generator)
            actions[step], log_probs[step], values[step] = action, log_prob, value
            observation, reward, terminated, truncated, _ = env.step(action.numpy())
            done = terminated | truncated
            episode_cost -= reward
            ended_costs += episode_cost[done].tolist()
            episode_cost[done] = 0.0
            rewards[step] = torch.from_numpy(reward / args.reward_scale).float()
            flat = flatten(observation)
            standardize.update(flat)
            next_obs, next_done = torch.from_numpy(standardize(flat)), torch.from_numpy(done.astype(np.float32))

        with torch.no_grad():  # generalised advantage estimation
            next_value = agent.value(next_obs)
            advantages, last = torch.zeros_like(rewards), torch.zeros(n)
            for t in reversed(range(steps)):
                not_done = 1.0 - (next_done if t == steps - 1 else dones[t + 1])
                following = next_value if t == steps - 1 else values[t + 1]
                delta = rewards[t] + args.gamma * following * not_done - values[t]
                last = delta + args.gamma * args.gae_lambda * not_done * last
                advantages[t] = last
            returns = advantages + values

        b_obs, b_actions = obs_buffer.reshape(batch, -1), actions.reshape(batch).long()
        b_log_probs, b_advantages = log_probs.reshape(batch), advantages.reshape(batch)
        b_returns, b_values = returns.reshape(batch), values.reshape(batch)
        for _ in range(args.epochs):
            order = rng.permutation(batch)
            for start in range(0, batch, minibatch):
                index = torch.from_numpy(order[start : start + minibatch])
                _, new_log_prob, entropy, new_value = agent.act(b_obs[index], generator, b_actions[index])
                ratio = (new_log_prob - b_log_probs[index]).exp()
                advantage = b_advantages[index]
                advantage = (advantage - advantage.mean()) / (advantage.std() + 1e-8)
                policy_loss = torch.max(-advantage * ratio, -advantage * ratio.clamp(1 - args.clip, 1 + args.clip)).mean()
                value_loss = 0.5 * ((new_value - b_returns[index]) ** 2).mean()
                loss = policy_loss - args.entropy_coef * entropy.mean() + args.value_coef * value_loss
                optimizer.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(agent.parameters(), args.max_grad_norm)
                optimizer.step()
        explained = 1.0 - float(torch.var(b_returns - b_values) / torch.var(b_returns)) if torch.var(b_returns) > 0 else float("nan")
        row = {
            "update": update + 1, "env_steps": (update + 1) * batch, "episodes_ended": len(ended_costs),
            "mean_episode_cost": float(np.mean(ended_costs)) if ended_costs else None,
            "mean_step_cost": float(-rewards.mean() * args.reward_scale), "explained_variance": explained,
            "elapsed_s": round(time.perf_counter() - started, 1),
        }
        updates_log.append(row)
        print(json.dumps(row), flush=True)
    env.close()
    train_seconds = time.perf_counter() - started

    def greedy(observation: dict[str, np.ndarray]) -> np.ndarray:
        with torch.no_grad():
            return agent.actor(torch.from_numpy(standardize(flatten(observation)))).argmax(-1).numpy()

    seeds = [EVALUATION_SEED + i for i in range(args.eval_episodes)]
    ppo_costs = evaluate(greedy, args.obs_mode, seeds)
    carry_on_costs = evaluate(lambda observation: np.zeros(len(seeds), dtype=np.int64), args.obs_mode, seeds)
    report = {
        "command": " ".join(["python experiments/integrations/cleanrl_ppo.py", *(argv if argv is not None else sys.argv[1:])]),
        "settings": {key: str(value) if isinstance(value, Path) else value for key, value in vars(args).items() if key != "out"},
        "versions": {"torch": torch.__version__, "gymnasium": gym.__version__, "numpy": np.__version__, "python": platform.python_version()},
        "updates": updates_log,
        "evaluation": {
            "seeds": seeds,
            "ppo_greedy_mean_cost": float(np.mean(ppo_costs)), "ppo_greedy_costs": ppo_costs,
            "carry_on_mean_cost": float(np.mean(carry_on_costs)), "carry_on_costs": carry_on_costs,
        },
        "train_seconds": round(train_seconds, 1),
        "total_seconds": round(time.perf_counter() - started, 1),
    }
    print(f"evaluation on {len(seeds)} seeds: PPO (greedy) {report['evaluation']['ppo_greedy_mean_cost']:.1f} per episode, "
          f"carry on {report['evaluation']['carry_on_mean_cost']:.1f}; training {train_seconds:.0f} s")
    write_atomic(args.out / "cleanrl_ppo.json", lambda tmp: Path(tmp).write_text(json.dumps(report, indent=2) + "\n"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
