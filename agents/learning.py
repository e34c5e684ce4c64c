"""stable-baselines3's ``learn`` for exactly the environment steps asked, with a progress bar over them and
no log directory left in the system's temporary directory.

SB3 learns whole rollouts (PPO and A2C: ``n_steps`` of every environment) and whole ``train_freq``
collections (DQN), so ``learn(20_000)`` on 16 environments of 500-step rollouts runs 24,000 steps.
``learn_steps`` runs the whole rollouts that fit, then one shorter rollout of what is left; DQN stops
collecting at the count. The count must be a whole number of vector steps (of ``n_envs`` steps each).
"""

from __future__ import annotations

from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from tqdm.auto import tqdm

__all__ = ["check_steps", "learn_steps"]


def check_steps(steps: int, n_envs: int) -> None:
    """Refuse a step count that the ``n_envs`` environments, stepped together, cannot make exactly."""
    if steps % n_envs:
        below, above = steps - steps % n_envs, steps - steps % n_envs + n_envs
        raise ValueError(f"timesteps: {steps} is not a multiple of n_envs ({n_envs}), whose environments step together; "
                         f"expected e.g. {below or above} or {above}")


def learn_steps(model: BaseAlgorithm, steps: int, callback: BaseCallback, progress_bar: bool, reset_num_timesteps: bool) -> None:
    """``model.learn`` for exactly ``steps`` environment steps (a multiple of ``model.n_envs``, ``check_steps``).

    A PPO or A2C model learns whole rollouts, then one rollout of the remaining steps (its ``n_steps`` is
    restored afterwards); a DQN model stops collecting at the count.
    """
    check_steps(steps, model.n_envs)
    if model.tensorboard_log is None:  # else SB3 makes an empty log directory in the system's temporary directory
        model.set_logger(Logger(folder=None, output_formats=[]))
    with tqdm(total=steps, desc=f"training {type(model).__name__}", unit="step", disable=not progress_bar, leave=False) as bar:
        callbacks = CallbackList([callback, _Advance(bar)])
        if not isinstance(model, OnPolicyAlgorithm):
            start = 0 if reset_num_timesteps else model.num_timesteps
            callbacks.callbacks.append(_StopAt(start + steps))
            model.learn(steps, callback=callbacks, reset_num_timesteps=reset_num_timesteps)
            return
        rollout = model.n_steps * model.n_envs
        whole, left = steps - steps % rollout, steps % rollout
        if whole:
            model.learn(whole, callback=callbacks, reset_num_timesteps=reset_num_timesteps)
        if left:
            full = model.n_steps
            _resize_rollout(model, left // model.n_envs)
            try:
                model.learn(left, callback=callbacks, reset_num_timesteps=reset_num_timesteps and not whole)
            finally:
                _resize_rollout(model, full)


def _resize_rollout(model: OnPolicyAlgorithm, n_steps: int) -> None:
    """Rollouts of ``n_steps`` steps of every environment from now on (a new, empty rollout buffer)."""
    model.n_steps = n_steps
    model.rollout_buffer = type(model.rollout_buffer)(
        n_steps, model.observation_space, model.action_space, device=model.device, gamma=model.gamma, gae_lambda=model.gae_lambda,
        n_envs=model.n_envs, **model.rollout_buffer_kwargs,
    )


class _Advance(BaseCallback):
    """Moves a progress bar by the environment steps of every vector step."""

    def __init__(self, bar: tqdm) -> None:
        super().__init__()
        self.bar = bar

    def _on_step(self) -> bool:
        self.bar.update(self.training_env.num_envs)
        return True


class _StopAt(BaseCallback):
    """Stops the collection once the model has made ``until`` environment steps in all."""

    def __init__(self, until: int) -> None:
        super().__init__()
        self.until = until

    def _on_step(self) -> bool:
        return self.num_timesteps < self.until
