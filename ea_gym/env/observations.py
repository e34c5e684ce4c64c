"""The observation of N systems, built beside its space, with its bounds named once.

Keys (E elements, C = R/C/I components, K = 1 + n classes, n maintainable components): ``ea`` (E,) J,
``eai`` (C,), ``residual`` (E,), ``time_since_maintenance`` (1,) s, ``maintenance_in_progress`` (1,),
and but for the "sensors" mode ``diagnosis`` (K,), ``parameter_estimate`` (n,) and ``rul`` (3,) s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from ea_gym._kernels.observation import observation_rows
from ea_gym.env.config import EnvConfig

OBSERVATION_BOUND = 1e6  # every value is clipped to +-OBSERVATION_BOUND (float32-safe; EA in J)
PARAMETER_POSITION_BOUNDS = (-1.0, 2.0)  # a parameter's position in its safe range: 0 lower limit, 1 upper
RESIDUAL_FLOOR = 1e-12  # J: the reference EA below which the relative residual's denominator stops

Observation = dict[str, np.ndarray]  # one system's (or, batched, N systems') observation by key


@dataclass(frozen=True)
class OracleTruth:
    """What the "oracle" mode shows of N systems.

    Attributes:
        values: the maintainable parameters' true values (N, n).
        diagnosis_class: the true class of each system (N,): 0 none, else 1 + the faulty component.
        rul: the true remaining useful life (N,), s.
    """

    values: np.ndarray
    diagnosis_class: np.ndarray
    rul: np.ndarray


class Observer:
    """Builds the observations of N systems from the step's outputs, and their space.

    Args:
        config: the environment's settings (obs_mode, rul_max, horizon, step_seconds).
        n_systems: N.
        elements: the bond-graph elements whose EA is observed (E).
        components: the R/C/I components with an EAI (C).
        classes: the diagnosis classes (K): "none", then the maintainable components.
        limits: the maintainable parameters' safe limits (n, 2).
        nominal: the maintainable parameters' nominal values (n,).
    """

    def __init__(
        self, config: EnvConfig, n_systems: int, elements: tuple[str, ...], components: tuple[str, ...], classes: tuple[str, ...],
        limits: np.ndarray, nominal: np.ndarray,
    ):
        self.config = config
        self.n = n_systems
        self.elements, self.components, self.classes = elements, components, classes
        self.limits = limits
        self._low, self._span = limits[:, 0].copy(), limits[:, 1] - limits[:, 0]
        self.idle = self._idle_outputs(nominal)
        self._none = np.empty((n_systems, 0))  # the "sensors" mode's diagnosis, estimates and RUL: no columns
        # each key's columns in the observation array, in the observation's order (``observation_rows``')
        E, C = len(elements), len(components)
        widths = {"ea": E, "eai": C, "residual": E, "time_since_maintenance": 1, "maintenance_in_progress": 1}
        if config.obs_mode != "sensors":
            widths |= {"diagnosis": len(classes), "parameter_estimate": len(limits), "rul": 3}
        ends = np.cumsum(list(widths.values())).tolist()
        self._columns = [(key, slice(end - width, end)) for (key, width), end in zip(widths.items(), ends)]
        self._width = ends[-1]
        # the kernel's bounds: the RUL's and the time since maintenance's, the residual's floor, the positions', every value's
        self._bounds = (float(config.rul_max), float(self.longest_run), RESIDUAL_FLOOR, *PARAMETER_POSITION_BOUNDS, OBSERVATION_BOUND)

    def space(self) -> spaces.Dict:
        """The Dict observation space of one system."""
        E, C, K, n = len(self.elements), len(self.components), len(self.classes), len(self.limits)
        config = self.config
        keys: dict[str, spaces.Space[Any]] = {
            "ea": spaces.Box(0.0, OBSERVATION_BOUND, (E,), np.float32),
            "eai": spaces.Box(0.0, 1.0, (C,), np.float32),
            "residual": spaces.Box(-OBSERVATION_BOUND, OBSERVATION_BOUND, (E,), np.float32),
            "time_since_maintenance": spaces.Box(0.0, self.longest_run, (1,), np.float32),
            "maintenance_in_progress": spaces.Box(0.0, 1.0, (1,), np.float32),
        }
        if config.obs_mode != "sensors":
            keys["diagnosis"] = spaces.Box(0.0, 1.0, (K,), np.float32)
            keys["parameter_estimate"] = spaces.Box(*PARAMETER_POSITION_BOUNDS, (n,), np.float32)
            keys["rul"] = spaces.Box(0.0, config.rul_max, (3,), np.float32)
        return spaces.Dict(keys)

    @property
    def longest_run(self) -> float:
        """The longest time since maintenance an episode can show (s)."""
        return self.config.horizon * self.config.step_seconds

    def _idle_outputs(self, nominal: np.ndarray) -> dict[str, np.ndarray]:
        """Outputs before the first step (or while a machine is down): no activity, nothing known.

        Built once (``self.idle``) and only read: every observation is a fresh array.
        """
        n, E, C = self.n, len(self.elements), len(self.components)
        diagnosis = np.zeros((n, len(self.classes)))
        diagnosis[:, 0] = 1.0
        return {
            "ea": np.zeros((n, E)), "ea_reference": np.zeros((n, E)), "eai": np.full((n, C), 1.0 / C),
            "diagnosis": diagnosis, "estimates": np.tile(nominal, (n, 1)),
            "rul": np.full((n, 3), np.inf),
        }

    def observe(
        self, outputs: dict[str, np.ndarray], since_maintenance: np.ndarray, down: np.ndarray, oracle: OracleTruth | None
    ) -> Observation:
        """Observation arrays (float32) of the step's ``outputs``; systems ``down`` (N,) show idle outputs.

        ``since_maintenance`` (N,) in s; ``oracle`` is needed in the "oracle" mode only.
        """
        idle = self.idle
        if down.any():
            merged = {key: np.where(down.reshape((-1,) + (1,) * (idle[key].ndim - 1)), idle[key], outputs.get(key, idle[key])) for key in idle}
        else:
            merged = {**idle, **outputs}
        config = self.config
        if config.obs_mode == "oracle":
            if oracle is None:
                raise ValueError("the oracle mode observes the truth: oracle must be given")
            diagnosis = np.zeros((self.n, len(self.classes)))
            diagnosis[np.arange(self.n), oracle.diagnosis_class] = 1.0
            values, rul = oracle.values, np.repeat(oracle.rul[:, None], 3, axis=1)
        elif config.obs_mode == "phm":
            diagnosis, values, rul = merged["diagnosis"], merged["estimates"], merged["rul"]
        else:
            diagnosis = values = rul = self._none
        # every key side by side in one float32 array, computed and clipped in one compiled pass; each key a view on it
        observation = np.empty((self.n, self._width), np.float32)
        observation_rows(
            merged["ea"], merged["ea_reference"], merged["eai"], since_maintenance, down, diagnosis, values, self._low, self._span, rul,
            *self._bounds, observation,
        )
        return {key: observation[:, columns] for key, columns in self._columns}
