"""Potential-based reward shaping with the components' true wear, for training only.

The environment charges a failure at once, 400 on one step, while what causes it, a part wearing
toward its limit, and what prevents it, a corrective step or a replacement, come tens of steps earlier.
A learner then sees a maintenance step cost 1 or 52 now and its benefit as a small shift of a rare
-400 somewhere ahead, buried in the noise of every other episode's failures.

``WearShaping`` adds F = gamma * Phi(s') - Phi(s) to every training reward, with the potential

    Phi(s) = -failure_cost * sum over components of clip((wear - onset) / (1 - onset), 0, 1),

the wear a component's true way from nominal to the safe limit on its side (0 at nominal, 1 at the
limit). A part wearing past the onset toward its limit is charged the failure's cost as it wears, a
step that brings it back is credited at once, and a failure's -400 is offset by the wear it ends.
Shaping of this form changes no policy's ranking (Ng, Harada and Russell, 1999: the shaped discounted
return is the original one minus Phi of the first state), so the best policy stays the best for the
environment's own cost. The potential reads the true parameters from the step's info (the simulator's
state, which the policy never sees); validation and evaluation use the environment's own rewards.

Why an onset (``agents.training.TrainingRun``'s default 0.3): wear far from the limit can still be
corrected in time, and the best policies leave it alone (the oracle corrects at 2 s of RUL). Charged
from nominal on (onset 0), every corrective step on a worn part is credited 10 to 30 times its cost
wherever the part is, and a learner corrected from the first sign of wear on, in runs of consecutive
steps. A corrective action keeps its direction while it is continued, so such runs carried the part
through nominal to its other limit: 61 of that learner's 75 failures came on a step of corrective action
(``experiments/results/from_scratch``). Charged from the onset on, a corrective step pays only where the
part is nearer its limit.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

__all__ = ["WearShaping", "true_wear"]


def true_wear(parameters: dict[str, float], nominal: dict[str, float], limits: dict[str, tuple[float, float]]) -> np.ndarray:
    """Each component's way from its nominal value to the safe limit on its side, clipped to [0, 1]."""
    wear = []
    for name, (low, high) in limits.items():
        value, centre = parameters[name], nominal[name]
        wear.append((centre - value) / (centre - low) if value < centre else (value - centre) / (high - centre))
    return np.clip(np.array(wear), 0.0, 1.0)


class WearShaping(VecEnvWrapper):
    """Adds gamma * Phi(s') - Phi(s) to the rewards, Phi = -scale * sum of the true wear past ``onset``,
    rescaled to [0, 1] (see the module).

    Args:
        venv: the maintenance VecEnv (infos with ``true_parameters``; ``nominal_parameters`` and ``safe_limits``).
        gamma: the learner's discount (the shaping keeps the best policy only with the same one).
        scale: the potential at one component's limit, in the cost model's unit (the failure cost).
        onset: the wear in [0, 1) from which the potential falls (0: from nominal on).
    """

    def __init__(self, venv: VecEnv, gamma: float, scale: float, onset: float = 0.0):
        if not (isinstance(onset, (int, float)) and 0.0 <= onset < 1.0):
            raise ValueError(f"shaping onset must be a wear in [0, 1), got {onset!r}")
        super().__init__(venv)
        self.gamma, self.scale, self.onset = float(gamma), float(scale), float(onset)
        self.nominal = venv.get_attr("nominal_parameters")[0]
        self.limits = venv.get_attr("safe_limits")[0]
        self.potential = np.zeros(venv.num_envs)

    def _potential(self, info: dict[str, Any]) -> float:
        wear = true_wear(info["true_parameters"], self.nominal, self.limits)
        return -self.scale * float(np.clip((wear - self.onset) / (1.0 - self.onset), 0.0, 1.0).sum())

    def reset(self) -> Any:
        self.potential = np.zeros(self.num_envs)  # every episode starts with its components at nominal
        return self.venv.reset()

    def step_wait(self) -> Any:
        observation, rewards, dones, infos = self.venv.step_wait()
        after = np.array([self._potential(info) for info in infos])  # an ended episode's last state
        shaped = rewards + self.gamma * after - self.potential
        self.potential = np.where(dones, 0.0, after)
        return observation, shaped.astype(np.float32), dones, infos
