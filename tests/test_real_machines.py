"""experiments/studies/records.py and part_tracks.py: the independent records against ea-gym's own simulation, and the
per-part scores of issue 30's acceptance on hand-built tracks."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments.studies import part_tracks, records  # noqa: E402


@pytest.mark.parametrize(("system", "rate"), [("spring_mass_damper", 100.0), ("two_mass_chain", 100.0), ("rlc_circuit", 400.0), ("dc_motor", 400.0)])
def test_the_hand_written_equations_are_the_models(system: str, rate: float) -> None:
    """Every part off nominal, two of them ramping, a random load: the ODE and ea_gym.plant.run_model agree to 1e-6 of each
    signal's amplitude. (The plant holds the load as a cubic between samples, exact to (h omega)^4: at 100 Hz the circuit's
    and the motor's 5 and 10 Hz loads leave 3e-6 and 6e-5, at 400 Hz 1e-8 and 2e-7.)"""
    rng = np.random.default_rng(7)
    machine = records.worn(records.Machine(system, records.middle_half(system, rng)), records.MULTI_PART[system][:2], scale=0.1)
    assert records.plant_agreement(machine, records.draw_load(system, "random", rng), 20.0, rate) <= 1e-6


@pytest.mark.parametrize("system", records.SYSTEMS)
def test_a_record_starts_at_rest_under_its_mean_load(system: str) -> None:
    values = records.system_model(system).parameter_vector()
    state = records.equilibrium(system, values, 7.0)
    rates = records.EQUATIONS[system](state, dict(zip(records.system_model(system).parameter_names, values)), 7.0)
    np.testing.assert_allclose(rates, 0.0, atol=1e-12)


def test_a_ramp_reaches_its_limit_at_its_end_of_life() -> None:
    machine = records.worn(records.Machine("spring_mass_damper", {"k": 95.0}), [("k", 40.0, 100.0), ("b", 55.0, 80.0)])
    k, b = machine.ramps
    assert (machine.end_of_life(k), machine.end_of_life(b)) == (pytest.approx(140.0), pytest.approx(135.0))
    values = machine.values(np.array([0.0, 40.0, 140.0, 135.0]))  # parameter order m, k, b
    np.testing.assert_allclose(values[:, 1], [95.0, 95.0, 85.0, 85.5])  # k: 95 -> 85 N/m over 40..140 s
    np.testing.assert_allclose(values[[0, 3], 2], [0.5, 0.6])  # b: 0.5 -> 0.6 N s/m at 135 s
    with pytest.raises(ValueError, match="one ramp per part"):
        records.Machine("spring_mass_damper", ramps=(k, k))


def test_the_noise_is_a_fraction_of_each_blocks_rms() -> None:
    rng = np.random.default_rng(0)
    signals = np.concatenate([np.full((5000, 2), 2.0), np.full((5000, 2), -0.5)]) * np.array([1.0, 10.0])
    noise = records.block_noise(signals, 0.01, 5000, rng) - signals
    for block, level in ((slice(0, 5000), 2.0), (slice(5000, None), 0.5)):
        np.testing.assert_allclose(noise[block].std(axis=0), 0.01 * level * np.array([1.0, 10.0]), rtol=0.05)


def test_the_load_noise_leaves_the_sensors_noise_as_it_was() -> None:
    exact, _ = records.case_record("rlc_circuit", "single part", 1, scale=0.2)
    noisy, _ = records.case_record("rlc_circuit", "single part", 1, scale=0.2, load_noise=0.01)
    np.testing.assert_array_equal(exact.measurements.signals, noisy.measurements.signals)
    difference = noisy.measurements.load - exact.measurements.load
    assert 0.005 < difference.std() / np.sqrt(np.mean(exact.load**2)) < 0.015


def track(t: np.ndarray, named: np.ndarray, eol: np.ndarray, low: np.ndarray, high: np.ndarray) -> part_tracks.PartTrack:
    """A spring-mass-damper's track (parts k, m, b) with the given named set and End of Life of each part."""
    steps = len(t)
    return part_tracks.PartTrack(
        t=t, parts=("k", "m", "b"), value=np.tile([100.0, 10.0, 0.5], (steps, 1)), std=np.ones((steps, 3)), degrading=named.astype(float),
        named=named, eol=eol, eol_low=low, eol_high=high, alarm=np.zeros(steps, dtype=bool), isolated=np.full(steps, -1),
        fits=np.ones(steps, dtype=bool), misfit=np.zeros(steps, dtype=bool), machine_eol=np.full(steps, np.inf),
    )


def test_the_set_named_counts_from_30_s_after_each_onset() -> None:
    machine = records.Machine("spring_mass_damper", ramps=(records.Ramp("k", 10.0, -0.1), records.Ramp("b", 50.0, 0.001)))
    t = np.arange(1.0, 101.0)
    named = np.zeros((100, 3), dtype=bool)
    named[t > 20, 0] = True  # k named 10 s after its onset
    named[t > 90, 2] = True  # b 40 s after its onset
    right = part_tracks.set_named_right(track(t, named, *np.full((3, 100, 3), np.inf)), machine)
    # counted: 40..50 and 80..100 (the 30 s after b's onset left out): 11 + 21 steps, of which 80..90 wrong
    assert len(right) == 32 and right.sum() == 21


def test_alpha_lambda_and_coverage_count_every_prediction_of_the_span() -> None:
    machine = records.Machine("spring_mass_damper", ramps=(records.Ramp("k", 0.0, -0.15),))  # 100 -> 85 N/m at 100 s
    t = np.arange(1.0, 101.0)
    eol = np.full((100, 3), np.inf)
    eol[:, 0] = np.where(t < 70, 100.0, 150.0)  # right until 69 s, then 50 s late
    low, high = eol - 5.0, eol + 5.0
    high[t == 60, 0] = np.inf  # an unbounded interval misses
    alpha, covered = part_tracks.prognosis_hits(track(t, np.zeros((100, 3), dtype=bool), eol, low, high), machine)["k"]
    # predictions at 50..90 s: true RUL 50..10 s; 50..69 s right (20), 70..90 s 50 s late: RUL 80..60 s against 30..10 s
    assert len(alpha) == 41 and alpha.sum() == 20 and covered.sum() == 19


def test_the_first_alarm_is_any_alarm_name_or_end_of_life() -> None:
    t = np.arange(1.0, 11.0)
    quiet = track(t, np.zeros((10, 3), dtype=bool), *np.full((3, 10, 3), np.inf))
    assert part_tracks.first_alarm(quiet) == np.inf
    assert part_tracks.first_alarm(replace(quiet, alarm=t >= 7)) == 7.0
    assert part_tracks.first_alarm(replace(quiet, machine_eol=np.where(t >= 4, 50.0, np.inf))) == 4.0


def test_estimate_errors_count_from_10_s_after_the_first_onset() -> None:
    machine = records.Machine("spring_mass_damper", ramps=(records.Ramp("m", 20.0, 0.01),))
    t = np.arange(1.0, 51.0)
    errors = part_tracks.estimate_errors(track(t, np.zeros((50, 3), dtype=bool), *np.full((3, 50, 3), np.inf)), machine)
    assert len(errors["m"]) == 21  # 30..50 s
    np.testing.assert_allclose(errors["m"], 0.01 * (np.arange(30.0, 51.0) - 20.0))
    np.testing.assert_allclose(errors["k"], 0.0)


def test_a_part_is_named_from_the_naming_probability_until_it_falls_below_the_release() -> None:
    probability = np.array([[0.1, 0.95], [0.92, 0.6], [0.7, 0.49], [0.4, 0.5], [0.9, 0.91]])
    named = part_tracks.hysteresis(probability, name=0.9, release=0.5)
    assert named.tolist() == [[False, True], [True, True], [True, False], [False, False], [True, True]]
