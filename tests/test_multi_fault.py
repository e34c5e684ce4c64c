"""Several parts ageing at once: a scenario's ``faults``, the plant that follows every profile, and the truth per part."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import ea_gym
from ea_gym.scenario import Scenario

M = 10.0  # kg, the spring-mass-damper's nominal mass, left alone
TWO_FAULTS = {
    "system": "spring_mass_damper",
    "duration": 60.0,
    "load": {"kind": "sines", "offset": 10.0, "sines": [{"amplitude": 4.0, "frequency": 0.25}, {"amplitude": 2.0, "frequency": 0.7, "phase": 1.0}]},
    "faults": [
        {"parameter": "k", "profile": [[0, 100], [10, 100], [60, 88]]},
        {"parameter": "b", "profile": [[0, 0.5], [20, 0.5], [60, 0.58]]},
    ],
}


def two_faults() -> Scenario:
    return ea_gym.load_scenario(TWO_FAULTS)


def test_the_plant_follows_both_profiles_as_an_independent_ode_does() -> None:
    """m dv/dt = u - k(t) x - b(t) v, dx/dt = v, k and b ramping over overlapping times, solved by scipy's DOP853:
    the plant's momentum p = m v and displacement q = x agree within 1e-6 of their largest values (measured 1.2e-7
    and 4.6e-9: the plant holds the parameters at each interval's midpoint)."""
    scenario = two_faults()
    plant = ea_gym.simulate(scenario)
    load = scenario.make_load()
    k_column, b_column = (scenario.model.parameter_names.index(name) for name in ("k", "b"))

    def rhs(t: float, y: np.ndarray) -> list[float]:
        x, v = y
        k = np.interp(t, [0, 10, 60], [100, 100, 88])  # the profiles written again, not read from the scenario
        b = np.interp(t, [0, 20, 60], [0.5, 0.5, 0.58])
        return [v, (float(load.value(np.array(t))) - k * x - b * v) / M]

    x, v = solve_ivp(rhs, (0.0, 60.0), [0.0, 0.0], t_eval=plant.t, method="DOP853", rtol=1e-11, atol=1e-13, max_step=0.05).y
    assert scenario.model.state_names == ("m", "k")  # momentum of m, displacement of k
    np.testing.assert_allclose(plant.states[:, 0], M * v, rtol=0, atol=1e-6 * np.abs(M * v).max())
    np.testing.assert_allclose(plant.states[:, 1], x, rtol=0, atol=1e-6 * np.abs(x).max())
    np.testing.assert_allclose(plant.parameters[:, k_column], np.interp(plant.t, [0, 10, 60], [100, 100, 88]), rtol=1e-12)
    np.testing.assert_allclose(plant.parameters[:, b_column], np.interp(plant.t, [0, 20, 60], [0.5, 0.5, 0.58]), rtol=1e-12)


def test_the_truth_per_part_is_each_profiles_own_trend() -> None:
    """k: 100 -> 88 over 10-60 s, -0.24 N/m per s, reaches its lower limit 85 at 10 + 15 / 0.24 = 72.5 s; b: +0.002 N s/m per
    s from 20 s, reaches its upper limit 0.6 at 20 + 0.1 / 0.002 = 70 s; before its onset a part has no End of Life."""
    scenario = two_faults()
    assert scenario.faulty_parameters == ("k", "b") and scenario.fault is scenario.faults[0]
    assert scenario.model.safe_limits["k"] == (85.0, 105.0) and scenario.model.safe_limits["b"] == (0.4, 0.6)
    eol = scenario.true_end_of_life(np.array([5.0, 15.0, 30.0]))
    assert list(eol) == ["k", "b"]
    np.testing.assert_allclose(eol["k"], [np.inf, 72.5, 72.5])
    np.testing.assert_allclose(eol["b"], [np.inf, np.inf, 70.0])


def test_one_fault_in_either_form_is_the_same_scenario() -> None:
    single = {**TWO_FAULTS, "faults": None, "fault": TWO_FAULTS["faults"][0]}
    listed = {**TWO_FAULTS, "faults": TWO_FAULTS["faults"][:1]}
    a, b = ea_gym.load_scenario(single), ea_gym.load_scenario(listed)
    assert a.faults == b.faults and a.fault == b.fault
    t = np.linspace(0, 60, 7)
    np.testing.assert_array_equal(a.parameters_at(t), b.parameters_at(t))
    np.testing.assert_array_equal(ea_gym.simulate(a).states, ea_gym.simulate(b).states)


def test_faults_survive_the_round_trip_through_to_dict() -> None:
    """Each form comes back as written: a scenario of one ``fault`` gains no ``faults`` key (scripts that replace its
    ``fault`` keep working), one of ``faults`` no ``fault`` key."""
    scenario = two_faults()
    data = scenario.to_dict()
    assert "fault" not in data and ea_gym.load_scenario(data).faults == scenario.faults
    single = ea_gym.load_scenario({**TWO_FAULTS, "faults": None, "fault": TWO_FAULTS["faults"][0]}).to_dict()
    assert "faults" not in single and ea_gym.load_scenario(single).faults == scenario.faults[:1]


@pytest.mark.parametrize("faults, fragment", [
    ([{"parameter": "k", "profile": [[0, 100]]}, {"parameter": "k", "profile": [[0, 90]]}],
     "faults[1].parameter: 'k' is already faulty (faults[0])"),
    ([{"parameter": "k", "profile": [[0, 100]]}, {"parameter": "z", "profile": [[0, 1]]}], "faults[1].parameter: unknown parameter 'z'"),
    ([{"parameter": "b", "profile": [[5, 0.5], [1, 0.4]]}], "faults[0].profile[1]: time 1.0 s is not above the previous time 5.0 s"),
    ([{"parameter": "b", "profile": [[0, 0.5], [5, 5e3]]}], "faults[0].profile[1]: 'b' = 5000.0 is more than a factor 1000"),
])
def test_a_bad_fault_in_the_list_is_named_by_its_index(faults: list, fragment: str) -> None:
    with pytest.raises(ea_gym.ScenarioError) as info:
        ea_gym.load_scenario({**TWO_FAULTS, "faults": faults})
    assert fragment in str(info.value)


def test_the_fastest_mode_is_checked_with_every_part_at_its_value_of_the_time() -> None:
    """At 3 Hz (pi x 3 = 9.4 1/s) k = 300 N/m and m = 4 kg are each resolved alone (|lambda| = 5.5 and 5 1/s), together
    (sqrt(300 / 4) = 8.7 1/s) too; k = 300 with m = 3 kg (10 1/s) is not: refused, naming the breakpoint where both are."""
    at = {**TWO_FAULTS, "sample_rate": 3.0, "load": {"kind": "constant", "value": 10.0}}
    ok = [{"parameter": "k", "profile": [[0, 100], [30, 300]]}, {"parameter": "m", "profile": [[0, 10], [30, 4]]}]
    ea_gym.load_scenario({**at, "faults": ok})
    too_fast = [ok[0], {"parameter": "m", "profile": [[0, 10], [30, 3]]}]
    with pytest.raises(ea_gym.ScenarioError) as info:
        ea_gym.load_scenario({**at, "faults": too_fast})
    assert "faults[0].profile[1]: the model's fastest mode" in str(info.value)
    for one in too_fast:  # each alone is resolved
        ea_gym.load_scenario({**at, "faults": [one]})
