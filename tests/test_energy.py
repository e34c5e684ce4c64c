"""Element power (Table 1), Energy Activity (eq 4/7), its index (eq 5) and the streaming accumulator."""

import numpy as np
import pytest
from scipy.integrate import trapezoid

from ea_gym import models
from ea_gym.energy import (
    EnergyActivityAccumulator,
    activity_index,
    activity_shares,
    component_activity_index,
    constitutive_power,
    cumulative_energy_activity,
    energy_activity,
    step_activity_index,
    window_samples,
)
from ea_gym.loads import Sine, SinesLoad
from ea_gym.plant import run_model

H = 0.01
LOAD = SinesLoad(10.0, (Sine(5.0, 0.3),))


@pytest.fixture(scope="module")
def smd():
    """The spring-mass-damper (m=10, k=100, b=0.5) under a slow sine load, 30 s at 100 Hz, from rest."""
    model = models.spring_mass_damper()
    return run_model(model, np.linspace(0.0, 30.0, 3001), LOAD)


@pytest.fixture(scope="module")
def smd_drifting():
    """The same with the stiffness drifting from 100 to 90 N/m over the 30 s."""
    model = models.spring_mass_damper()

    def parameters(t):
        t = np.asarray(t, dtype=float)
        return np.stack([np.full_like(t, 10.0), 100.0 - 10.0 * t / 30.0, np.full_like(t, 0.5)], axis=-1)

    return run_model(model, np.linspace(0.0, 30.0, 3001), LOAD, parameters)


def assert_close_to_scale(actual, expected, rel):
    """|actual - expected| <= rel * max|expected| at every sample."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    assert actual.shape == expected.shape
    scale = np.abs(expected).max()
    assert scale > 0
    error = np.abs(actual - expected).max() / scale
    assert error <= rel, error


def rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


# --------------------------------------------------------------------------------------------------
# constitutive power (Table 1) against e * f of a simulation


def test_resistor_power_in_both_causalities(smd):
    b = 0.5
    # flow in: P = f * b f; effort in: P = e * e / b; both equal the simulated e * f
    assert_close_to_scale(constitutive_power("R", "flow", smd.flow["b"], b, H), smd.power["b"], 1e-12)
    assert_close_to_scale(constitutive_power("R", "effort", smd.effort["b"], b, H), smd.power["b"], 1e-12)


@pytest.mark.parametrize("fixture", ["smd", "smd_drifting"])
def test_storage_power_in_integral_causality_with_known_energy_variable(fixture, request):
    traj = request.getfixturevalue(fixture)
    m, k = traj.parameters[:, 0], traj.parameters[:, 1]
    p, q = traj.states[:, 0], traj.states[:, 1]
    # C (spring) takes its flow: P = f * k q;  I (mass) takes its effort: P = e * p / m
    spring = constitutive_power("C", "flow", traj.flow["k"], k, H, c_form="stiffness", integral=q)
    mass = constitutive_power("I", "effort", traj.effort["m"], m, H, integral=p)
    assert_close_to_scale(spring, traj.power["k"], 1e-12)
    assert_close_to_scale(mass, traj.power["m"], 1e-12)
    # the same spring written as a compliance 1/k
    compliance = constitutive_power("C", "flow", traj.flow["k"], 1.0 / k, H, c_form="capacitance", integral=q)
    assert_close_to_scale(compliance, traj.power["k"], 1e-12)


def test_storage_power_in_integral_causality_integrating_the_input(smd):
    # without the energy variable the input is integrated from zero (the run starts at rest), which
    # only costs the trapezoidal rule's O(h^2) error
    spring = constitutive_power("C", "flow", smd.flow["k"], 100.0, H, c_form="stiffness")
    mass = constitutive_power("I", "effort", smd.effort["m"], 10.0, H)
    assert_close_to_scale(spring, smd.power["k"], 1e-3)
    assert_close_to_scale(mass, smd.power["m"], 1e-3)


def test_storage_power_in_derivative_causality(smd):
    # C takes its effort: f = (1/k) de/dt;  I takes its flow: e = m df/dt. np.gradient's central
    # differences are O(h^2) inside and first order at both ends: within 1e-3 of the RMS power.
    spring = constitutive_power("C", "effort", smd.effort["k"], 100.0, H, c_form="stiffness")
    mass = constitutive_power("I", "flow", smd.flow["m"], 10.0, H)
    for derived, simulated in ((spring, smd.power["k"]), (mass, smd.power["m"])):
        assert rms(derived - simulated) <= 1e-3 * rms(simulated)
        # and np.gradient itself is what is used: the difference from it is round-off
    np.testing.assert_allclose(
        mass, smd.flow["m"] * 10.0 * np.gradient(smd.flow["m"], H), rtol=0, atol=1e-14 * np.abs(mass).max()
    )


def test_constitutive_power_hand_computed_cases():
    # R: P = R f^2 (flow in), e^2 / R (effort in)
    np.testing.assert_allclose(constitutive_power("R", "flow", np.array([1.0, -2.0, 3.0]), 2.0, 1.0), [2.0, 8.0, 18.0])
    np.testing.assert_allclose(constitutive_power("R", "effort", np.array([2.0, -4.0]), 2.0, 1.0), [2.0, 8.0])
    # C, integral, q integrated by the trapezoid from 0: f = 1 for h = 0.5 -> q = 0, 0.5, 1;
    # e = k q with k = 4 (or q / C with C = 0.25) -> P = f e = 0, 2, 4
    ones = np.ones(3)
    np.testing.assert_allclose(constitutive_power("C", "flow", ones, 4.0, 0.5, c_form="stiffness"), [0.0, 2.0, 4.0])
    np.testing.assert_allclose(constitutive_power("C", "flow", ones, 0.25, 0.5), [0.0, 2.0, 4.0])
    # C, integral, q known: P = f q / C = [2 * 1 / 0.5, 3 * -1 / 0.5]
    np.testing.assert_allclose(
        constitutive_power("C", "flow", np.array([2.0, 3.0]), 0.5, 1.0, integral=np.array([1.0, -1.0])), [4.0, -6.0]
    )
    # C, derivative: e = 0, 1, 2, 3 every 0.5 s -> de/dt = 2; f = C de/dt = 1 (C = 0.5, or k = 2) -> P = e
    e = np.array([0.0, 1.0, 2.0, 3.0])
    np.testing.assert_allclose(constitutive_power("C", "effort", e, 0.5, 0.5), e)
    np.testing.assert_allclose(constitutive_power("C", "effort", e, 2.0, 0.5, c_form="stiffness"), e)
    # I, integral: e = 2 every 0.25 s -> p = 0, 0.5, 1; f = p / I with I = 4 -> P = e f = 0, 0.25, 0.5
    np.testing.assert_allclose(constitutive_power("I", "effort", np.full(3, 2.0), 4.0, 0.25), [0.0, 0.25, 0.5])
    # I, integral with p known: P = e p / I
    np.testing.assert_allclose(
        constitutive_power("I", "effort", np.array([3.0, -1.0]), 2.0, 1.0, integral=np.array([4.0, 6.0])), [6.0, -3.0]
    )
    # I, derivative: f = 1, 2, 3, 4 every 0.5 s -> df/dt = 2; e = I df/dt = 6 (I = 3) -> P = 6 f
    f = np.array([1.0, 2.0, 3.0, 4.0])
    np.testing.assert_allclose(constitutive_power("I", "flow", f, 3.0, 0.5), 6.0 * f)


def test_constitutive_power_works_over_leading_axes():
    # two signals at once, each with its own component value; time on the last axis
    S = np.array([[1.0, 1.0, 1.0], [2.0, 2.0, 2.0]])
    values = np.array([[4.0], [1.0]])
    out = constitutive_power("C", "flow", S, values, 0.5, c_form="stiffness")
    # q = 0, 0.5, 1 and 0, 1, 2; P = S k q
    np.testing.assert_allclose(out, [[0.0, 2.0, 4.0], [0.0, 2.0, 4.0]])
    out = constitutive_power("I", "flow", np.array([[0.0, 1.0, 2.0], [0.0, 2.0, 4.0]]), 1.0, 1.0)
    np.testing.assert_allclose(out, [[0.0, 1.0, 2.0], [0.0, 4.0, 8.0]])


@pytest.mark.parametrize("kind", ["Se", "Sf", "TF", "0"])
def test_constitutive_power_rejects_non_rci_kinds(kind):
    with pytest.raises(ValueError, match="kind must be R, C or I"):
        constitutive_power(kind, "flow", np.ones(3), 1.0, 1.0)


# --------------------------------------------------------------------------------------------------
# energy activity


def test_energy_activity_hand_computed_small_case():
    # |P| = 0, 1, 1, 2 every 0.5 s; trapezoids: 0.25, 0.5, 0.75
    P = np.array([0.0, 1.0, -1.0, 2.0])
    np.testing.assert_allclose(energy_activity(P, 0.5), [1.5], rtol=1e-15)
    np.testing.assert_allclose(energy_activity(P, 0.5, window=0.5), [0.25, 0.5, 0.75], rtol=1e-15)
    # 1 s windows: the first covers two intervals, the trailing partial one is left out
    np.testing.assert_allclose(energy_activity(P, 0.5, window=1.0), [0.75], rtol=1e-15)
    np.testing.assert_allclose(energy_activity(P, 0.5, window=1.5), [1.5], rtol=1e-15)


def test_energy_activity_of_a_sine():
    h = 0.01
    t = np.arange(201) * h  # [0, 2] s: two periods of sin(2 pi t)
    P = np.sin(2 * np.pi * t)
    whole = energy_activity(P, h)
    assert whole.shape == (1,)
    np.testing.assert_allclose(whole[0], trapezoid(np.abs(P), dx=h), rtol=1e-13)
    # the exact integral of |sin(2 pi t)| over two periods is 4 / pi; trapezoid error O(h^2)
    np.testing.assert_allclose(whole[0], 4 / np.pi, rtol=1e-3)
    # half-period windows each hold one hump of area 1 / pi (to O(h^2)), and equal the trapezoid of the slice
    halves = energy_activity(P, h, window=0.5)
    assert halves.shape == (4,)
    for i in range(4):
        np.testing.assert_allclose(halves[i], trapezoid(np.abs(P[50 * i : 50 * i + 51]), dx=h), rtol=1e-13)
    np.testing.assert_allclose(halves, 1 / np.pi, rtol=1e-3)


def test_energy_activity_of_a_constant_power_is_exact():
    # dyadic numbers: every step is exact in floating point
    P = np.full(33, -3.0)  # 32 intervals of 0.25 s = 8 s
    np.testing.assert_array_equal(energy_activity(P, 0.25, window=2.0), [6.0, 6.0, 6.0, 6.0])
    np.testing.assert_array_equal(energy_activity(P, 0.25), [24.0])
    # a decimal period: exact up to round-off
    c, h, window = 2.5, 0.01, 1.0
    P = np.full(1001, c)
    np.testing.assert_allclose(energy_activity(P, h, window=window), np.full(10, c * window), rtol=1e-12)


def test_energy_activity_keeps_leading_axes_and_mappings():
    rng = np.random.default_rng(3)
    P = rng.normal(size=(2, 3, 401))
    out = energy_activity(P, 0.01, window=1.0)
    assert out.shape == (2, 3, 4)
    for i in range(2):
        for j in range(3):
            np.testing.assert_allclose(out[i, j], energy_activity(P[i, j], 0.01, window=1.0), rtol=1e-15)
    mapped = energy_activity({"a": P[0, 0], "b": P[1, 2]}, 0.01, window=1.0)
    assert set(mapped) == {"a", "b"}
    np.testing.assert_allclose(mapped["b"], out[1, 2], rtol=1e-15)


@pytest.mark.parametrize(("window", "period"), [(0.015, 0.01), (0.005, 0.01), (0.0, 0.01), (-1.0, 0.01), (1.0, 0.3)])
def test_window_must_be_a_whole_number_of_periods(window, period):
    with pytest.raises(ValueError, match="window"):
        energy_activity(np.ones(200), period, window=window)
    with pytest.raises(ValueError, match="window"):
        EnergyActivityAccumulator(period, window)


def test_window_samples_tolerates_decimal_round_off():
    assert window_samples(0.3, 0.1) == 3  # 0.3 / 0.1 = 2.9999999999999996
    assert window_samples(1.0, 0.01) == 100


def test_nan_or_inf_power_is_rejected():
    P = np.ones(11)
    P[4] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        energy_activity(P, 0.1)
    with pytest.raises(ValueError, match="NaN"):
        energy_activity(P, 0.1, window=0.5)
    with pytest.raises(ValueError, match="NaN"):
        cumulative_energy_activity(P, 0.1)
    P[4] = np.inf
    with pytest.raises(ValueError, match="inf"):
        energy_activity(P, 0.1)


# --------------------------------------------------------------------------------------------------
# energy activity index


def test_activity_index_hand_computed():
    eai = activity_index({"a": np.array([1.0, 0.0, 2.0]), "b": np.array([3.0, 0.0, 0.0])})
    np.testing.assert_allclose(eai["a"], [0.25, 0.5, 1.0])
    np.testing.assert_allclose(eai["b"], [0.75, 0.5, 0.0])
    with pytest.raises(ValueError):
        activity_index({})


def test_component_activity_index_by_rows_hand_computed():
    # rows are systems, columns elements; the components are columns 0 and 2 (column 1 is no component)
    ea = np.array([[1.0, 5.0, 3.0], [0.0, 7.0, 0.0], [2.0, 0.0, 2.0]])
    eai = component_activity_index(ea, np.array([0, 2]), ("R", "C"))
    np.testing.assert_array_equal(eai, [[0.25, 0.75], [0.5, 0.5], [0.5, 0.5]])  # no activity: an even share
    assert eai.flags.c_contiguous
    with pytest.raises(ValueError, match="'C'"):
        component_activity_index(np.array([[1.0, 0.0, -1.0]]), np.array([0, 2]), ("R", "C"))


@pytest.mark.parametrize("rows", [1, 2, 3, 512])
def test_component_activity_index_is_activity_shares_to_the_bit(rows):
    # compiled: numpy's order of the sum (pairwise over one row's many components, row after row for several)
    rng = np.random.default_rng(rows)
    for components in (1, 3, 8, 9, 17, 40):
        ea = np.abs(rng.normal(size=(rows, components + 2))) * 10.0 ** rng.integers(-5, 5, size=(rows, components + 2))
        ea[rng.random(ea.shape) < 0.1] = 0.0
        columns = rng.permutation(components + 2)[:components]
        names = [f"c{k}" for k in range(components)]
        expected = activity_shares(np.ascontiguousarray(ea.T[columns]), names).T
        np.testing.assert_array_equal(component_activity_index(ea, columns, names).view(np.int64), expected.view(np.int64))


def test_activity_index_of_a_simulation_sums_to_one(smd):
    model = smd.model
    assert model.rco_elements == ("m", "k", "b")
    power = {name: smd.power[name].copy() for name in model.rco_elements}
    # make the first 1 s window silent: all three powers zero on samples 0..100
    for name in power:
        power[name][:101] = 0.0
    ea = energy_activity(power, H, window=1.0)
    assert all(v.shape == (30,) for v in ea.values())
    eai = activity_index(ea)
    stacked = np.stack([eai[name] for name in model.rco_elements])
    np.testing.assert_allclose(stacked.sum(axis=0), 1.0, rtol=0, atol=1e-12)
    assert np.all(stacked >= 0.0) and np.all(stacked <= 1.0)
    # the silent window is shared equally; the others are the EA shares
    np.testing.assert_array_equal(stacked[:, 0], np.full(3, 1.0 / 3.0))
    total = sum(ea.values())
    assert np.all(total[1:] > 0)
    for name in model.rco_elements:
        np.testing.assert_allclose(eai[name][1:], ea[name][1:] / total[1:], rtol=1e-14)
    # all three elements do work in every active window
    assert np.all(stacked[:, 1:] > 0)


# --------------------------------------------------------------------------------------------------
# cumulative and streaming energy activity


def test_cumulative_energy_activity(smd):
    P = np.stack([smd.power[name] for name in ("m", "k", "b", "F")])
    cumulative = cumulative_energy_activity(P, H)
    assert cumulative.shape == P.shape
    np.testing.assert_array_equal(cumulative[:, 0], 0.0)
    assert np.all(np.diff(cumulative, axis=-1) >= 0.0)
    np.testing.assert_allclose(cumulative[:, -1], energy_activity(P, H)[:, 0], rtol=1e-12)
    # at every window boundary it is the sum of the windows so far
    windows = energy_activity(P, H, window=1.0)
    np.testing.assert_allclose(cumulative[:, 100::100], np.cumsum(windows, axis=-1), rtol=1e-12)
    mapped = cumulative_energy_activity({"b": smd.power["b"]}, H)
    np.testing.assert_array_equal(mapped["b"], cumulative[2])


def test_streaming_equals_batch(smd):
    P = np.stack([smd.power[name] for name in ("m", "k", "b")])  # (3, T + 1)
    window = 0.5
    batch = energy_activity(P, H, window=window)
    rng = np.random.default_rng(0)
    accumulator = EnergyActivityAccumulator(H, window)
    outputs, start, sizes = [], 0, []
    while start < P.shape[-1]:
        size = int(rng.integers(1, 120))
        sizes.append(size)
        done = accumulator.update(P[:, start : start + size])
        assert done.shape[:-1] == (3,)
        outputs.append(done)
        start += size
    assert min(sizes) < 50 < max(sizes)  # chunks both shorter and longer than a 50-sample window
    streamed = np.concatenate(outputs, axis=-1)
    assert streamed.shape == batch.shape == (3, 60)
    assert np.array_equal(streamed, batch)
    np.testing.assert_allclose(accumulator.total, energy_activity(P, H)[:, 0], rtol=1e-12)


def test_streaming_one_sample_at_a_time():
    rng = np.random.default_rng(5)
    P = rng.normal(size=(2, 41))
    accumulator = EnergyActivityAccumulator(0.25, 1.0)
    outputs = [accumulator.update(P[:, i : i + 1]) for i in range(P.shape[-1])]
    # a window completes at samples 4, 8, ..., 40
    completed = [i for i, out in enumerate(outputs) if out.shape[-1]]
    assert completed == [4, 8, 12, 16, 20, 24, 28, 32, 36, 40]
    assert np.array_equal(np.concatenate(outputs, axis=-1), energy_activity(P, 0.25, window=1.0))


@pytest.mark.parametrize("n", [1, 4])
def test_step_activity_index_is_its_numpy_form_to_the_bit(n):
    # the sub-windows summed as np.sum adds them (pairwise from eight on), then the shares of both sums' rows stacked
    rng = np.random.default_rng(n)
    for subs, components in ((1, 3), (5, 3), (9, 8), (140, 9)):
        elements = components + 2
        shape = (n, elements, subs)
        sub_ea, sub_ea_reference = (np.abs(rng.normal(size=shape)) * 10.0 ** rng.integers(-5, 5, size=shape) for _ in range(2))
        sub_ea[0, :, :] = 0.0  # no activity: an even share
        columns = rng.permutation(elements)[:components]
        names = [f"c{k}" for k in range(components)]
        ea, ea_reference = sub_ea.sum(-1), sub_ea_reference.sum(-1)
        shares = component_activity_index(np.concatenate([ea, ea_reference]), columns, names)
        got = step_activity_index(sub_ea, sub_ea_reference, columns, names)
        for value, expected in zip(got, (ea, ea_reference, shares[:n], shares[n:])):
            np.testing.assert_array_equal(value.view(np.int64), expected.view(np.int64))
    sub_ea_reference[-1, columns[1], 0] = np.nan
    with pytest.raises(ValueError, match="'c1'"):
        step_activity_index(sub_ea, sub_ea_reference, columns, names)
