"""The maintenance environment's step, over arrays of N systems (the single environment is N = 1).

One step: apply the maintenance actions, wear the components for ``step_seconds``, simulate the plant
and the fault-free reference model for ``window_seconds`` under each system's load, measure, run the
PHM chain (or only the monitor), then check failures and count costs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ea_gym.bondgraph.simulation import simulate_measured
from ea_gym.degradation import Wear, WearConfig
from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.diagnosis.database import classes_of
from ea_gym.diagnosis.monitor import Monitor
from ea_gym.energy import activity_index, window_samples
from ea_gym.env.costs import CostModel
from ea_gym.loads import multisine_rotations, rotated_multisine
from ea_gym.models import SystemModel
from ea_gym.phm import PHMChain, PHMConfig, calibrate_thresholds, classifier_for
from ea_gym.sensors import SystemNoise
from ea_gym.threads import single_threaded_blas

OBS_MODES = ("phm", "sensors", "oracle")
COST_ITEMS = ("corrective", "replacement", "failure", "lost_production", "total")
LOAD_COMPONENTS = 16


_THRESHOLDS: dict[tuple, np.ndarray] = {}
def _calibrated_thresholds(model: SystemModel, config: PHMConfig, seed: int) -> np.ndarray:
    """Detection thresholds, calibrated once per process for a model, chain settings and seed.

    The calibration is deterministic; without the cache, every one of a thousand single environments
    (in a SyncVectorEnv, say) would repeat it.
    """
    key = (model.name, model.parameter_vector().tobytes(), tuple(sorted(model.safe_limits.items())), config, seed)
    if key not in _THRESHOLDS:
        _THRESHOLDS[key] = calibrate_thresholds(model, config, np.random.default_rng(seed))
    return _THRESHOLDS[key].copy()


@dataclass(frozen=True)
class EnvConfig:
    """Everything that shapes an episode.

    Attributes:
        step_seconds: degradation time one step covers (s).
        window_seconds: measured operation per step (s); None: equal to ``step_seconds``.
        sample_rate: sensor sample rate (Hz).
        noise: sensor noise, fraction of each measured signal's RMS.
        horizon: steps before truncation.
        obs_mode: "phm", "sensors" or "oracle".
        costs: the cost model.
        wear: wearing components and how they wear; None: every parameter with safe limits, linear
            drift in a random direction.
        corrective_rate: speed of a corrective action, fraction of the safe range per s (the paper's
            corrective action restores the spring at 0.27 N/m/s, 1.35 % of its range per s).
        continue_after_failure: a failure forces a replacement with downtime instead of ending the episode.
        rul_max: RUL observations are clipped to [0, rul_max] (s).
        load_std: range of the random loads' std, fraction of the nominal load.
    """

    step_seconds: float = 1.0
    window_seconds: float | None = None
    sample_rate: float = 100.0
    noise: float = 0.01
    horizon: int = 500
    obs_mode: str = "phm"
    costs: CostModel = field(default_factory=CostModel)
    wear: dict[str, WearConfig] | None = None
    corrective_rate: float = 0.02
    continue_after_failure: bool = False
    rul_max: float = 1000.0
    load_std: tuple[float, float] = (0.2, 0.4)

    @property
    def window(self) -> float:
        return self.step_seconds if self.window_seconds is None else self.window_seconds


@dataclass(frozen=True)
class StepResult:
    """One step for N systems: observation arrays, rewards and the ground truth for ``info``."""

    observation: dict[str, np.ndarray]
    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    true_parameters: np.ndarray  # (N, P)
    true_rul: np.ndarray  # (N,)
    costs: dict[str, np.ndarray]  # per cost item, (N,)
    failed: np.ndarray
    events: list[list[str]]


class MaintenanceCore:
    """N degrading machines under maintenance, stepped together.

    Args:
        model: the machine.
        config: episode settings.
        n_systems: N.
        classifier: the isolation network (phm mode); None loads the one shipped for the model.
        calibration_seed: seed of the detector's fault-free calibration runs (fixed, so that an
            environment's behaviour depends only on its reset seeds).
    """

    def __init__(
        self,
        model: SystemModel,
        config: EnvConfig,
        n_systems: int = 1,
        classifier: FaultClassifier | None = None,
        calibration_seed: int = 0,
    ):
        if config.obs_mode not in OBS_MODES:
            raise ValueError(f"obs_mode must be one of {OBS_MODES}, got {config.obs_mode!r}")
        for name in ("step_seconds", "sample_rate", "corrective_rate", "rul_max"):
            value = getattr(config, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        if not (isinstance(config.noise, (int, float)) and 0 <= config.noise < 1):
            raise ValueError(f"noise must be in [0, 1), got {config.noise!r}")
        if not (isinstance(config.horizon, int) and config.horizon > 0):
            raise ValueError(f"horizon must be a positive int, got {config.horizon!r}")
        self.model = model
        self.config = config
        self.n = n_systems
        self.h = 1.0 / config.sample_rate
        self.samples = window_samples(config.window, self.h)
        self._window_grid = np.arange(self.samples + 1) * self.h
        self.components = classes_of(model)[1:]  # maintainable = degradable parameters
        self.classes = ("none", *self.components)
        wear = config.wear if config.wear is not None else {name: WearConfig() for name in self.components}
        unknown = sorted(set(wear) - set(self.components))
        if unknown:
            raise ValueError(f"wear: unknown components {unknown}; maintainable components are {list(self.components)}")
        self.nominal = model.parameter_vector()
        self._component_index = np.array([model.parameter_names.index(c) for c in self.components])
        self.limits = np.array([model.safe_limits[c] for c in self.components])
        wearing = [c for c in self.components if c in wear]
        self._wearing_index = np.array([model.parameter_names.index(c) for c in wearing])
        self.wear = Wear(
            self.nominal[self._wearing_index], np.array([model.safe_limits[c] for c in wearing]), [wear[c] for c in wearing], n_systems
        )
        self.chain: PHMChain | None = None
        if config.obs_mode == "phm":
            if classifier is None:
                classifier = classifier_for(model, np.random.default_rng(calibration_seed))
            phm_config = PHMConfig(step=config.window, step_time=config.step_seconds, sample_rate=config.sample_rate, noise=config.noise)
            thresholds = _calibrated_thresholds(model, phm_config, calibration_seed)
            self.chain = PHMChain(model, classifier, thresholds, phm_config, n_systems)
        self.monitor = self.chain.monitor if self.chain is not None else Monitor(model, self.h, PHMConfig().monitor, n_systems)
        self.elements = self.monitor.elements
        self.rco = self.monitor.components
        self._corrective_speed = config.corrective_rate * (self.limits[:, 1] - self.limits[:, 0])
        self._corrective_events = tuple(f"corrective action on {c}" for c in self.components)
        self.action_meanings = ("carry on", *self._corrective_events, *(f"replace {c}" for c in self.components))
        self.nominal_parameters = dict(zip(model.parameter_names, map(float, self.nominal)))
        self.safe_limits = {name: tuple(map(float, limits)) for name, limits in model.safe_limits.items()}
        self._state: dict[str, np.ndarray] = {}
        self._idle = self._idle_outputs()
        self.sensor_noise = SystemNoise(config.noise)

    # -- episode bookkeeping ------------------------------------------------------------------

    def reset(self, rngs: Sequence[np.random.Generator], systems: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Start new episodes (all systems, or those in the boolean mask); returns the first observation.

        System i draws only from ``rngs[i]``, here and in ``step``: its episode is the same whether it
        is stepped alone or with others.
        """
        n, nx = self.n, len(self.model.state_names)
        mask = np.ones(n, dtype=bool) if systems is None else np.asarray(systems, dtype=bool)
        if systems is None or not self._state:
            self._state = {
                "theta": np.tile(self.nominal, (n, 1)),
                "plant": np.zeros((n, nx)),
                "reference": np.zeros((n, nx)),
                "clock": np.zeros(n),
                "operation": np.zeros(n),
                "steps": np.zeros(n, dtype=int),
                "down": np.zeros(n, dtype=int),
                "since_maintenance": np.zeros(n),
                "corrective_direction": np.zeros((n, len(self.components))),
                "load_mean": np.zeros(n),
                "load_amplitude": np.zeros(n),
                "load_frequency": np.zeros((n, LOAD_COMPONENTS)),
                "load_phase": np.zeros((n, LOAD_COMPONENTS)),
                "load_rotation": np.zeros((n, 3, LOAD_COMPONENTS)),  # of the frequencies, kept for the episode
            }
        s = self._state
        for key in ("plant", "reference", "clock", "operation", "since_maintenance", "corrective_direction"):
            s[key][mask] = 0.0
        s["theta"][mask] = self.nominal
        s["steps"][mask] = 0
        s["down"][mask] = 0
        self._draw_loads(rngs, mask)
        self.wear.start(rngs, s["clock"], mask)
        if self.chain is not None:
            self.chain.reset(mask)
        else:
            self.monitor.reset(mask if systems is not None else None)
        return self._observe(self._idle)

    def _draw_loads(self, rngs: Sequence[np.random.Generator], mask: np.ndarray) -> None:
        s = self._state
        model = self.model
        for i in np.flatnonzero(mask):
            rng = rngs[i]
            std = model.nominal_load * rng.uniform(*self.config.load_std)
            s["load_mean"][i] = model.nominal_load
            s["load_amplitude"][i] = std * math.sqrt(2.0 / LOAD_COMPONENTS)
            s["load_frequency"][i] = model.excitation_bandwidth - rng.uniform(0.0, model.excitation_bandwidth, LOAD_COMPONENTS)
            s["load_phase"][i] = rng.uniform(0.0, 2.0 * math.pi, LOAD_COMPONENTS)
        s["load_rotation"][mask] = multisine_rotations(s["load_frequency"][mask], self.h)

    def _load(self, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each system's load and its derivative over one window from its time ``start`` (N,), on the
        sample grid: random-phase multisines, (N, samples + 1)."""
        s = self._state
        t = start[:, None] + self._window_grid
        waves, slopes = rotated_multisine(t, s["load_phase"], s["load_rotation"])
        amplitude = s["load_amplitude"][:, None]
        return s["load_mean"][:, None] + amplitude * waves, amplitude * slopes

    # -- the step ---------------------------------------------------------------------------------

    def step(self, actions: np.ndarray, rngs: Sequence[np.random.Generator]) -> StepResult:
        """Advance every system by one step under ``actions`` (N,) in [0, 2 n_components]."""
        # small arrays throughout: one BLAS thread, which also leaves the other core to the learner's torch
        with single_threaded_blas():
            return self._step(actions, rngs)

    def _step(self, actions: np.ndarray, rngs: Sequence[np.random.Generator]) -> StepResult:
        actions = np.asarray(actions)
        n_actions = 1 + 2 * len(self.components)
        if actions.shape != (self.n,) or not np.issubdtype(actions.dtype, np.integer) or np.any((actions < 0) | (actions >= n_actions)):
            raise ValueError(f"actions must be {self.n} integers in [0, {n_actions - 1}], got {actions!r}")
        s, c, dt = self._state, self.config.costs, self.config.step_seconds
        costs = {key: np.zeros(self.n) for key in COST_ITEMS[:-1]}
        events: list[list[str]] = [[] for _ in range(self.n)]
        down = s["down"] > 0
        actions = np.where(down, 0, actions)  # a machine under replacement takes no orders

        k = len(self.components)
        corrective = (actions >= 1) & (actions <= k)
        replace = actions > k
        rows = np.flatnonzero(corrective)
        if len(rows):
            d = actions[rows] - 1
            j = self._component_index[d]
            direction = s["corrective_direction"]
            new = direction[rows, d] == 0  # a new corrective action heads for nominal
            heading = np.sign(self.nominal[j[new]] - s["theta"][rows[new], j[new]])
            direction[rows[new]] = 0.0
            direction[rows[new], d[new]] = np.where(heading == 0, 1.0, heading)
            change = direction[rows, d] * self._corrective_speed[d] * dt
            s["theta"][rows, j] += change
            if self.chain is not None:  # the maintenance log: the chain's prognosis knows what was done
                self.chain.record_adjustment(rows, d, change)
            costs["corrective"][rows] += c.corrective
            for i, component in zip(rows, d):
                events[i].append(self._corrective_events[component])
        s["corrective_direction"][~corrective] = 0.0
        replaced = np.flatnonzero(replace)
        self._replace(replaced, actions[replaced] - 1 - k, c.replace_downtime, rngs, events)
        costs["replacement"][replaced] += c.replacement

        running = s["down"] == 0
        wearing = s["theta"][:, self._wearing_index]
        worn = self.wear.advance(wearing, s["clock"], dt, rngs)
        s["theta"][:, self._wearing_index] = np.where(running[:, None], worn, wearing)
        s["clock"] = s["clock"] + dt

        outputs = self._operate(rngs)
        low, high = self.limits[:, 0], self.limits[:, 1]
        values = s["theta"][:, self._component_index]
        failed = running & np.any((values < low) | (values > high), axis=1)
        broken = np.flatnonzero(failed)
        costs["failure"][broken] += c.failure
        culprits = np.argmax(np.maximum(low - values[broken], values[broken] - high), axis=1)
        for i, d in zip(broken, culprits):
            events[i].append(f"failure: {self.components[d]} = {values[i, d]:.4g} outside {tuple(self.limits[d])}")
        if self.config.continue_after_failure:
            self._replace(broken, culprits, c.failure_downtime, rngs, events)
        costs["lost_production"] += np.where(s["down"] > 0, c.lost_production, 0.0)
        s["down"] = np.maximum(s["down"] - 1, 0)
        s["since_maintenance"] = np.where(corrective | replace | failed, 0.0, s["since_maintenance"] + dt)
        s["steps"] = s["steps"] + 1

        terminated = failed & (not self.config.continue_after_failure)
        truncated = (s["steps"] >= self.config.horizon) & ~terminated
        total = sum(costs.values())
        costs["total"] = total
        observation = self._observe(outputs)
        return StepResult(
            observation=observation,
            reward=-total,
            terminated=terminated,
            truncated=truncated,
            true_parameters=s["theta"].copy(),
            true_rul=self._true_rul(),
            costs=costs,
            failed=failed,
            events=events,
        )

    def info(self, result: StepResult, i: int) -> dict[str, Any]:
        """The Gymnasium ``info`` of system i after a step."""
        return {
            "true_parameters": dict(zip(self.model.parameter_names, map(float, result.true_parameters[i]))),
            "true_rul": float(result.true_rul[i]),
            "cost": {key: float(value[i]) for key, value in result.costs.items()},
            "failed": bool(result.failed[i]),
            "events": list(result.events[i]),
        }

    def reset_info(self, i: int) -> dict[str, Any]:
        """The Gymnasium ``info`` of system i after a reset: its true state, no cost, no event."""
        return {
            "true_parameters": dict(zip(self.model.parameter_names, map(float, self._state["theta"][i]))),
            "true_rul": float(self._true_rul()[i]),
            "cost": {key: 0.0 for key in COST_ITEMS},
            "failed": False,
            "events": [],
        }

    def _replace(
        self, systems: np.ndarray, components: np.ndarray, downtime: int, rngs: Sequence[np.random.Generator], events: list[list[str]]
    ) -> None:
        """Put a new component ``components[k]`` in system ``systems[k]`` (distinct systems): nominal value,
        downtime, a new fault where it was the faulty one.

        The systems are reset together; each draws only from its own generator, as when replaced one by one.
        """
        if len(systems) == 0:
            return
        s = self._state
        components = np.asarray(components, dtype=int)
        parameters = self._component_index[components]
        s["theta"][systems, parameters] = self.nominal[parameters]
        s["down"][systems] = downtime
        s["plant"][systems] = 0.0  # the machine is stopped and restarted
        s["reference"][systems] = 0.0
        mask = np.zeros(self.n, dtype=bool)
        mask[systems] = True
        # the faulty one: a new fault is drawn
        faulty = self._wearing_index[self.wear.faulty[systems]] == parameters
        if np.any(faulty):
            fresh = np.zeros(self.n, dtype=bool)
            fresh[systems[faulty]] = True
            self.wear.start(rngs, s["clock"], fresh)
        if self.chain is not None:
            self.chain.reset(mask)
        else:
            self.monitor.reset(mask)
        for i, d in zip(systems, components):
            events[i].append(f"replacement of {self.components[d]} ({downtime} steps down)")

    @property
    def wear_components(self) -> tuple[str, ...]:
        return tuple(self.model.parameter_names[j] for j in self._wearing_index)

    def _operate(self, rngs: Sequence[np.random.Generator]) -> dict[str, np.ndarray]:
        """Simulate one window of plant and reference, measure, and run the chain or the monitor."""
        s = self._state
        u, du = self._load(s["operation"])
        n = self.n
        # plant and reference in one batch (the reference rows, and healthy plants, share one discretization)
        theta = np.concatenate([s["theta"], np.broadcast_to(self.nominal, s["theta"].shape)])
        loads = np.concatenate([u, u])[..., None]
        rates = np.concatenate([du, du])[..., None]
        # the measurement matrices are diagonal: a product per state equals the matrix product exactly
        gain = self.monitor.measurement_gain(theta)
        x0 = np.concatenate([s["plant"], s["reference"]])
        signals, last = simulate_measured(self.model.state_space, self.h, loads, rates, theta, x0, gain)
        s["plant"], s["reference"] = last[:n], last[n:]
        s["operation"] = s["operation"] + self.config.window
        measured = self.sensor_noise(signals[:n], rngs)
        expected = signals[n:]
        if self.chain is not None:
            status = self.chain.update(measured, expected, u, du)
            return {
                "ea": status.ea, "ea_reference": status.ea_reference, "eai": status.eai,
                "diagnosis": status.diagnosis, "estimates": status.estimates, "rul": status.rul,
            }
        window = self.monitor.update(measured, expected, u)
        ea, ea_ref = window.ea.sum(-1), window.ea_reference.sum(-1)
        components = np.array([self.elements.index(c) for c in self.rco])
        eai = np.stack(list(activity_index(dict(enumerate(ea[:, components].T))).values()), axis=1)
        return {"ea": ea, "ea_reference": ea_ref, "eai": eai}

    def _idle_outputs(self) -> dict[str, np.ndarray]:
        """Outputs before the first step (or while a machine is down): no activity, nothing known.

        Built once (``self._idle``) and only read: every observation is a fresh array.
        """
        n, E, C = self.n, len(self.elements), len(self.rco)
        diagnosis = np.zeros((n, len(self.classes)))
        diagnosis[:, 0] = 1.0
        return {
            "ea": np.zeros((n, E)), "ea_reference": np.zeros((n, E)), "eai": np.full((n, C), 1.0 / C),
            "diagnosis": diagnosis, "estimates": np.tile(self.nominal[self._component_index], (n, 1)),
            "rul": np.full((n, 3), np.inf),
        }

    def _true_rul(self) -> np.ndarray:
        s = self._state
        return self.wear.true_rul(s["theta"][:, self._wearing_index], s["clock"])

    def _observe(self, outputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Observation arrays; systems that are down show idle outputs."""
        s = self._state
        idle = self._idle
        down = s["down"] > 0
        if down.any():
            merged = {key: np.where(down.reshape((-1,) + (1,) * (idle[key].ndim - 1)), idle[key], outputs.get(key, idle[key])) for key in idle}
        else:
            merged = {**idle, **outputs}
        residual = (merged["ea"] - merged["ea_reference"]) / np.maximum(merged["ea_reference"], 1e-12)
        obs = {
            "ea": merged["ea"],
            "eai": merged["eai"],
            "residual": residual,
            "time_since_maintenance": s["since_maintenance"][:, None],
            "maintenance_in_progress": (s["down"] > 0).astype(float)[:, None],
        }
        if self.config.obs_mode == "oracle":
            true = s["theta"][:, self._component_index]
            diagnosis = np.zeros((self.n, len(self.classes)))
            arrived = s["clock"] >= self.wear.arrival
            faulty = np.array([self.components.index(self.wear_components[d]) + 1 for d in self.wear.faulty])
            diagnosis[np.arange(self.n), np.where(arrived, faulty, 0)] = 1.0
            obs["diagnosis"] = diagnosis
            obs["parameter_estimate"] = self._health_coordinate(true)
            obs["rul"] = np.repeat(self._true_rul()[:, None], 3, axis=1)
        elif self.config.obs_mode == "phm":
            obs["diagnosis"] = merged["diagnosis"]
            obs["parameter_estimate"] = self._health_coordinate(merged["estimates"])
            obs["rul"] = merged["rul"]
        if "rul" in obs:
            obs["rul"] = np.clip(np.nan_to_num(obs["rul"], nan=self.config.rul_max, posinf=self.config.rul_max), 0.0, self.config.rul_max)
        obs["time_since_maintenance"] = np.minimum(obs["time_since_maintenance"], self.config.horizon * self.config.step_seconds)
        return {key: np.clip(value, -1e6, 1e6).astype(np.float32) for key, value in obs.items()}

    def _health_coordinate(self, values: np.ndarray) -> np.ndarray:
        """Position of each maintainable parameter in its safe range: 0 at the lower limit, 1 at the upper."""
        low, high = self.limits[:, 0], self.limits[:, 1]
        return np.clip((values - low) / (high - low), -1.0, 2.0)
