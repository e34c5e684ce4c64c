"""The maintenance environment's step, over arrays of N systems (the single environment is N = 1).

One step: apply the maintenance actions, wear the components for ``step_seconds``, simulate the plant
and the fault-free reference model for ``window_seconds`` under each system's load, measure, run the
PHM chain (or only the monitor), then check failures and count costs. ``MaintenanceCore`` composes
the rooms that do it: ``operation`` (loads, plant, sensors, wear), ``actions`` (what each kind of
action does), ``events`` (actions and events as values), ``observations`` and ``infos``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ea_gym._kernels.ledger import close_step, outside_limits, take_orders
from ea_gym.degradation import PartsWear, Wear, WearConfig
from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.diagnosis.database import classes_of
from ea_gym.diagnosis.monitor import Monitor
from ea_gym.energy import component_activity_index
from ea_gym.env.actions import DEFAULT_ACTION_KINDS, HandlerFactory, Orders
from ea_gym.env.config import EnvConfig
from ea_gym.env.events import ActionKind, Event, Failure, Replacement, action_table
from ea_gym.env.infos import StepInfo, cost_items
from ea_gym.env.observations import Observation, Observer, OracleTruth
from ea_gym.env.operation import Degradation, Operation, PartsDegradation
from ea_gym.models import SystemModel
from ea_gym.phm import HealthStatus, PHMChain, PHMConfig, classifier_for, commission, thresholds_for
from ea_gym.threads import single_threaded_blas


@dataclass(frozen=True)
class StepResult:
    """One step for N systems: observation arrays, rewards, ends, and what the ``info`` reports."""

    observation: Observation
    reward: np.ndarray  # (N,)
    terminated: np.ndarray  # (N,)
    truncated: np.ndarray  # (N,)
    info: StepInfo


class MaintenanceCore:
    """N degrading machines under maintenance, stepped together.

    Args:
        model: the machine.
        config: episode settings.
        n_systems: N.
        classifier: the isolation network (phm mode); None loads the one shipped for the model.
        calibration_seed: seed of the detector's fault-free calibration runs (fixed, so that an
            environment's behaviour depends only on its reset seeds).
        action_kinds: the handlers of the action kinds in use (``ea_gym.env.actions``), carrying on
            first; their order is the action table's.
    """

    def __init__(
        self,
        model: SystemModel,
        config: EnvConfig,
        n_systems: int = 1,
        classifier: FaultClassifier | None = None,
        calibration_seed: int = 0,
        action_kinds: Sequence[HandlerFactory] = DEFAULT_ACTION_KINDS,
    ):
        if not isinstance(config, EnvConfig):
            raise TypeError(f"config must be an EnvConfig, got {type(config).__name__}")
        self.model = model
        self.config = config
        self.n = n_systems
        self.components = classes_of(model)[1:]  # maintainable = degradable parameters
        self.classes = ("none", *self.components)
        self.nominal = model.parameter_vector()
        self._component_index = np.array([model.parameter_names.index(c) for c in self.components])
        self.limits = np.array([model.safe_limits[c] for c in self.components])
        self._low, self._high = self.limits[:, 0].copy(), self.limits[:, 1].copy()
        wear = config.wear if config.wear is not None else {name: WearConfig() for name in self.components}
        self.degradation: Degradation | PartsDegradation
        if config.concurrent_wear:
            self.degradation = PartsDegradation(model, wear, self.components, n_systems, config.tolerance, config.background_wear)
            _check_tolerance(self.degradation, config.tolerance)
        else:
            self.degradation = Degradation(model, wear, self.components, n_systems)
        self.chain, self.monitor = _supervision(model, config, wear, n_systems, classifier, calibration_seed)
        self._joint_config = config.phm_config.joint  # what commissioning fits with
        self.elements = self.monitor.elements
        self.rco = self.monitor.components
        self._rco_index = np.array([self.elements.index(c) for c in self.rco])
        self.operation = Operation(model, n_systems, config.sample_rate, config.window, config.noise, config.load_std)
        self.h, self.samples = self.operation.h, self.operation.samples
        self.nominal_parameters = dict(zip(model.parameter_names, map(float, self.nominal)))
        self.safe_limits = {name: tuple(map(float, limits)) for name, limits in model.safe_limits.items()}
        self.observer = Observer(config, n_systems, self.elements, self.rco, self.classes, self.limits, self.nominal[self._component_index])
        self._rul_columns = self.components if config.concurrent_wear else ()  # what info["true_rul"]'s columns are
        n = n_systems
        self._theta = np.tile(self.nominal, (n, 1))  # true parameter values (N, P)
        self._clock = np.zeros(n)  # degradation time (s)
        self._steps = np.zeros(n, dtype=int)
        self._down = np.zeros(n, dtype=int)  # steps left without production
        self._since_maintenance = np.zeros(n)  # s
        self._last_orders = np.zeros(n, dtype=int)  # the orders of the step before: which ones continue
        self._take_action_kinds(action_kinds)

    def _take_action_kinds(self, action_kinds: Sequence[HandlerFactory]) -> None:
        """The handlers, the action table of their kinds, each action's kind (its handler's index) and
        component, and the cost items."""
        self.handlers = tuple(make(self) for make in action_kinds)
        kinds = [handler.kind for handler in self.handlers]
        if not kinds or kinds[0] != ActionKind.CARRY_ON or len(set(kinds)) != len(kinds):
            raise ValueError(f"action_kinds must be distinct kinds, carrying on first (a machine that is down carries on), got {kinds}")
        self.actions = action_table(self.components, kinds)
        self.action_meanings = tuple(map(str, self.actions))
        self._action_kind = np.array([kinds.index(action.kind) for action in self.actions])
        self._action_component = np.array([-1 if a.component is None else self.components.index(a.component) for a in self.actions])
        self._action_maintains = np.array([action.kind.maintains for action in self.actions])
        self.cost_items = cost_items(kinds)
        self._prices = [kind.price(self.config.costs) for kind in kinds]
        if any(price != 0 and kind.cost_item is None for kind, price in zip(kinds, self._prices)):
            raise ValueError("an action kind with a price needs a cost_item to count it under")
        self._cost_rows = [-1 if kind.cost_item is None else self.cost_items.index(kind.cost_item) for kind in kinds]

    # -- public read-only views -----------------------------------------------------------------

    @property
    def true_parameters(self) -> np.ndarray:
        """Every system's true parameter values (N, P), columns in ``model.parameter_names`` order (a copy)."""
        return self._theta.copy()

    def true_rul(self) -> np.ndarray:
        """Every system's true remaining useful life (s): (N,) with one fault per system, (N, n) per maintainable
        component where every part ages (``EnvConfig.concurrent_wear``)."""
        return self.degradation.true_rul(self._theta, self._clock)

    def faulty_component(self, i: int) -> str:
        """The component whose fault system i has (or will have: its arrival may be ahead); one fault per system only."""
        if isinstance(self.degradation, PartsDegradation):
            raise ValueError("every part ages (concurrent_wear=True): there is no one faulty component; see true_rul() per part")
        return self.degradation.faulty_component(i)

    @property
    def wear(self) -> Wear | PartsWear:
        """The wear processes of the wearing components."""
        return self.degradation.wear

    @property
    def wear_components(self) -> tuple[str, ...]:
        """The wearing components, in ``wear``'s order."""
        return self.degradation.components

    # -- episode bookkeeping ------------------------------------------------------------------

    def reset(self, rngs: Sequence[np.random.Generator], systems: np.ndarray | None = None) -> Observation:
        """Start new episodes (all systems, or those in the boolean mask); returns the first observation.

        System i draws only from ``rngs[i]``, here and in ``step``: its episode is the same whether it
        is stepped alone or with others.
        """
        mask = np.ones(self.n, dtype=bool) if systems is None else np.asarray(systems, dtype=bool)
        self._clock[mask] = 0.0
        self._since_maintenance[mask] = 0.0
        self._last_orders[mask] = 0
        self._theta[mask] = self.nominal
        self._steps[mask] = 0
        self._down[mask] = 0
        self.operation.start(rngs, mask)
        self.degradation.start(rngs, self._clock, mask, self._theta)
        if self.chain is not None:
            self.chain.reset(mask)
        else:
            self.monitor.reset(mask if systems is not None else None)
        if self._commission(rngs, mask):  # before its first step the chain knows the machine it was commissioned with
            return self.observe({**self.observer.idle, "estimates": self.operation.reference_parameters[:, self._component_index]})
        return self.observe(self.observer.idle)

    def reset_info(self) -> StepInfo:
        """What the systems report after a reset: their true state, no cost, no event."""
        return StepInfo.at_reset(self.model.parameter_names, self.true_parameters, self.true_rul(), self.cost_items, self._rul_columns)

    # -- the step ---------------------------------------------------------------------------------

    def step(self, actions: np.ndarray, rngs: Sequence[np.random.Generator]) -> StepResult:
        """Advance every system by one step under ``actions`` (N,), indices into ``self.actions``."""
        # small arrays throughout: one BLAS thread, which also leaves the other core to the learner's torch
        with single_threaded_blas():
            return self._step(actions, rngs)

    def _step(self, actions: np.ndarray, rngs: Sequence[np.random.Generator]) -> StepResult:
        actions = np.asarray(actions)
        n_actions = len(self.actions)
        orders = np.empty_like(actions)
        if actions.shape != (self.n,) or actions.dtype.kind not in "iu" or not take_orders(actions, n_actions, self._down, orders):
            raise ValueError(f"actions must be {self.n} integers in [0, {n_actions - 1}], got {actions!r}")
        dt = self.config.step_seconds
        items = np.zeros((len(self.cost_items), self.n))  # one row per cost item, the total last
        costs = dict(zip(self.cost_items, items))
        events: list[list[Event]] = [[] for _ in range(self.n)]
        maintained = self._maintain(orders, rngs, items, events)  # a machine under replacement took no orders

        running = self._down == 0
        self.degradation.advance(self._theta, running, self._clock, dt, rngs)
        self._clock = self._clock + dt

        outputs = self.operate(rngs)
        failed = self._failures(running, rngs, costs, events)
        terminated, truncated = np.empty(self.n, dtype=bool), np.empty(self.n, dtype=bool)
        # lost production, downtime, time since maintenance, step count, episode ends and the total cost, in place
        close_step(
            items, self.cost_items.index("lost_production"), self.config.costs.lost_production, self._down, self._since_maintenance,
            self._steps, maintained, failed, dt, self.config.horizon, not self.config.continue_after_failure, terminated, truncated,
        )
        observation = self.observe(outputs)
        info = StepInfo(self.model.parameter_names, self._theta.copy(), self.true_rul(), costs, failed, events, self._rul_columns)
        return StepResult(observation=observation, reward=-costs["total"], terminated=terminated, truncated=truncated, info=info)

    def _maintain(
        self, orders: np.ndarray, rngs: Sequence[np.random.Generator], items: np.ndarray, events: list[list[Event]]
    ) -> np.ndarray:
        """Hand each kind's orders among ``orders`` (N,) to its handler and count their prices in the cost
        ``items`` (rows, N); returns the systems maintained (N,) bool: given an order of a kind that maintains."""
        previous, self._last_orders = self._last_orders, orders
        carrying_on = orders == 0  # action 0 is carrying on
        if carrying_on.all():  # the common step
            return ~carrying_on
        kinds = self._action_kind[orders]
        for kind in np.unique(kinds).tolist():  # in the table's order
            rows = np.flatnonzero(kinds == kind)
            given = orders[rows]
            self.handlers[kind].apply(Orders(rows, self._action_component[given], previous[rows] == given), rngs, events)
            if self._cost_rows[kind] >= 0:
                items[self._cost_rows[kind], rows] += self._prices[kind]
        return self._action_maintains[orders]

    def _failures(
        self, running: np.ndarray, rngs: Sequence[np.random.Generator], costs: dict[str, np.ndarray], events: list[list[Event]]
    ) -> np.ndarray:
        """The running machines with a parameter outside its safe limits (N,) bool, their costs and events."""
        low, high = self._low, self._high
        failed = np.empty(self.n, dtype=bool)
        if not outside_limits(self._theta, self._component_index, low, high, running, failed):
            return failed
        values = self._theta[:, self._component_index]
        broken = np.flatnonzero(failed)
        costs["failure"][broken] += self.config.costs.failure
        culprits = np.argmax(np.maximum(low - values[broken], values[broken] - high), axis=1)
        for i, d in zip(broken, culprits):
            events[i].append(Failure(self.components[d], values[i, d], tuple(self.limits[d])))
        if self.config.continue_after_failure:
            self.replace(broken, culprits, self.config.costs.failure_downtime, rngs, events)
        return failed

    # -- what the action handlers change (``ea_gym.env.actions.Machines``) --------------------------

    def deviation(self, systems: np.ndarray, components: np.ndarray) -> np.ndarray:
        """Nominal minus the true value of ``components[k]``'s parameter in ``systems[k]`` (SI)."""
        columns = self._component_index[components]
        return self.nominal[columns] - self._theta[systems, columns]

    def adjust(self, systems: np.ndarray, components: np.ndarray, change: np.ndarray) -> None:
        """Move ``components[k]``'s parameter in ``systems[k]`` by ``change[k]`` (SI); the chain's prognosis
        logs it (the maintenance log: it knows what was done)."""
        self._theta[systems, self._component_index[components]] += change
        if self.chain is not None:
            self.chain.record_adjustment(systems, components, change)

    def replace(
        self, systems: np.ndarray, components: np.ndarray, downtime: int, rngs: Sequence[np.random.Generator], events: list[list[Event]]
    ) -> None:
        """Put a new component ``components[k]`` in system ``systems[k]`` (distinct systems), the machine down for
        ``downtime`` steps: with one fault per system, at nominal, and a new fault where it was the faulty one;
        where every part ages, within its tolerance with a new wear process.

        The systems are reset together; each draws only from its own generator, as when replaced one by one.
        """
        if len(systems) == 0:
            return
        components = np.asarray(components, dtype=int)
        self.degradation.replace(rngs, self._clock, np.asarray(systems), self._component_index[components], self._theta)
        self._down[systems] = downtime
        self.operation.stop(systems)  # the machine is stopped and restarted
        mask = np.zeros(self.n, dtype=bool)
        mask[systems] = True
        if self.chain is not None:
            self.chain.reset(mask)
        else:
            self.monitor.reset(mask)
        self._commission(rngs, mask)
        for i, d in zip(systems, components):
            events[i].append(Replacement(self.components[d], downtime))

    def _commission(self, rngs: Sequence[np.random.Generator], systems: np.ndarray) -> bool:
        """Commission the machines in the boolean mask ``systems`` (``EnvConfig.commission_seconds``; none where it
        is 0): each runs that long healthy under its own load, its parts' values are fitted from the measured record
        (``ea_gym.phm.commission``, in every obs_mode: the same draws whatever is observed), and they become its
        reference model's and, in the "phm" mode, the chain's healthy machine. Returns whether any was."""
        seconds = self.config.commission_seconds
        if seconds == 0 or not systems.any():
            return False
        rows = np.flatnonzero(systems)
        window = self.operation.commissioning(rows, self._theta[rows], seconds, rngs)
        fitted = commission(
            self.model, window.measured, window.load, window.load_rate, self.config.sample_rate, self.config.noise, config=self._joint_config
        )
        if self.chain is not None:
            self.chain.commission(fitted.value, systems, fitted.std)
            reference = self.chain.reference_parameters[rows]
        else:
            reference = np.tile(self.nominal, (len(rows), 1))
            reference[:, self._component_index] = fitted.value
        self.operation.set_reference(rows, reference)
        return True

    def operate(self, rngs: Sequence[np.random.Generator]) -> dict[str, np.ndarray]:
        """Simulate one window of plant and reference, measure, and run the chain or the monitor."""
        window = self.operation.run(self._theta, rngs)
        if self.chain is not None:
            status = self.chain.update(window.measured, window.expected, window.load, window.load_rate)
            if self.observer.per_part:
                return {"ea": status.ea, "ea_reference": status.ea_reference, "eai": status.eai, **self._part_outputs(status)}
            return {
                "ea": status.ea, "ea_reference": status.ea_reference, "eai": status.eai,
                "diagnosis": status.diagnosis, "estimates": status.estimates, "rul": status.rul,
            }
        monitored = self.monitor.update(window.measured, window.expected, window.load)
        ea, ea_ref = monitored.ea.sum(-1), monitored.ea_reference.sum(-1)
        eai = component_activity_index(ea, self._rco_index, self.rco)
        return {"ea": ea, "ea_reference": ea_ref, "eai": eai}

    @staticmethod
    def _part_outputs(status: HealthStatus) -> dict[str, np.ndarray]:
        """Every part's degrading probability (N, n), joint estimate (N, n, SI) and RUL [point, low, high] (N, n, 3) s
        (``PartHealth``: inf but for the parts judged degrading)."""
        if status.parts is None:
            raise ValueError(
                "every part ages (concurrent_wear=True): the chain needs its joint filter (estimator_kind 'joint' or JointFilterConfig.beside)"
            )
        return {"degrading": status.parts.degrading, "estimates": status.parts.value, "rul": status.parts.rul}

    def observe(self, outputs: dict[str, np.ndarray]) -> Observation:
        """Observation arrays of the step's ``outputs``; systems that are down show idle outputs."""
        oracle = None
        if self.config.obs_mode == "oracle":
            values, rul = self._theta[:, self._component_index], self.true_rul()
            if isinstance(self.degradation, PartsDegradation):
                oracle = OracleTruth(values=values, diagnosis_class=None, rul=rul, degrading=self.degradation.degrading(self._clock))
            else:
                oracle = OracleTruth(values=values, diagnosis_class=self.degradation.diagnosis_class(self._clock), rul=rul)
        return self.observer.observe(outputs, self._since_maintenance, self._down > 0, oracle)


def _check_tolerance(degradation: PartsDegradation, tolerance: float) -> None:
    """A ValueError naming ``tolerance`` where it would start a part on or outside its safe limits."""
    span = degradation.limits[:, 1] - degradation.limits[:, 0]
    nominal = degradation.nominal[degradation.parameter_index]
    low, high = nominal - tolerance * span, nominal + tolerance * span
    outside = np.flatnonzero((low <= degradation.limits[:, 0]) | (high >= degradation.limits[:, 1]))
    if len(outside):
        d = int(outside[0])
        raise ValueError(
            f"tolerance {tolerance:g} starts {degradation.components[d]} anywhere in [{low[d]:g}, {high[d]:g}], not inside its safe limits "
            f"{tuple(map(float, degradation.limits[d]))}"
        )


def chain_settings(model: SystemModel, config: EnvConfig, wear: dict[str, WearConfig]) -> PHMConfig:
    """The chain's settings (``EnvConfig.phm_config``), the tracking filters' theta random walk of every
    wearing component its wear's own (``WearConfig.random_walk_std`` over nominal; settings the chain
    names itself win): the filters' process noise is then that of the process they track, none for
    linear wear, whose drift the filter's drift state carries."""
    phm = config.phm_config
    derived = {name: w.random_walk_std(model.nominal[name], model.safe_limits[name]) / abs(model.nominal[name]) for name, w in wear.items()}
    noise = derived | dict(phm.tracking.parameter_theta_noise)
    return replace(phm, tracking=replace(phm.tracking, parameter_theta_noise=tuple(noise.items())))


def _supervision(
    model: SystemModel, config: EnvConfig, wear: dict[str, WearConfig], n_systems: int, classifier: FaultClassifier | None, calibration_seed: int
) -> tuple[PHMChain | None, Monitor]:
    """The PHM chain and its monitor (phm mode), or a monitor alone (the EA features of the other modes)."""
    phm_config = chain_settings(model, config, wear)
    if config.obs_mode != "phm":
        return None, Monitor(model, 1.0 / config.sample_rate, phm_config.monitor, n_systems)
    if classifier is None:
        classifier = classifier_for(model)
    # the same thresholds for every environment of a model and settings: shipped, cached or calibrated once
    thresholds = thresholds_for(model, phm_config, np.random.default_rng(calibration_seed))
    chain = PHMChain(model, classifier, thresholds, phm_config, n_systems)
    return chain, chain.monitor
