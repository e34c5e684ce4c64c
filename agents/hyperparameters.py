"""The hyperparameters a training run or an agent file may set, per algorithm, with the values each takes.

stable-baselines3 takes its constructor's keyword arguments as they come: ``learning_rate: "fast"`` fails
at the first update, ``_init_setup_model: false`` makes a model without a policy, a negative ``n_steps``
fails deep in numpy. ``check_hyperparameters`` refuses such a setting first, naming it. Only plain
numbers and switches are settable: the objects a run supplies itself (policy, environment, logs, device,
seed, buffers' classes) are not hyperparameters.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["Setting", "HYPERPARAMETERS", "check_hyperparameters"]


@dataclass(frozen=True)
class Setting:
    """The values one hyperparameter takes: ``kind`` "int", "number" or "bool"; numbers in [low, high] (low excluded
    when ``above_low``); ``optional``: null too (stable-baselines3's None, the feature off)."""

    kind: str
    low: float = -math.inf
    high: float = math.inf
    above_low: bool = False
    optional: bool = False

    def accepts(self, value: Any) -> bool:
        if value is None:
            return self.optional
        if self.kind == "bool":
            return isinstance(value, bool)
        numeric = int if self.kind == "int" else (int, float)
        if isinstance(value, bool) or not isinstance(value, numeric) or not math.isfinite(value):
            return False
        return (value > self.low if self.above_low else value >= self.low) and value <= self.high

    def expected(self) -> str:
        if self.kind == "bool":
            text = "true or false"
        else:
            noun = "an integer" if self.kind == "int" else "a finite number"
            if self.high < math.inf:
                text = f"{noun} in {'(' if self.above_low else '['}{self.low:g}, {self.high:g}]"
            else:
                text = f"{noun} {'>' if self.above_low else '>='} {self.low:g}"
        return f"{text} or null" if self.optional else text


_POSITIVE_INT = Setting("int", 1)
_POSITIVE = Setting("number", 0, above_low=True)
_NON_NEGATIVE = Setting("number", 0)
_FRACTION = Setting("number", 0, 1)
_SWITCH = Setting("bool")

_COMMON = {"learning_rate": _POSITIVE, "gamma": _FRACTION, "max_grad_norm": _POSITIVE, "stats_window_size": _POSITIVE_INT}
_ON_POLICY = {**_COMMON, "n_steps": _POSITIVE_INT, "gae_lambda": _FRACTION, "ent_coef": _NON_NEGATIVE, "vf_coef": _NON_NEGATIVE,
              "normalize_advantage": _SWITCH}

#: per algorithm (``agents.agent_files.ALGORITHMS``' names), the hyperparameters that may be set and their values
HYPERPARAMETERS: dict[str, dict[str, Setting]] = {
    "ppo": {**_ON_POLICY, "batch_size": _POSITIVE_INT, "n_epochs": _POSITIVE_INT, "clip_range": _POSITIVE,
            "clip_range_vf": Setting("number", 0, above_low=True, optional=True), "target_kl": Setting("number", 0, above_low=True, optional=True)},
    "a2c": {**_ON_POLICY, "rms_prop_eps": _POSITIVE, "use_rms_prop": _SWITCH},
    "dqn": {**_COMMON, "buffer_size": _POSITIVE_INT, "learning_starts": Setting("int", 0), "batch_size": _POSITIVE_INT,
            "tau": Setting("number", 0, 1, above_low=True), "train_freq": _POSITIVE_INT, "gradient_steps": Setting("int", -1),
            "n_steps": _POSITIVE_INT, "target_update_interval": _POSITIVE_INT, "exploration_fraction": _FRACTION,
            "exploration_initial_eps": _FRACTION, "exploration_final_eps": _FRACTION, "optimize_memory_usage": _SWITCH},
}


def check_hyperparameters(algorithm: str, hyperparameters: Mapping[str, Any], where: str) -> None:
    """Refuse a hyperparameter ``algorithm`` does not take from a file, or a value it cannot use: ValueError
    ``<where>.<name> ...`` naming it and what was expected."""
    settings = HYPERPARAMETERS[algorithm]
    for name, value in hyperparameters.items():
        if name not in settings:
            raise ValueError(f"{where}.{name} is not a hyperparameter {algorithm} takes from a file; expected some of {sorted(settings)}")
        if not settings[name].accepts(value):
            raise ValueError(f"{where}.{name} must be {settings[name].expected()}, got {value!r}")
