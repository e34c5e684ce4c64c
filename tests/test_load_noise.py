"""The load as a measurement (``ChainTiming.load_noise``): the joint filter carries its noise as errors in variables,
and the detection thresholds are calibrated with the reference model driven by a load measured so; on records
made by solve_ivp (``tests/ode_records.py``) under a band-limited random load, 1 % sensor noise.

Measured (spring-mass-damper, k falling 4e-3 of its span per s from 40 s, seeds 20-24, 120 s): with the load
exact, alarms at 48-52 s and the joint filter's k within 0.24 % of the span in the median from 70 s on; with
1 % noise on the load and the chain told so, no alarm before the onset (alarms at 53-62 s: the thresholds are
10-17 x the exact load's), k within 0.47 % (1.96 x the exact load's error, above issue 30's 1.5 x; the tracking
filter's isolated k: 0.06 % and 0.09 %, 1.5 x); with 1 % noise on the load and the chain not told, alarms
before the onset on 2 of 5 records. On a multisine load the joint filter's k error grows 1.35 x. The lightly
damped b suffers more: its only trace, the resonance's slow decay, drowns in the resonance the load's noise
excites (b rising 5e-3 of its span per s, same records: 0.44 % of the span exact, 1.2 % with 1 % load noise,
2.75 x; the tracking filter's 0.27 % and 1.9 %; alarms at 80-90 s instead of 52-58 s; the joint filter's own
std grows with its error: |error| / std stays about 1).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from ode_records import RATE, Fault, chain_for, run_chain, simulate

from ea_gym.bondgraph.simulation import hermite_coefficients
from ea_gym.env.config import EnvConfig
from ea_gym.models import get_model
from ea_gym.phm import ChainTiming, JointFilter, PHMConfig, StepSignals, calibrate_thresholds, chain_config
from ea_gym.phm.thresholds import calibration_key, calibration_settings, shipped_thresholds
from ea_gym.phm.tracking import transition

NOISE = 0.01


def with_load_noise(config: PHMConfig, load_noise: float) -> PHMConfig:
    return dataclasses.replace(config, timing=dataclasses.replace(config.timing, load_noise=load_noise))


def test_a_load_error_held_over_the_record_adds_up_to_gamma_0() -> None:
    """The derivation in ``ea_gym.phm.joint``: one sample's load error e, with the rate the central difference, perturbs
    the Hermite coefficients of the four intervals around it; their effects on the next states, summed, are
    Gamma_0 e (the rate's terms cancel)."""
    model = get_model("spring_mass_damper")
    h = 1.0 / RATE
    step = transition(model, model.parameter_vector(), h)  # (nx, nx + 4): [Phi | Gamma_0 .. Gamma_3]
    nx = len(model.state_names)
    error = np.zeros(9)
    error[4] = 0.37  # one sample's error, far from the ends
    w = hermite_coefficients(error[:, None], np.gradient(error, h)[:, None], h)  # (8, 4)
    effects = w @ step[:, nx:].T  # (8, nx): each interval's extra input to the states
    np.testing.assert_allclose(effects.sum(axis=0), 0.37 * step[:, nx], rtol=1e-9, atol=1e-15)
    assert np.count_nonzero(np.abs(effects).sum(axis=1) > 1e-12 * np.abs(step[:, nx]).max()) == 4


@pytest.mark.parametrize("system", ["rlc_circuit", "dc_motor"])
def test_the_filters_innovations_match_their_predicted_covariance_only_with_the_load_noise_in_it(system: str) -> None:
    """3 % noise on the load: told, the joint filter's normalized innovations squared sit at their degrees of freedom
    (measured 0.91-1.00 per degree); not told, far above (2.8-4.4)."""
    model = get_model(system)
    records = [simulate(system, seed, 60.0, load_noise=0.03) for seed in (5, 6)]
    nis = {}
    for told in (0.0, 0.03):
        joint = JointFilter(model, RATE, NOISE, 2, load_noise=told)
        terms = []
        for s in range(59):
            part = slice(s * 100, s * 100 + 101)
            signals = StepSignals(
                measured=np.stack([r.measured[:, part] for r in records]), load=np.stack([r.load[part] for r in records]),
                load_rate=np.stack([r.load_rate[part] for r in records]), t=np.full(2, s + 1.0),
            )
            joint.update(signals, np.zeros(2, dtype=bool), np.ones((2, len(joint.degradable)), dtype=bool))
            step = joint.innovations()
            if s >= 10:
                terms.append(step.nis / step.dof)
        nis[told] = np.mean(terms, axis=0)
    assert np.all((nis[0.03] > 0.85) & (nis[0.03] < 1.15))
    assert np.all(nis[0.0] > 2.0)


def test_an_exact_load_keeps_its_thresholds_key_and_a_noisy_one_raises_the_thresholds() -> None:
    model = get_model("spring_mass_damper")
    exact = EnvConfig().phm_config  # the environments' settings, whose thresholds are shipped
    assert "load_noise" not in calibration_settings(exact)
    assert calibration_key(model, exact, np.random.default_rng(0)) in shipped_thresholds()
    noisy = with_load_noise(exact, 0.01)
    assert calibration_settings(noisy)["load_noise"] == 0.01
    assert calibration_key(model, noisy, np.random.default_rng(0)) != calibration_key(model, exact, np.random.default_rng(0))
    quick = dataclasses.replace(exact, detector=dataclasses.replace(exact.detector, calibration_runs=2, calibration_duration=60.0))
    base = calibrate_thresholds(model, quick, np.random.default_rng(3))
    raised = calibrate_thresholds(model, with_load_noise(quick, 0.01), np.random.default_rng(3))
    assert np.all(raised[:-1] > 3 * base[:-1])  # every element's: the reference runs on the noisy load
    with pytest.raises(ValueError, match="load_noise"):
        ChainTiming(load_noise=-0.01)


@pytest.fixture(scope="module")
def noisy_load_runs() -> dict[str, tuple[list, list]]:
    """A k ramp (from 40 s, 4e-3 of its span per s) on 5 records under a band-limited random load, exact and with 1 %
    load noise, each through a chain told the load's noise; and 5 healthy records with 1 % load noise."""
    onset, slope, seeds = 40.0, -4e-3 * 20.0, range(20, 25)
    runs = {}
    for load_noise in (0.0, 0.01):
        records = [simulate("spring_mass_damper", s, 120.0, (Fault("k", onset, slope),), load_noise=load_noise, random_load=True) for s in seeds]
        chain = chain_for("spring_mass_damper", 5, with_load_noise(chain_config(RATE, NOISE), load_noise))
        runs[f"ramp {load_noise}"] = (records, run_chain(chain, records))
    healthy = [simulate("spring_mass_damper", s, 120.0, load_noise=0.01, random_load=True) for s in range(30, 35)]
    runs["healthy"] = (healthy, run_chain(chain_for("spring_mass_damper", 5, with_load_noise(chain_config(RATE, NOISE), 0.01)), healthy))
    return runs


def test_a_healthy_machine_read_with_a_noisy_load_raises_no_alarm_and_names_no_part(noisy_load_runs: dict) -> None:
    _, statuses = noisy_load_runs["healthy"]
    assert not any(s.alarm.any() for s in statuses)
    assert not any(s.parts is not None and s.parts.named.any() for s in statuses)


def test_a_fault_read_with_a_noisy_load_is_not_seen_before_it_begins_and_is_estimated(noisy_load_runs: dict) -> None:
    errors = {}
    for load_noise in (0.0, 0.01):
        records, statuses = noisy_load_runs[f"ramp {load_noise}"]
        detection = statuses[-1].detection_time
        assert np.all(np.isfinite(detection) & (detection >= 40.0))  # found, and not before the onset
        t = np.array([s.t[0] for s in statuses])
        late = t >= 70.0
        k = statuses[0].parts.names.index("k")
        value = np.array([s.parts.value[:, k] for s in statuses])[late]
        truth = np.array([r.parameter("k")[np.round(t[late] * RATE).astype(int)] for r in records]).T
        errors[load_noise] = np.median(np.abs(value - truth)) / 20.0
        assert all(s.parts.named[:, k].all() for s in np.array(statuses)[late])
    # measured 0.24 % and 0.47 % of the span (module docstring: 1.96 x, not issue 30's 1.5 x)
    assert errors[0.0] < 0.005 and errors[0.01] < 0.01
    assert errors[0.01] < 2.5 * errors[0.0]
