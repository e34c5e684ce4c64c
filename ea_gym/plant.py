"""The plant: a system model simulated under a scenario, with every element's effort, flow and power."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ea_gym.bondgraph.simulation import simulate_linear
from ea_gym.loads import Load
from ea_gym.models import SystemModel
from ea_gym.scenario import Scenario


@dataclass(frozen=True)
class Trajectory:
    """A simulated run.

    Attributes:
        t: sample times (s), shape (T + 1,).
        states: energy variables (p of each I, q of each C) at every sample, (T + 1, nx), columns in
            ``model.state_names`` order.
        parameters: component values at every sample, (T + 1, P), columns in ``model.parameter_names``.
        bonds: efforts (first n_bonds columns) and flows of every bond, (T + 1, 2 n_bonds).
        effort, flow, power: per element name, arrays over ``t``. Flow and power are into R, C and I
            elements, out of sources, into the first port of a TF or GY; power in W.
        model: the simulated system.
    """

    t: np.ndarray
    states: np.ndarray
    parameters: np.ndarray
    bonds: np.ndarray
    effort: dict[str, np.ndarray]
    flow: dict[str, np.ndarray]
    power: dict[str, np.ndarray]
    model: SystemModel

    @property
    def sample_period(self) -> float:
        return float(self.t[1] - self.t[0])


def run_model(
    model: SystemModel,
    t: np.ndarray,
    load: Load,
    parameters: Callable[[np.ndarray], np.ndarray] | None = None,
    initial_state: np.ndarray | None = None,
) -> Trajectory:
    """Simulate ``model`` at the evenly spaced sample times ``t`` (s).

    Args:
        load: drives the model's load source (its unit, e.g. N); the other sources hold their constant values.
        parameters: maps times (T,) to component values (T, P); default: the nominal values.
        initial_state: energy variables at t[0]; default at rest.
    """
    t = np.asarray(t, dtype=float)
    h = float(t[1] - t[0])
    if parameters is None:
        nominal = model.parameter_vector()

        def parameters(times: np.ndarray) -> np.ndarray:
            return np.broadcast_to(nominal, times.shape + nominal.shape)

    theta = np.asarray(parameters(t), dtype=float)
    theta_mid = np.asarray(parameters(t[:-1] + 0.5 * h), dtype=float)
    x0 = np.zeros(len(model.state_names)) if initial_state is None else np.asarray(initial_state, dtype=float)
    u, du = model.source_inputs(load.value(t), load.derivative(t))
    states, bonds = simulate_linear(model.state_space, h, u, du, theta_mid, theta, x0)
    effort, flow = model.state_space.element_signals(bonds)
    power = {name: effort[name] * flow[name] for name in effort}
    return Trajectory(t=t, states=states, parameters=theta, bonds=bonds, effort=effort, flow=flow, power=power, model=model)


def simulate(scenario: Scenario) -> Trajectory:
    """Simulate the plant of ``scenario``: its model under its (true) load, every faulty parameter following its profile
    at once (``Scenario.parameters_at``); the true signals."""
    return run_model(
        scenario.model,
        scenario.times(),
        scenario.make_load(),
        scenario.parameters_at,
        scenario.initial_state_vector(),
    )
