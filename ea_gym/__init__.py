"""ea-gym: Energy-Activity prognostics and health management on bond graphs.

The top level gives the main entry points::

    scenario = ea_gym.load_scenario("scenario.json")
    trajectory = ea_gym.simulate(scenario)           # .t, .effort, .flow, .power per element
    ea = ea_gym.energy_activity(trajectory.power, trajectory.sample_period, window=1.0)
    eai = ea_gym.activity_index({name: ea[name] for name in scenario.model.rco_elements})
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

import ea_gym.env  # noqa: F401 - registers the Gymnasium environments

if TYPE_CHECKING:
    from ea_gym.energy import (
        EnergyActivityAccumulator,
        activity_index,
        constitutive_power,
        cumulative_energy_activity,
        energy_activity,
        windowed_energy,
    )
    from ea_gym.models import MODELS, ParameterError, SystemModel, get_model
    from ea_gym.plant import Trajectory, run_model, simulate
    from ea_gym.scenario import Scenario, ScenarioError, load_scenario
    from ea_gym.threads import kernel_threads, set_kernel_threads

# imported on first use: ``ea-gym`` reads and refuses a bad file before the numerical kernels (numba, scipy) load
_WHERE = {
    **dict.fromkeys(
        ("EnergyActivityAccumulator", "activity_index", "constitutive_power", "cumulative_energy_activity", "energy_activity",
         "windowed_energy"), "ea_gym.energy"),
    **dict.fromkeys(("MODELS", "ParameterError", "SystemModel", "get_model"), "ea_gym.models"),
    **dict.fromkeys(("Trajectory", "run_model", "simulate"), "ea_gym.plant"),
    **dict.fromkeys(("Scenario", "ScenarioError", "load_scenario"), "ea_gym.scenario"),
    **dict.fromkeys(("kernel_threads", "set_kernel_threads"), "ea_gym.threads"),
}


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module 'ea_gym' has no attribute {name!r}")
    return getattr(importlib.import_module(_WHERE[name]), name)


__version__ = "0.1.0"

__all__ = [
    "MODELS",
    "EnergyActivityAccumulator",
    "ParameterError",
    "Scenario",
    "ScenarioError",
    "SystemModel",
    "Trajectory",
    "activity_index",
    "constitutive_power",
    "cumulative_energy_activity",
    "energy_activity",
    "get_model",
    "kernel_threads",
    "load_scenario",
    "run_model",
    "set_kernel_threads",
    "simulate",
    "windowed_energy",
]
