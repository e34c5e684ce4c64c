"""The maintenance cost model: every number the environment's reward is made of."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass


@dataclass(frozen=True)
class CostModel:
    """Costs in one monetary unit; the reward of a step is minus their sum.

    Attributes:
        corrective: per step of corrective action on a component.
        replacement: per component replacement (parts and labour).
        failure: when a parameter leaves its safe limits.
        lost_production: per step the machine is down (replacement or failure downtime).
        replace_downtime: steps a replacement keeps the machine down.
        failure_downtime: steps a failure keeps the machine down (repair, then a new component).
    """

    corrective: float = 1.0
    replacement: float = 40.0
    failure: float = 400.0
    lost_production: float = 4.0
    replace_downtime: int = 3
    failure_downtime: int = 20

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"cost model: {name} must be finite and >= 0, got {value!r}")
        for name in ("replace_downtime", "failure_downtime"):
            if int(getattr(self, name)) != getattr(self, name):
                raise ValueError(f"cost model: {name} must be a whole number of steps, got {getattr(self, name)!r}")
