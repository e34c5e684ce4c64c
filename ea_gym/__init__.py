"""ea-gym: Energy-Activity prognostics and health management on bond graphs.

The top level gives the main entry points::

    scenario = ea_gym.load_scenario("scenario.json")
    trajectory = ea_gym.simulate(scenario)           # .t, .effort, .flow, .power per element
    ea = ea_gym.energy_activity(trajectory.power, trajectory.sample_period, window=1.0)
    eai = ea_gym.activity_index({name: ea[name] for name in scenario.model.rco_elements})
"""

import ea_gym.env  # noqa: F401 - registers the Gymnasium environments
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
    "load_scenario",
    "run_model",
    "simulate",
    "windowed_energy",
]
