"""The machines' operation over arrays of N systems: random loads, plant and fault-free reference
simulated over a step's window, the sensors, and the wear of the degrading components (one fault per
system, the v0 world; or every part ageing at once, the v1 world).

System i draws only from its own generator ``rngs[i]``, so that its episode is the same whether it
is stepped alone or with others.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ea_gym.bondgraph.simulation import MeasuredSimulation, simulate_measured
from ea_gym.degradation import PartsWear, Wear, WearConfig
from ea_gym.energy import window_samples
from ea_gym.loads import multisine_rotations, rotated_multisine_into
from ea_gym.models import SystemModel
from ea_gym.sensors import Sensors, SystemNoise
from ea_gym.threads import over_rows

LOAD_COMPONENTS = 16  # sines in each random load


class Loads:
    """Each system's random load: a random-phase multisine around the model's nominal load.

    Args:
        model: the machine (its nominal load (N, V, ...) and excitation bandwidth (Hz)).
        n_systems: N.
        h: sample period (s).
        load_std: range (low, high) of the load's std, fraction of ``model.random_load_scale`` (the nominal load unless the model gives a scale).
    """

    def __init__(self, model: SystemModel, n_systems: int, h: float, load_std: tuple[float, float]):
        self.model = model
        self.h = h
        self.load_std = load_std
        n = n_systems
        self.mean = np.zeros(n)
        self.amplitude = np.zeros(n)
        self.frequency = np.zeros((n, LOAD_COMPONENTS))  # Hz
        self.phase = np.zeros((n, LOAD_COMPONENTS))  # rad
        self.rotation = np.zeros((n, 3, LOAD_COMPONENTS))  # of the frequencies, kept for the episode

    def draw(self, rngs: Sequence[np.random.Generator], mask: np.ndarray) -> None:
        """New loads for the systems in the boolean ``mask``."""
        model = self.model
        for i in np.flatnonzero(mask).tolist():
            rng = rngs[i]
            std = model.random_load_scale * rng.uniform(*self.load_std)
            self.mean[i] = model.nominal_load
            self.amplitude[i] = std * math.sqrt(2.0 / LOAD_COMPONENTS)
            self.frequency[i] = model.excitation_bandwidth - rng.uniform(0.0, model.excitation_bandwidth, LOAD_COMPONENTS)
            self.phase[i] = rng.uniform(0.0, 2.0 * math.pi, LOAD_COMPONENTS)
        self.rotation[mask] = multisine_rotations(self.frequency[mask], self.h)

    def signal(self, t: np.ndarray, systems: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Each system's load and its time derivative at its times ``t`` (N, T); of the ``systems`` (K,) alone
        where given, ``t`` then (K, T)."""
        load, rate = np.empty(t.shape), np.empty(t.shape)
        phase, rotation, mean, amplitude = self.phase, self.rotation, self.mean, self.amplitude
        if systems is not None:
            phase, rotation, mean, amplitude = phase[systems], rotation[systems], mean[systems], amplitude[systems]

        def load_rows(start: int, stop: int) -> None:
            rows = slice(start, stop)
            rotated_multisine_into(t[rows], phase[rows], rotation[rows], mean[rows], amplitude[rows], load[rows], rate[rows])

        over_rows(load_rows, len(t))
        return load, rate


@dataclass(frozen=True)
class Window:
    """One step's measured operation of N systems, T = samples + 1 points.

    Attributes:
        measured: the plant's noisy sensor signals (N, nx, T).
        expected: the fault-free reference's noise-free signals (N, nx, T).
        load: the load (N, T); load_rate: its time derivative (N, T), per s.
    """

    measured: np.ndarray
    expected: np.ndarray
    load: np.ndarray
    load_rate: np.ndarray


class Operation:
    """The plant and its fault-free reference under the same loads, measured by the sensors.

    Args:
        model: the machine (its sensors measure both).
        n_systems: N.
        sample_rate: Hz.
        window: measured operation per step (s).
        noise: sensor noise, fraction of each signal's RMS.
        load_std: range of the loads' std, fraction of ``model.random_load_scale`` (the nominal load unless the model gives a scale).
    """

    def __init__(
        self, model: SystemModel, n_systems: int, sample_rate: float, window: float, noise: float,
        load_std: tuple[float, float],
    ):
        self.model = model
        self.sensors = Sensors(model)
        self.n = n_systems
        self.nominal = model.parameter_vector()  # the references' parameters unless set (``set_reference``)
        # plant and reference in one batch: the plants' parameter rows (written each window), then the references'
        self._theta = np.tile(self.nominal, (2 * n_systems, 1))
        self.h = 1.0 / sample_rate
        self.window = window
        self.samples = window_samples(window, self.h)
        self.window_grid = np.arange(self.samples + 1) * self.h  # s
        self.loads = Loads(model, n_systems, self.h, load_std)
        self.sensor_noise = SystemNoise(noise)
        self.states = np.zeros((2 * n_systems, len(model.state_names)))  # energy variables at the end of the last window
        self.elapsed = np.zeros(n_systems)  # operation time (s): the load's clock
        # system i's load drives plant i and reference i; the reference rows, and a healthy batch's, keep their discretization
        self.simulation = MeasuredSimulation(model.state_space, self.h, np.tile(np.arange(n_systems), 2), n_systems)

    @property
    def plant(self) -> np.ndarray:
        """The plants' energy variables at the end of the last window, (N, nx)."""
        return self.states[: self.n]

    @property
    def reference(self) -> np.ndarray:
        """The references' energy variables at the end of the last window, (N, nx)."""
        return self.states[self.n :]

    @property
    def reference_parameters(self) -> np.ndarray:
        """The parameter vectors (N, P) each system's fault-free reference is simulated with (a copy): nominal
        until ``set_reference`` gives a system its own healthy machine."""
        return self._theta[self.n :].copy()

    def set_reference(self, systems: np.ndarray, parameters: np.ndarray) -> None:
        """Simulate the references of ``systems`` (indices or mask) with ``parameters`` (one row (P,) or a row
        per system) from the next window on."""
        self._theta[self.n :][systems] = parameters

    def start(self, rngs: Sequence[np.random.Generator], mask: np.ndarray) -> None:
        """New episodes for the systems in ``mask``: at rest, a new load."""
        self.stop(mask)
        self.elapsed[mask] = 0.0
        self.loads.draw(rngs, mask)

    def stop(self, systems: np.ndarray) -> None:
        """Stop the machines ``systems`` (indices or mask): plant and reference at rest."""
        self.plant[systems] = 0.0
        self.reference[systems] = 0.0

    def load(self, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each system's load and its derivative over one window from its time ``start`` (N,), on the
        sample grid, (N, samples + 1)."""
        return self.loads.signal(start[:, None] + self.window_grid)

    def commissioning(self, systems: np.ndarray, parameters: np.ndarray, seconds: float, rngs: Sequence[np.random.Generator]) -> Window:
        """``seconds`` of healthy operation of the plants ``systems`` (K,) under their own ``parameters`` (K, P), measured
        (system i drawing its noise from ``rngs[i]``): the record a machine is commissioned from before its episode.
        Their loads' clocks move on by ``seconds``; each reference then starts from its plant's state (the
        commissioned reference describes the machine from there). ``Window``'s arrays have K rows, ``expected`` the
        plants' own noise-free signals."""
        systems = np.asarray(systems, dtype=np.intp)
        samples = window_samples(seconds, self.h)
        u, du = self.loads.signal(self.elapsed[systems, None] + np.arange(samples + 1) * self.h, systems)
        loads, rates = self.model.source_inputs(u, du)
        signals, last = simulate_measured(
            self.model.state_space, self.h, loads, rates, parameters, self.plant[systems], self.sensors.gain(parameters)
        )
        self.plant[systems] = last
        self.reference[systems] = last
        self.elapsed[systems] += samples * self.h
        return Window(measured=self.sensor_noise(signals, [rngs[i] for i in systems.tolist()]), expected=signals, load=u, load_rate=du)

    def run(self, parameters: np.ndarray, rngs: Sequence[np.random.Generator]) -> Window:
        """Simulate one window of every plant under its true ``parameters`` (N, P) and of the reference, and measure."""
        u, du = self.load(self.elapsed)
        n, theta = self.n, self._theta
        theta[:n] = parameters
        loads, rates = self.model.source_inputs(u, du)  # system i's, driving plant i and reference i
        # the measurement matrices are diagonal: a product per state equals the matrix product exactly
        signals, self.states = self.simulation(loads, rates, theta, self.states, self.sensors.gain(theta))
        self.elapsed += self.window
        return Window(measured=self.sensor_noise(signals[:n], rngs), expected=signals[n:], load=u, load_rate=du)


class WearingComponents:
    """What both worlds know of the wearing components of a machine: which they are and where they sit.

    Args:
        model: the machine.
        wear: how each wearing component wears (a subset of the maintainable ones).
        components: the maintainable components, in the action space's order.
    """

    def __init__(self, model: SystemModel, wear: dict[str, WearConfig], components: tuple[str, ...]):
        unknown = sorted(set(wear) - set(components))
        if unknown:
            raise ValueError(f"wear: unknown components {unknown}; maintainable components are {list(components)}")
        wearing = [c for c in components if c in wear]
        self.components = tuple(wearing)
        self.parameter_index = np.array([model.parameter_names.index(c) for c in wearing], dtype=int)  # into the parameter vector
        self.nominal = model.parameter_vector()
        self.limits = np.array([model.safe_limits[c] for c in wearing])
        self.configs = [wear[c] for c in wearing]
        self._maintainable_index = np.array([components.index(c) for c in wearing], dtype=int)
        self.n_components = len(components)


class Degradation(WearingComponents):
    """The wearing components of N systems, one fault at a time per system (the v0 world): which one is
    faulty, its drift, and the true RUL.

    Args:
        model: the machine.
        wear: how each wearing component wears (a subset of the maintainable ones).
        components: the maintainable components, in the action space's order.
        n_systems: N.
    """

    def __init__(self, model: SystemModel, wear: dict[str, WearConfig], components: tuple[str, ...], n_systems: int):
        super().__init__(model, wear, components)
        self.wear = Wear(self.nominal[self.parameter_index], self.limits, self.configs, n_systems, columns=self.parameter_index)

    def start(self, rngs: Sequence[np.random.Generator], clock: np.ndarray, systems: np.ndarray, parameters: np.ndarray) -> None:
        """A new fault for the systems in the boolean mask ``systems``, from their ``clock`` (s) on; their
        ``parameters`` (N, P) stay nominal."""
        self.wear.start(rngs, clock, systems)

    def advance(self, parameters: np.ndarray, running: np.ndarray, clock: np.ndarray, dt: float, rngs: Sequence[np.random.Generator]) -> None:
        """Wear the ``running`` machines' parameters (N, P, in place) over ``dt`` seconds from ``clock``."""
        self.wear.advance(parameters, clock, dt, rngs, running)

    def replace(
        self, rngs: Sequence[np.random.Generator], clock: np.ndarray, systems: np.ndarray, columns: np.ndarray, parameters: np.ndarray
    ) -> None:
        """New components in ``parameters[systems[k], columns[k]]`` (distinct systems; columns of the parameter
        vector): at nominal, and a new fault where the replaced one was the faulty one."""
        parameters[systems, columns] = self.nominal[columns]
        faulty = self.faulty_parameters()[systems] == columns
        if np.any(faulty):
            fresh = np.zeros(len(parameters), dtype=bool)
            fresh[systems[faulty]] = True
            self.wear.start(rngs, clock, fresh)

    def true_rul(self, parameters: np.ndarray, clock: np.ndarray) -> np.ndarray:
        """Each system's true remaining useful life (s), (N,)."""
        return self.wear.true_rul(parameters, clock)

    def faulty_component(self, i: int) -> str:
        """The component system i's fault is (or will be) in."""
        return self.components[int(self.wear.faulty[i])]

    def faulty_parameters(self) -> np.ndarray:
        """Each system's faulty parameter, an index into the parameter vector, (N,)."""
        return self.parameter_index[self.wear.faulty]

    def diagnosis_class(self, clock: np.ndarray) -> np.ndarray:
        """Each system's true class (N,): 0 before its fault arrives, then 1 + its faulty component's
        index among the maintainable ones."""
        arrived = clock >= self.wear.arrival
        return np.where(arrived, self._maintainable_index[self.wear.faulty] + 1, 0)


class PartsDegradation(WearingComponents):
    """Every wearing component of N systems ageing at once (the v1 world, ``ea_gym.degradation.PartsWear``):
    each starts within its tolerance, ages in the background and from its own fault's arrival on.

    Args:
        model, wear, components, n_systems: as ``Degradation``'s; the components left out of ``wear`` stay at
            their nominal values and never age.
        tolerance: half-width of the parts' starting values' spread, fraction of each safe span.
        background: background ageing, fraction of the distance from nominal to the limit per second.
    """

    def __init__(
        self, model: SystemModel, wear: dict[str, WearConfig], components: tuple[str, ...], n_systems: int, tolerance: float,
        background: float,
    ):
        super().__init__(model, wear, components)
        self.wear = PartsWear(
            self.nominal[self.parameter_index], self.limits, self.configs, n_systems, columns=self.parameter_index,
            tolerance=tolerance, background=background,
        )
        self._part_of_column = {c: d for d, c in enumerate(self.parameter_index.tolist())}

    def start(self, rngs: Sequence[np.random.Generator], clock: np.ndarray, systems: np.ndarray, parameters: np.ndarray) -> None:
        """New parts throughout the systems in the boolean mask ``systems``: their ``parameters`` (N, P) drawn within
        tolerance, a wear process each, from their ``clock`` (s) on."""
        self.wear.start(rngs, clock, systems, parameters)

    def advance(self, parameters: np.ndarray, running: np.ndarray, clock: np.ndarray, dt: float, rngs: Sequence[np.random.Generator]) -> None:
        """Age the ``running`` machines' parameters (N, P, in place) over ``dt`` seconds from ``clock``."""
        self.wear.advance(parameters, clock, dt, rngs, running)

    def replace(
        self, rngs: Sequence[np.random.Generator], clock: np.ndarray, systems: np.ndarray, columns: np.ndarray, parameters: np.ndarray
    ) -> None:
        """New components in ``parameters[systems[k], columns[k]]``: a wearing part drawn within tolerance with a
        new wear process, another at nominal."""
        parameters[systems, columns] = self.nominal[columns]
        wearing = np.array([c in self._part_of_column for c in np.asarray(columns).tolist()], dtype=bool)
        parts = np.array([self._part_of_column[c] for c in np.asarray(columns)[wearing].tolist()], dtype=int)
        self.wear.install(rngs, clock, np.asarray(systems)[wearing], parts, parameters)

    def true_rul(self, parameters: np.ndarray, clock: np.ndarray) -> np.ndarray:
        """Each maintainable component's true remaining useful life (s), (N, n): its mean trend's time to its limit
        (``PartsWear.true_rul``), inf for a component that does not age."""
        rul = np.full((len(parameters), self.n_components), np.inf)
        rul[:, self._maintainable_index] = self.wear.true_rul(parameters, clock)
        return rul

    def degrading(self, clock: np.ndarray) -> np.ndarray:
        """Whether each maintainable component's fault has arrived (it degrades beyond its background ageing), (N, n)."""
        arrived = np.zeros((len(clock), self.n_components), dtype=bool)
        arrived[:, self._maintainable_index] = self.wear.arrived(clock)
        return arrived
