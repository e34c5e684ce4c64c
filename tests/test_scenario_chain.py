"""A scenario through the chain's harness: the load as its sensor reads it, and the reference model at the chain's
healthy machine (``PHMChain.reference_parameters``, what commissioning sets)."""

from __future__ import annotations

import numpy as np
import pytest

import ea_gym
from ea_gym.diagnosis.training import load_shipped_classifier
from ea_gym.models import spring_mass_damper
from ea_gym.phm import PHMChain, PHMConfig, run_measurements
from ea_gym.phm.harness import chain_config, measured_load, reference_signals, scenario_measurements
from ea_gym.plant import run_model
from ea_gym.sensors import Sensors

MODEL = spring_mass_damper()
LOAD = {"kind": "sines", "offset": 10.0, "sines": [{"amplitude": 4.0, "frequency": 0.25}, {"amplitude": 2.0, "frequency": 0.7}]}


def _scenario(**changes: object) -> ea_gym.Scenario:
    return ea_gym.load_scenario({"system": "spring_mass_damper", "duration": 40.0, "load": LOAD, **changes})


def test_the_load_column_carries_the_load_noise_and_nothing_else_changes() -> None:
    """The sensors' noise is drawn first: with load noise the signals are those of the exact-load record, and the load
    column departs from the true load by white noise of 2 % of its RMS over each 1 s step (measured 2.03 %)."""
    exact = scenario_measurements(_scenario(sensors={"noise": 0.01, "seed": 0}), np.random.default_rng(5))
    noisy = scenario_measurements(_scenario(sensors={"noise": 0.01, "load_noise": 0.02, "seed": 0}), np.random.default_rng(5))
    np.testing.assert_array_equal(noisy.signals, exact.signals)
    error = (noisy.load - exact.load)[:4000].reshape(40, 100)
    rms = np.sqrt(np.mean(exact.load[:4000].reshape(40, 100) ** 2, axis=1))
    ratio = np.sqrt(np.mean((error / rms[:, None]) ** 2))
    assert ratio == pytest.approx(0.02, rel=0.05)
    assert abs(np.mean(error / rms[:, None])) < 0.02 * 4 / np.sqrt(error.size)  # zero mean


def test_no_load_noise_draws_nothing() -> None:
    rng = np.random.default_rng(0)
    load = np.linspace(0, 1, 50)
    assert measured_load(load, 0.0, 10, rng) is load
    assert rng.random() == np.random.default_rng(0).random()


@pytest.fixture(scope="module")
def chain() -> PHMChain:
    config = chain_config(100.0, 0.01)
    return PHMChain(MODEL, load_shipped_classifier(MODEL.name), np.full(len(MODEL.graph.elements), 1e9), config)


def test_the_reference_model_is_the_chains_healthy_machine(chain: PHMChain) -> None:
    """After ``commission`` (k 96 N/m, m 10.3 kg, b 0.52 N s/m) the reference signals are those of that machine, simulated
    here by the plant's own simulation."""
    scenario = _scenario(parameters={"m": 10.3, "k": 96.0, "b": 0.52})
    t = scenario.times()
    load = scenario.make_load()
    machine = run_model(scenario.model, t, load)
    degradable = [MODEL.parameter_names.index(name) for name in chain.degradable]
    chain.commission(scenario.model.parameter_vector()[degradable][None])
    try:
        signals, last = reference_signals(chain, load.value(t)[None], load.derivative(t)[None], np.zeros((1, 2)))
        expected = Sensors(MODEL).measure(machine.parameters[None], machine.states[None], 0.0, np.random.default_rng(0))
        np.testing.assert_allclose(signals, expected, rtol=0, atol=1e-9 * np.abs(expected).max())
        np.testing.assert_allclose(last[0], machine.states[-1], rtol=1e-9)
    finally:
        chain.commission(MODEL.parameter_vector()[degradable][None])


def test_a_record_of_the_commissioned_machine_leaves_no_residual_the_nominal_one_does(chain: PHMChain) -> None:
    """A noise-free record of a machine 4 % heavier and 3 % softer than nominal: against the nominal reference the largest
    EA residual of an element over a step is more than 1 % of its EA (measured 13 x); against the commissioned machine
    below 1e-3 of it (measured 1e-7)."""
    scenario = _scenario(parameters={"m": 10.4, "k": 97.0})
    record = scenario_measurements(scenario, np.random.default_rng(0))
    nominal = run_measurements(chain, record)
    degradable = [MODEL.parameter_names.index(name) for name in chain.degradable]
    chain.commission(scenario.model.parameter_vector()[degradable][None])
    try:
        commissioned = run_measurements(chain, record)
    finally:
        chain.commission(MODEL.parameter_vector()[degradable][None])

    def worst(run: object) -> float:
        statuses = run.statuses[5:]  # type: ignore[attr-defined]
        return max(float(np.max(np.abs(s.residual[0]) / np.maximum(s.ea[0], 1e-12))) for s in statuses)

    assert worst(commissioned) < 1e-3 < 1e-2 < worst(nominal)


def test_a_scenarios_chain_reads_the_noisy_load_its_plant_the_true_one() -> None:
    """The truth (the plant's parameters) does not depend on the load noise; the reference model, driven by the load the
    chain reads, does."""
    from ea_gym.phm import run_scenario

    def run(load_noise: float) -> object:
        scenario = _scenario(duration=12.0, faults=[{"parameter": "k", "profile": [[0, 100], [12, 97]]}],
                             sensors={"noise": 0.0, "load_noise": load_noise})
        config = PHMConfig(timing=chain_config(100.0, 0.0).timing)
        chain = PHMChain(MODEL, load_shipped_classifier(MODEL.name), np.full(len(MODEL.graph.elements), 1e9), config)
        return run_scenario(scenario, chain, np.random.default_rng(0))

    exact, noisy = run(0.0), run(0.05)
    np.testing.assert_array_equal(exact.true_parameters, noisy.true_parameters)  # type: ignore[attr-defined]
    assert not np.array_equal(exact.statuses[-1].ea_reference, noisy.statuses[-1].ea_reference)  # type: ignore[attr-defined]
