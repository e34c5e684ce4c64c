"""Every compiled kernel of ``ea_gym._kernels`` against a plain numpy (or scipy) form of the same arithmetic."""

import numpy as np
import pytest
from scipy import linalg
from scipy.signal import savgol_filter

from ea_gym._kernels.activity import interval_activities, trapezoid_activity, trapezoid_area
from ea_gym._kernels.detection import detect
from ea_gym._kernels.expm import PADE13, expm_batch, matmul, pade_polynomial, solve
from ea_gym._kernels.monitor import (
    EnergyWindows,
    NominalLaws,
    Smoothing,
    chunk_statistics,
    copy,
    element_powers,
    load_sources,
    padded_chunk,
    same,
    smooth_rows,
)
from ea_gym._kernels.multisine import multisine_rotations, rotated_multisine
from ea_gym._kernels.prognosis import drift_ends, drift_prognosis
from ea_gym._kernels.propagation import propagate_states, simulate_hermite
from ea_gym._kernels.smoothing import LANES, filter_into, filter_lanes, filter_rows
from ea_gym._kernels.wear import mean_trend_rul, steady_wear
from ea_gym.bondgraph.simulation import hermite_coefficients
from ea_gym.diagnosis.smoothing import SavitzkyGolay
from ea_gym.numerics import TINY
from ea_gym.phm.detection import relative_residuals

H = 0.01  # sample period (s)


def _rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


# --- activity: the one EA trapezoid ---------------------------------------------------------------


def test_trapezoid_area_is_the_trapezoid_of_the_magnitudes():
    assert trapezoid_area(-2.0, 4.0, 0.5) == 0.5 * (2.0 + 4.0) * 0.5


def test_trapezoid_activity_equals_numpy_trapezoid_of_the_magnitude():
    power = _rng().standard_normal(1001)
    for start, stop in [(0, 1000), (100, 200), (5, 5)]:
        exact = np.trapezoid(np.abs(power[start : stop + 1]), dx=H)
        assert trapezoid_activity(power, start, stop, H) == pytest.approx(exact, rel=1e-13, abs=0.0)


def test_interval_activities_equal_the_numpy_formula_to_the_bit():
    power = _rng(1).standard_normal((3, 257))
    magnitude = np.abs(power)
    np.testing.assert_array_equal(interval_activities(power, H), 0.5 * (magnitude[:, :-1] + magnitude[:, 1:]) * H)
    np.testing.assert_allclose(interval_activities(power, H).sum(-1), np.trapezoid(magnitude, dx=H, axis=-1), rtol=1e-13)
    assert interval_activities(np.zeros((2, 1)), H).shape == (2, 0)


# --- smoothing: Savitzky-Golay ------------------------------------------------------------------


@pytest.mark.parametrize("deriv", [0, 1])
def test_filter_rows_and_filter_into_equal_savgol_filter(deriv):
    x = _rng(2).standard_normal((5, 160)).cumsum(-1)
    sg = SavitzkyGolay(51, 3, H)
    exact = savgol_filter(x, 51, 3, deriv=deriv, delta=H, axis=-1, mode="interp")
    np.testing.assert_allclose(filter_rows(x, *sg.coefficients(deriv)), exact, rtol=0, atol=1e-12 * np.abs(exact).max())
    one = np.empty(x.shape[1])
    filter_into(x[0], one, *sg.coefficients(deriv))
    np.testing.assert_allclose(one, exact[0], rtol=0, atol=1e-12 * np.abs(exact).max())


def test_filter_lanes_equals_savgol_filter():
    x = _rng(3).standard_normal((180, LANES)).cumsum(0)
    sg = SavitzkyGolay(51, 3, H)
    smooth, slope = np.empty_like(x), np.empty_like(x)
    filter_lanes(x, 0, sg.moments(), sg.lane_coefficients(0), sg.lane_coefficients(1), True, smooth, slope)
    for deriv, out in ((0, smooth), (1, slope)):
        exact = savgol_filter(x, 51, 3, deriv=deriv, delta=H, axis=0, mode="interp")
        bound = 2e-13 * np.abs(x).max() * np.abs(sg.coefficients(deriv)[0]).sum()
        np.testing.assert_allclose(out, exact, rtol=0, atol=bound)


# --- multisine loads ------------------------------------------------------------------------------


def test_multisine_rotations_equal_the_numpy_formula():
    frequencies = _rng(4).uniform(0.1, 5.0, (3, 7))
    rotation = multisine_rotations(frequencies, H)
    omega = 2.0 * np.pi * frequencies
    np.testing.assert_array_equal(rotation[:, 0], omega)
    np.testing.assert_allclose(rotation[:, 1], np.sin(omega * H), rtol=0, atol=1e-15)
    np.testing.assert_allclose(rotation[:, 2], np.cos(omega * H), rtol=0, atol=1e-15)


def test_rotated_multisine_equals_the_numpy_sum_of_sines():
    rng = _rng(5)
    n, components, samples = 70, 9, 400  # more systems than one block, more samples than one rotation span
    frequencies, phases = rng.uniform(0.1, 5.0, (n, components)), rng.uniform(0.0, 2 * np.pi, (n, components))
    t = rng.uniform(0.0, 10.0, (n, 1)) + H * np.arange(samples)
    waves, slopes = rotated_multisine(t, phases, multisine_rotations(frequencies, H))
    omega = 2.0 * np.pi * frequencies
    angle = t[:, :, None] * omega[:, None, :] + phases[:, None, :]
    np.testing.assert_allclose(waves, np.sin(angle).sum(-1), rtol=0, atol=1e-12 * components)
    np.testing.assert_allclose(slopes, (np.cos(angle) * omega[:, None, :]).sum(-1), rtol=0, atol=1e-12 * np.abs(omega).sum(-1).max())


# --- matrix exponential ---------------------------------------------------------------------------


def test_matmul_and_solve_equal_numpy():
    rng = _rng(6)
    a, b = rng.standard_normal((2, 6, 6))
    c = np.empty((6, 6))
    matmul(a, b, c)
    np.testing.assert_allclose(c, a @ b, rtol=1e-13, atol=1e-13)
    x = b.copy()
    solve(a.copy(), x)
    np.testing.assert_allclose(x, np.linalg.solve(a, b), rtol=1e-10, atol=1e-12)


def test_pade_polynomial_equals_the_numpy_formula():
    rng = _rng(7)
    A2, A4, A6 = rng.standard_normal((3, 4, 4)) * 0.1
    c = PADE13[0::2]
    out, workspace = np.empty((4, 4)), np.empty((4, 4))
    pade_polynomial(A2, A4, A6, c, workspace, out)
    exact = A6 @ (c[6] * A6 + c[5] * A4 + c[4] * A2) + c[3] * A6 + c[2] * A4 + c[1] * A2 + c[0] * np.eye(4)
    np.testing.assert_allclose(out, exact, rtol=1e-13, atol=1e-13 * np.abs(exact).max())


@pytest.mark.parametrize("norm", [0.01, 1.0, 40.0])
def test_expm_batch_equals_scipy(norm):
    Z = _rng(8).standard_normal((5, 6, 6))
    Z *= norm / np.abs(Z).sum(axis=1).max(axis=1)[:, None, None]
    exact = linalg.expm(Z)
    out = np.empty_like(Z)
    expm_batch(Z, out)
    np.testing.assert_allclose(out, exact, rtol=0, atol=1e-13 * np.abs(exact).max())


# --- propagation ----------------------------------------------------------------------------------


def _recursion(Phi, Gamma, w, x0):
    x = np.empty((w.shape[0], w.shape[1] + 1, x0.shape[1]))
    x[:, 0] = x0
    for k in range(w.shape[1]):
        kp = k if Phi.shape[1] > 1 else 0
        x[:, k + 1] = (Phi[:, kp] @ x[:, k, :, None])[..., 0] + (Gamma[:, kp] @ w[:, k, :, None])[..., 0]
    return x


@pytest.mark.parametrize("steps_of_matrices", [1, 20])
def test_propagate_states_equals_the_numpy_recursion(steps_of_matrices):
    rng = _rng(9)
    n, steps, nx, m = 3, 20, 4, 8
    Phi = 0.3 * rng.standard_normal((n, steps_of_matrices, nx, nx))
    Gamma = rng.standard_normal((n, steps_of_matrices, nx, m))
    w, x0 = rng.standard_normal((n, steps, m)), rng.standard_normal((n, nx))
    np.testing.assert_allclose(propagate_states(Phi, Gamma, w, x0), _recursion(Phi, Gamma, w, x0), rtol=1e-12, atol=1e-12)


def test_simulate_hermite_equals_the_recursion_on_hermite_coefficients():
    rng = _rng(10)
    n, samples, nx, nu, distinct = 130, 40, 3, 2, 4  # more systems than one block, more samples than one chunk
    Phi = 0.3 * rng.standard_normal((distinct, nx, nx))
    Gamma = 0.1 * rng.standard_normal((distinct, nx, 4 * nu))
    index = rng.integers(0, distinct, n)
    u, du = rng.standard_normal((2, n, samples, nu))
    x0, gain = rng.standard_normal((n, nx)), rng.uniform(0.5, 2.0, (n, nx))
    signals, last = np.empty((n, nx, samples)), np.empty((n, nx))
    simulate_hermite(Phi, Gamma, index, u, du, np.arange(n), H, x0, gain, signals, last)
    x = _recursion(Phi[index][:, None], Gamma[index][:, None], hermite_coefficients(u, du, H), x0)
    np.testing.assert_allclose(signals, x.transpose(0, 2, 1) * gain[:, :, None], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(last, x[:, -1], rtol=1e-10, atol=1e-12)


# --- monitor ----------------------------------------------------------------------------------------


def test_copy_and_same():
    source, target = np.arange(10.0), np.zeros(6)
    copy(source, 7, target, 2)
    np.testing.assert_array_equal(target, [0, 0, 7, 8, 9, 0])
    assert same(np.array([9.0, 1, 2]), np.array([5.0, 1, 2]), 1)
    assert not same(np.array([9.0, 1, 2]), np.array([9.0, 1, 3]), 0)


def test_load_sources_point_at_the_first_equal_neighbour_or_twin():
    load = np.array([[0, 1, 2], [9, 1, 2], [0, 5, 5], [7, 1, 2], [8, 1, 2], [0, 6, 6]], dtype=float)
    rows = np.zeros((6, 2, 3))
    rows[:, 1] = load
    source, distinct = load_sources(rows, 1, 1)
    # from sample 1 on: row 1 repeats its predecessor, row 3 its twin (row 0), row 4 its predecessor; rows 2 and 5 are new
    np.testing.assert_array_equal(source, [0, 0, 2, 0, 0, 5])
    np.testing.assert_array_equal(distinct, [0, 2, 5])


def test_smooth_rows_equal_savgol_filter():
    rng = _rng(11)
    M, nx, T, skip, cut = 5, 2, 150, 10, 25
    rows = rng.standard_normal((M, nx + 1, T)).cumsum(-1)
    sg = SavitzkyGolay(51, 3, H)
    inertia = np.array([[1.0, 0.0, 2.0]])  # channel 1 is an I element's flow
    smooth, slope = np.empty((M, nx + 1, T - skip - cut)), np.empty((M, 1, T - skip - cut))
    smooth_rows(rows, skip, cut, Smoothing(sg.moments(), sg.lane_coefficients(0), sg.lane_coefficients(1)), inertia, smooth, slope)
    exact = savgol_filter(rows[..., skip:], 51, 3, axis=-1, mode="interp")[..., cut:]
    exact_slope = savgol_filter(rows[:, 1, skip:], 51, 3, deriv=1, delta=H, axis=-1, mode="interp")[..., cut:]
    np.testing.assert_allclose(smooth, exact, rtol=0, atol=1e-11 * np.abs(rows).max())
    np.testing.assert_allclose(slope[:, 0], exact_slope, rtol=0, atol=1e-9 * np.abs(exact_slope).max())


def test_element_powers_equal_the_bond_value_products():
    rng = _rng(12)
    M, nx, L, bonds = 3, 2, 30, 4
    smooth, scale = rng.standard_normal((M, nx + 1, L)), rng.uniform(0.5, 2.0, nx)
    Cy, Dy = rng.standard_normal((2 * bonds, nx)), rng.standard_normal(2 * bonds)
    constant = rng.standard_normal(2 * bonds)  # what constant sources beside the load add to each bond value
    effort, flow, sign = np.array([0, 1, 2]), np.array([4, 5, 6]), np.array([1.0, -1.0, 1.0])
    inertia = np.array([[1.0, 2.0, 3.0]])  # element 2 is an I element measured on channel 1
    slope = rng.standard_normal((M, 1, L))
    power = np.empty((M, 3, L))
    element_powers(smooth, slope, NominalLaws(scale, Cy, Dy, constant, effort, flow, sign, inertia), power)
    z = np.einsum("bs,msl->mbl", Cy, smooth[:, :nx] * scale[:, None]) + Dy[None, :, None] * smooth[:, None, nx] + constant[None, :, None]
    exact = z[:, effort] * sign[None, :, None] * z[:, flow]
    exact[:, 2] = 3.0 * smooth[:, 1] * slope[:, 0]
    np.testing.assert_allclose(power, exact, rtol=1e-12, atol=1e-13)


def test_chunk_statistics_equal_numpy_sums():
    rng = _rng(13)
    n, E, nx, n_sub, n_balance, balances = 2, 4, 2, 5, 2, 3
    T = n_sub * n_balance * balances + 1
    power, smooth = rng.standard_normal((2 * n, E, T)), rng.standard_normal((2 * n, nx + 1, T))
    raw = rng.standard_normal((n, nx, T - 1))
    components, sources = np.array([1, 2, 3]), np.array([0])
    inertia = np.array([[0.0, 2.0, 1.5]])
    windows = EnergyWindows(H, n_sub, n_balance, components, sources)
    finite, ea, residual, gram, cross, noise = chunk_statistics(power, smooth, raw, windows, inertia)
    assert finite
    areas = 0.5 * (power[..., :-1] + power[..., 1:]) * H
    np.testing.assert_allclose(ea, _sub_sums(np.abs(power), n_sub), rtol=1e-13)
    energy = _sub_sums_of(areas, n_sub)
    f = smooth[:, 0, ::n_sub]
    energy[:, 2] = 0.75 * (f[:, 1:] ** 2 - f[:, :-1] ** 2)
    balance = energy[:, sources].sum(1) - energy[:, components].sum(1)
    exact_residual = (balance[:n] - balance[n:]).reshape(n, balances, n_balance).sum(-1)
    stored = energy[:n][:, components].reshape(n, len(components), balances, n_balance).sum(-1).transpose(0, 2, 1)
    np.testing.assert_allclose(residual, exact_residual, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(gram, stored[..., :, None] * stored[..., None, :], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(cross, stored * exact_residual[..., None], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(noise[:, 0], ((raw - smooth[:n, :nx, 1:]) ** 2).sum(-1), rtol=1e-12)
    np.testing.assert_allclose(noise[:, 1], (raw**2).sum(-1), rtol=1e-12)
    power[0, 0, 3] = np.nan
    assert not chunk_statistics(power, smooth, raw, windows, inertia)[0]


def _sub_sums(magnitude: np.ndarray, n_sub: int) -> np.ndarray:
    """EA per sub-window of n_sub intervals by np.trapezoid."""
    subs = (magnitude.shape[-1] - 1) // n_sub
    return np.stack([np.trapezoid(magnitude[..., s * n_sub : (s + 1) * n_sub + 1], dx=H, axis=-1) for s in range(subs)], axis=-1)


def _sub_sums_of(areas: np.ndarray, n_sub: int) -> np.ndarray:
    return areas.reshape(areas.shape[:-1] + (-1, n_sub)).sum(-1)


def test_padded_chunk_mirrors_a_fresh_chunk_and_keeps_the_context():
    rng = _rng(14)
    n, nx, T, H_context = 3, 2, 12, 3
    measured, reference, load = rng.standard_normal((n, nx, T)), rng.standard_normal((n, nx, T)), rng.standard_normal((n, T))
    context = np.full((2 * n, nx + 1, H_context), np.nan)
    context[1] = 7.0  # system 1's real rows carry context from a previous chunk
    signals = np.concatenate([np.concatenate([measured, load[:, None]], 1), np.concatenate([reference, load[:, None]], 1)])
    mirrored = signals[..., H_context:0:-1]
    # systems 1 and 2 of 3: their real rows (1, 2), then their reference rows (4, 5)
    padded = np.empty((4, nx + 1, H_context + T))
    padded_chunk(measured, reference, load, context, 1, 3, padded)
    rows = [1, 2, 4, 5]
    np.testing.assert_array_equal(padded[..., H_context:], signals[rows])
    np.testing.assert_array_equal(padded[[1, 2, 3], :, :H_context], mirrored[[2, 4, 5]])
    np.testing.assert_array_equal(padded[0, :, :H_context], 7.0)
    np.testing.assert_array_equal(context[rows], signals[rows][..., T - H_context - 1 : T - 1])
    assert np.isnan(context[[0, 3]]).all()  # system 0's context is left alone


# --- prognosis: the drift End of Life ---------------------------------------------------------------


def _drift_end_of_life_numpy(value, drift, covariance, limits, t, z, diffusion):
    """``drift_end_of_life``'s arithmetic as numpy expressions over whole arrays."""
    upward = drift >= 0
    limit = np.where(upward, limits[..., 1], limits[..., 0])
    sign = np.where(upward, 1.0, -1.0)
    margin = sign * (limit - value)
    rate = sign * drift
    v_tt, v_dd = covariance[..., 0, 0], covariance[..., 1, 1]
    v_td = covariance[..., 0, 1] + 0.5 * diffusion
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = np.where(margin <= 0, 0.0, np.where(rate > 0, margin / rate, np.inf))
        a = rate**2 - z**2 * v_dd
        b = -2.0 * rate * margin - 2.0 * z**2 * v_td
        c = margin**2 - z**2 * v_tt
        root = np.sqrt(np.maximum(b**2 - 4.0 * a * c, 0.0))
        linear = -c / b
        r1, r2 = (-b - root) / (2.0 * a), (-b + root) / (2.0 * a)
        small, large = np.minimum(r1, r2), np.maximum(r1, r2)
        low = np.where(a > 0, small, np.where(a < 0, large, linear))
        low = np.where(c <= 0, 0.0, np.maximum(low, 0.0))
        high = np.where(a > 0, np.maximum(large, 0.0), np.inf)
        high = np.where((margin < 0) & (c > 0), 0.0, high)
    return np.stack([t + tau, t + low, t + high], axis=1)


def test_drift_ends_equal_the_numpy_expressions_to_the_bit():
    rng = _rng(9)
    m = 4000
    value = 100.0 + rng.normal(0.0, 8.0, m)
    drift = rng.normal(0.0, 0.5, m)
    drift[::7] = 0.0  # no drift: no End of Life
    drift[1::11] = -0.0
    root = rng.normal(0.0, 1.0, (m, 2, 2)) * np.array([2.0, 0.05])[:, None]
    covariance = root @ root.transpose(0, 2, 1)
    covariance[::13] = 0.0  # certain values: a = rate^2
    covariance[5::17, 1, 1] = drift[5::17] ** 2 / 1.959963984540054**2  # a = 0 exactly where it can be
    limits = np.column_stack([np.full(m, 90.0), np.full(m, 110.0)])
    t = rng.uniform(0.0, 500.0, m)
    diffusion = rng.uniform(0.0, 0.05, m)
    z = 1.959963984540054
    out = np.empty((m, 3))
    drift_ends(value, drift, covariance[:, 0, 0].copy(), covariance[:, 0, 1].copy(), covariance[:, 1, 1].copy(), limits[:, 0].copy(),
               limits[:, 1].copy(), t, diffusion, z**2, out)
    expected = _drift_end_of_life_numpy(value, drift, covariance, limits, t, z, diffusion)
    np.testing.assert_array_equal(out, expected)
    assert np.isinf(out).any() and (out[:, 1] == t).any()  # the cases without an End of Life and already at the limit occur


# --- detection: numpy's sums, the statistic and the alarm ------------------------------------------


def _detect_numpy(ea, ea_reference, window, balance, dissipated, steps, step_samples, span_samples, thresholds, persistence, time, state):
    """``Detector.update``'s arithmetic as numpy expressions; ``state`` (above, alarm, detection_time) updated in place."""
    statistic = relative_residuals(ea[..., -window:].sum(-1), ea_reference[..., -window:].sum(-1), balance.sum(-1), dissipated.sum(-1))
    statistic = np.where((steps * step_samples)[:, None] >= span_samples, statistic, 0.0)
    above, alarm, detection_time = state
    exceeded = np.any(np.abs(statistic) > thresholds, axis=1)
    above[:] = np.where(exceeded, above + 1, 0)
    new_alarm = ~alarm & (above >= persistence)
    detection_time[:] = np.where(new_alarm, time, detection_time)
    alarm |= new_alarm
    return statistic


def test_detect_equals_the_numpy_statistic_and_alarm_to_the_bit():
    rng = _rng(11)
    n, elements, subs, balances, window = 40, 5, 120, 60, 50
    # windows on longer arrays, as the history keeps them
    ea = rng.uniform(0.0, 2.0, (n, elements, 2 * subs))[..., 7 : 7 + subs]
    ea_reference = (ea * rng.normal(1.0, 0.05, ea.shape)).copy()[..., :]
    ea_reference[3] = 0.0  # a system at rest: the floor of the denominator
    balance = rng.normal(0.0, 0.01, (n, 2 * balances))[:, 11 : 11 + balances]
    dissipated = rng.uniform(0.0, 1.0, (n, 2 * balances))[:, 3 : 3 + balances]
    steps = rng.integers(0, 80, n)
    span_samples = np.append(np.full(elements, window * 10), balances * 100)
    thresholds = rng.uniform(0.01, 0.1, elements + 1)
    time = rng.uniform(0.0, 100.0, n)
    above = rng.integers(0, 4, n)
    alarm = rng.random(n) < 0.3
    detection_time = np.where(alarm, 1.0, np.nan)
    expected_state = (above.copy(), alarm.copy(), detection_time.copy())
    expected = _detect_numpy(ea, ea_reference, window, balance, dissipated, steps, 100, span_samples, thresholds, 3, time, expected_state)
    statistic = np.empty((n, elements + 1))
    for start, stop in ((0, 17), (17, n)):  # in two parts, as on two kernel threads
        detect(
            start, stop, ea, ea_reference, window, balance, dissipated, steps, 100, span_samples, thresholds, 3, time, TINY, above, alarm,
            detection_time, statistic,
        )
    np.testing.assert_array_equal(statistic, expected)
    for got, want in zip((above, alarm, detection_time), expected_state):
        np.testing.assert_array_equal(got, want)
    assert expected_state[1].sum() > alarm.sum() - expected_state[1].sum() >= 0 and (expected_state[0] == 0).any()


# --- wear: the linear part of a step and the true RUL ------------------------------------------------


def _wear_case(seed: int):
    rng = _rng(seed)
    n, d = 300, 3
    values = rng.uniform(0.5, 1.5, (n, d))
    faulty = rng.integers(0, d, n)
    clock = rng.uniform(0.0, 100.0, n)
    arrival = clock + rng.uniform(-5.0, 3.0, n)
    arrival[::9] = np.inf  # no fault yet
    velocity = rng.normal(0.0, 0.01, n)
    velocity[::7] = 0.0
    limits = np.array([[0.2, 1.8], [0.4, 1.6], [0.1, 1.9]])
    return values, faulty, clock, arrival, velocity, limits


def test_steady_wear_equals_the_numpy_step_to_the_bit():
    values, faulty, clock, arrival, velocity, _ = _wear_case(12)
    linear = np.array([True, False, True])
    dt = 1.0
    running = np.arange(len(values)) % 5 != 2
    columns = np.array([3, 0, 2])  # the components' columns in wider rows (a parameter vector), column 1 not wearing
    active = np.clip(clock + dt - np.maximum(arrival, clock), 0.0, dt)
    worn = np.flatnonzero(active > 0)
    means = velocity[worn] * active[worn]
    random = ~linear[faulty[worn]] & (means != 0)
    wearing = values.copy()
    steady = worn[~random]
    wearing[steady, faulty[steady]] += means[~random]
    rows = np.full((len(values), 4), 7.0)
    rows[:, columns] = values
    expected = rows.copy()
    expected[:, columns] = np.where(running[:, None], wearing, values)
    out, seconds = rows.copy(), np.empty(len(values))
    drawn = steady_wear(out, columns, running, faulty, arrival, velocity, clock, dt, linear, seconds)
    np.testing.assert_array_equal(out, expected)
    np.testing.assert_array_equal(seconds, active)
    np.testing.assert_array_equal(drawn, worn[random])
    assert len(drawn) > 0 and len(steady) > 0


def test_mean_trend_rul_equals_the_numpy_formula_to_the_bit():
    values, faulty, clock, arrival, velocity, limits = _wear_case(13)
    values[::5, :] = 2.0  # past the upper limits: RUL 0 where heading up
    current = values[np.arange(len(faulty)), faulty]
    limit = np.where(velocity > 0, limits[faulty, 1], limits[faulty, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        rul = np.where(velocity != 0, (limit - current) / velocity, np.inf)
    expected = np.where(clock >= arrival, np.maximum(rul, 0.0), np.inf)
    out = np.empty(len(values))
    mean_trend_rul(values, np.arange(3), faulty, limits, velocity, arrival, clock, out)
    np.testing.assert_array_equal(out, expected)
    columns = np.array([2, 0, 3])  # the values in wider rows
    rows = np.zeros((len(values), 4))
    rows[:, columns] = values
    mean_trend_rul(rows, columns, faulty, limits, velocity, arrival, clock, out)
    np.testing.assert_array_equal(out, expected)
    assert np.isinf(out).any() and (out == 0).any() and np.isfinite(out).any()


def test_drift_prognosis_is_the_suspects_drift_ends_within_the_horizon():
    rng = _rng(10)
    n, d = 200, 3
    value = 100.0 + rng.normal(0.0, 8.0, (n, d))
    drift = rng.normal(0.0, 0.2, (n, d))
    root = rng.normal(0.0, 1.0, (n, d, 2, 2)) * np.array([2.0, 0.05])[:, None]
    covariance = root @ np.swapaxes(root, -1, -2)
    stamps = np.repeat(rng.uniform(0.0, 500.0, n)[:, None], d, axis=1)
    isolated = rng.integers(1, d + 1, n)
    confident = rng.random(n) < 0.6
    lower, upper, diffusion = np.array([90.0, 80.0, 95.0]), np.array([110.0, 120.0, 105.0]), rng.uniform(0.0, 0.05, d)
    t, z, horizon = stamps[:, 0] + 0.5, 1.959963984540054, 300.0
    out = np.empty((7, n))
    drift_prognosis(value, drift, covariance[..., 0, 0].copy(), covariance[..., 0, 1].copy(), covariance[..., 1, 1].copy(), stamps, isolated,
                    confident, lower, upper, diffusion, t, z**2, horizon, out)
    estimate, ends, suspect_drift, suspect_variance = out[0], out[1:4].T, out[4], out[5]
    rows = np.flatnonzero(confident)
    k = isolated[rows] - 1
    expected = np.empty((len(rows), 3))
    drift_ends(value[rows, k], drift[rows, k], covariance[rows, k, 0, 0], covariance[rows, k, 0, 1], covariance[rows, k, 1, 1], lower[k], upper[k],
               stamps[rows, k], diffusion[k], z**2, expected)
    expected = np.where(expected - t[rows, None] > horizon, np.inf, expected)
    np.testing.assert_array_equal(ends[rows], expected)
    np.testing.assert_array_equal(estimate[rows], value[rows, k])
    np.testing.assert_array_equal(suspect_drift[rows], drift[rows, k])
    np.testing.assert_array_equal(suspect_variance[rows], covariance[rows, k, 1, 1])
    np.testing.assert_array_equal(out[6], t)
    assert np.isinf(ends[~confident]).all() and np.isnan(estimate[~confident]).all()
    assert np.isnan(suspect_drift[~confident]).all() and np.isnan(suspect_variance[~confident]).all()
    assert np.isinf(expected).any() and np.isfinite(expected).any()
