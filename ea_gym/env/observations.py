"""The observation of N systems, built beside its space, with its bounds named once.

Keys (E elements, C = R/C/I components, K = 1 + n classes, n maintainable components): ``ea`` (E,) J,
``eai`` (C,), ``residual`` (E,), ``time_since_maintenance`` (1,) s, ``maintenance_in_progress`` (1,),
and but for the "sensors" mode ``diagnosis`` (K,), ``parameter_estimate`` (n,) and ``rul`` (3,) s; in the
world where every part ages (``EnvConfig.concurrent_wear``, the v1 environments), ``degrading`` (n,),
``parameter_estimate`` (n,) and ``rul`` (n, 3) s per part instead.
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
        diagnosis_class: the true class of each system (N,): 0 none, else 1 + the faulty component (one fault
            per system); None where every part ages.
        rul: the true remaining useful life, s: (N,) of the one fault, or (N, n) of every part.
        degrading: where every part ages, whether each one's fault has arrived (N, n) bool; None otherwise.
    """

    values: np.ndarray
    diagnosis_class: np.ndarray | None
    rul: np.ndarray
    degrading: np.ndarray | None = None


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
        self.per_part = config.concurrent_wear  # every part ages: its own RUL and degrading probability
        self.idle = self._idle_outputs(nominal)
        self._none = np.empty((n_systems, 0))  # the "sensors" mode's diagnosis, estimates and RUL: no columns
        # each key's columns in the observation array, in the observation's order (``observation_rows``': the
        # per-part world's degrading probabilities in the diagnosis's place, its RUL rows side by side)
        E, C, n = len(elements), len(components), len(limits)
        widths = {"ea": E, "eai": C, "residual": E, "time_since_maintenance": 1, "maintenance_in_progress": 1}
        if config.obs_mode != "sensors":
            first = {"degrading": n} if self.per_part else {"diagnosis": len(classes)}
            widths |= first | {"parameter_estimate": n, "rul": 3 * n if self.per_part else 3}
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
            if self.per_part:
                keys["degrading"] = spaces.Box(0.0, 1.0, (n,), np.float32)
            else:
                keys["diagnosis"] = spaces.Box(0.0, 1.0, (K,), np.float32)
            keys["parameter_estimate"] = spaces.Box(*PARAMETER_POSITION_BOUNDS, (n,), np.float32)
            keys["rul"] = spaces.Box(0.0, config.rul_max, (n, 3) if self.per_part else (3,), np.float32)
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
        idle = {"ea": np.zeros((n, E)), "ea_reference": np.zeros((n, E)), "eai": np.full((n, C), 1.0 / C), "estimates": np.tile(nominal, (n, 1))}
        if self.per_part:
            return idle | {"degrading": np.zeros((n, len(nominal))), "rul": np.full((n, len(nominal), 3), np.inf)}
        diagnosis = np.zeros((n, len(self.classes)))
        diagnosis[:, 0] = 1.0
        return idle | {"diagnosis": diagnosis, "rul": np.full((n, 3), np.inf)}

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
            if oracle.degrading is not None:  # every part: its fault's arrival, its own RUL
                diagnosis = oracle.degrading.astype(float)
            else:
                diagnosis = np.zeros((self.n, len(self.classes)))
                diagnosis[np.arange(self.n), oracle.diagnosis_class] = 1.0
            values, rul = oracle.values, np.repeat(oracle.rul[..., None], 3, axis=-1)
        elif config.obs_mode == "phm":
            diagnosis = merged["degrading"] if self.per_part else merged["diagnosis"]
            values, rul = merged["estimates"], merged["rul"]
        else:
            diagnosis = values = rul = self._none
        # every key side by side in one float32 array, computed and clipped in one compiled pass; each key a view on it
        observation = np.empty((self.n, self._width), np.float32)
        observation_rows(
            merged["ea"], merged["ea_reference"], merged["eai"], since_maintenance, down, diagnosis, values, self._low, self._span,
            rul.reshape(self.n, -1), *self._bounds, observation,
        )
        keys = {key: observation[:, columns] for key, columns in self._columns}
        if self.per_part and "rul" in keys:  # each part's [point, low, high], a view on the same array
            keys["rul"] = keys["rul"].reshape(self.n, -1, 3)
        return keys
