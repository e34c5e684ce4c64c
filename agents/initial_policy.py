"""The action distribution a new policy starts from, before any learning.

stable-baselines3 initialises the action head with tiny weights, so a new policy picks the seven actions
of the spring-mass-damper uniformly: it maintains 6 steps in 7 and replaces a part 3 steps in 7 (each
replacement 40 plus 3 steps down at 4), an episode costing thousands where running to failure costs
about 1,070. Every early rollout then says "maintenance is ruinous", and the learner settles for never
maintaining before it has seen a maintenance action that prevents a failure.

A maintenance policy carries on at almost every step. So a new policy here carries on with probability
``carry_on``, and the maintenance actions share the rest in inverse proportion to their immediate cost
(a corrective step ``costs.corrective``; a replacement ``costs.replacement`` plus its downtime's lost
production): with the default costs and ``carry_on`` 0.8 (``agents.training.TrainingRun``), each
corrective action 0.065 and each replacement 0.0013. The learner tries the cheap actions often enough
to find where they pay, and the expensive ones rarely. At 0.9 (each corrective action 0.033) a
corrective action's logit had 3.3 nats to climb before the deterministic policy took it, and learners
took longer to leave running to failure (``experiments/results/from_scratch``). Only the action head's
bias is set: its weights stay tiny, so every state starts from this distribution.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import torch
from stable_baselines3.common.policies import ActorCriticPolicy

from ea_gym.env.costs import CostModel
from ea_gym.env.events import parse_action

__all__ = ["immediate_costs", "initial_probabilities", "start_from"]


def immediate_costs(action_meanings: Sequence[str], costs: CostModel) -> np.ndarray:
    """Each action's cost on the step it is taken (carrying on 0), in the cost model's unit: its kind's
    price and its downtime's lost production."""
    return np.array([parse_action(meaning).kind.immediate_cost(costs) for meaning in action_meanings])


def initial_probabilities(action_meanings: Sequence[str], costs: CostModel, carry_on: float) -> np.ndarray:
    """Carry on (action 0) with probability ``carry_on``; the maintenance actions share the rest in
    inverse proportion to their immediate cost (equally where every one is free)."""
    if not (isinstance(carry_on, (int, float)) and 0.0 < carry_on < 1.0):
        raise ValueError(f"initial_carry_on must be a probability in (0, 1), got {carry_on!r}")
    maintenance = immediate_costs(action_meanings, costs)[1:]
    if len(maintenance) == 0:
        raise ValueError("the environment has no maintenance action to share the rest of the probability")
    free = maintenance == 0
    weights = free.astype(float) if free.any() else 1.0 / maintenance
    return np.concatenate([[carry_on], (1.0 - carry_on) * weights / weights.sum()])


def start_from(policy: ActorCriticPolicy, probabilities: np.ndarray) -> None:
    """Set the action head's bias to the logits of ``probabilities`` (a categorical action distribution)."""
    head = policy.action_net
    if not isinstance(head, torch.nn.Linear) or head.out_features != len(probabilities):
        raise ValueError(f"expected a linear action head with {len(probabilities)} outputs, got {head}")
    with torch.no_grad():
        head.bias.copy_(torch.as_tensor([math.log(p) if p > 0 else -30.0 for p in probabilities], dtype=head.bias.dtype))
