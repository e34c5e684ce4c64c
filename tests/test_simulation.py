"""Simulation of the bond-graph models against closed forms, a reference integrator and invariants."""

import numpy as np
import pytest
from power_balance import power_residuals  # tests/power_balance.py
from scipy import linalg, signal
from scipy.integrate import solve_ivp

from ea_gym import models
from ea_gym._kernels.propagation import SYSTEMS_BLOCK, simulate_hermite
from ea_gym.bondgraph.simulation import HOLD_ORDER, Discretization, discretize, expm, hermite_coefficients, propagate
from ea_gym.loads import ConstantLoad, Sine, SinesLoad, multisine_rotations, rotated_multisine
from ea_gym.plant import run_model

M, K, B = 10.0, 100.0, 0.5  # the paper's Table 2: m (kg), k (N/m), b (N s/m)
SIGMA = B / (2 * M)  # decay rate (1/s)
WN2 = K / M  # natural angular frequency squared (rad^2/s^2)
WD = np.sqrt(WN2 - SIGMA**2)  # damped angular frequency (rad/s)
T_100HZ = np.linspace(0.0, 120.0, 12001)  # 120 s at 100 Hz


def max_rel_error(simulated: np.ndarray, exact: np.ndarray) -> float:
    """Largest absolute error relative to the exact signal's amplitude (its largest magnitude)."""
    return float(np.abs(simulated - exact).max() / np.abs(exact).max())


def drifting_stiffness(duration: float = 200.0, k0: float = 100.0, k1: float = 86.0):
    """k(t) falling linearly from k0 to k1 over ``duration`` s; m and b nominal (parameter order m, k, b)."""

    def k_of(t):
        return k0 + (k1 - k0) * np.asarray(t) / duration

    def parameters(t):
        t = np.asarray(t, dtype=float)
        return np.stack([np.full_like(t, M), k_of(t), np.full_like(t, B)], axis=-1)

    return k_of, parameters


# --------------------------------------------------------------------------------------------------
# closed-form responses of the spring-mass-damper


def test_step_response_matches_the_underdamped_closed_form():
    # m x'' + b x' + k x = F from rest: x = F/k [1 - e^{-s t} (cos wd t + (s/wd) sin wd t)],
    # v = x' = (F/k) (wn^2/wd) e^{-s t} sin wd t, with s = b/2m, wn^2 = k/m, wd^2 = wn^2 - s^2.
    model = models.spring_mass_damper()
    assert model.state_names == ("m", "k")
    F, t = 10.0, T_100HZ
    traj = run_model(model, t, ConstantLoad(F))
    x = F / K * (1 - np.exp(-SIGMA * t) * (np.cos(WD * t) + SIGMA / WD * np.sin(WD * t)))
    v = F / K * WN2 / WD * np.exp(-SIGMA * t) * np.sin(WD * t)
    position, velocity = traj.states[:, 1], traj.states[:, 0] / M
    assert position[0] == 0.0 and velocity[0] == 0.0
    for simulated, exact in ((position, x), (velocity, v)):
        error = max_rel_error(simulated, exact)
        assert error <= 1e-6
        # the discretization is exact for a constant input: only round-off remains (measured ~3e-14)
        assert error <= 1e-9
    # the trajectory's own views agree with the states
    np.testing.assert_allclose(traj.flow["m"], velocity, rtol=1e-13, atol=1e-16)
    np.testing.assert_array_equal(traj.t, t)


def _sine_closed_form(t, offset=10.0, amplitude=5.0, frequency=0.3):
    """x(t), v(t) of m x'' + b x' + k x = offset + amplitude sin(w t) from rest.

    Particular solution: x_p = offset/k + Im(X e^{i w t}) with X = amplitude / (k - m w^2 + i b w).
    Homogeneous: e^{-s t} (c1 cos wd t + c2 sin wd t), with x(0) = 0 -> c1 = -x_p(0) and
    v(0) = 0 -> -s c1 + wd c2 = -x_p'(0).
    """
    w = 2 * np.pi * frequency
    X = amplitude / (K - M * w**2 + 1j * B * w)
    xp = offset / K + np.imag(X * np.exp(1j * w * t))
    vp = np.imag(1j * w * X * np.exp(1j * w * t))
    xp0, vp0 = offset / K + np.imag(X), np.imag(1j * w * X)
    c1 = -xp0
    c2 = (-vp0 + SIGMA * c1) / WD
    decay = np.exp(-SIGMA * t)
    x = xp + decay * (c1 * np.cos(WD * t) + c2 * np.sin(WD * t))
    v = vp + decay * ((WD * c2 - SIGMA * c1) * np.cos(WD * t) - (WD * c1 + SIGMA * c2) * np.sin(WD * t))
    return x, v


def test_closed_form_for_the_sine_load_is_self_consistent():
    # guard the reference itself: zero initial conditions, v = dx/dt and m dv/dt + b v + k x = F(t)
    t = np.linspace(0.0, 20.0, 200001)
    x, v = _sine_closed_form(t)
    assert abs(x[0]) < 1e-15 and abs(v[0]) < 1e-15
    np.testing.assert_allclose(np.gradient(x, t, edge_order=2), v, rtol=0, atol=1e-6 * np.abs(v).max())
    force = 10.0 + 5.0 * np.sin(2 * np.pi * 0.3 * t)
    residual = M * np.gradient(v, t, edge_order=2) + B * v + K * x - force
    assert np.abs(residual).max() <= 1e-5 * np.abs(force).max()


def test_sine_response_matches_the_closed_form():
    model = models.spring_mass_damper()
    t = T_100HZ
    load = SinesLoad(10.0, (Sine(5.0, 0.3),))
    traj = run_model(model, t, load)
    x, v = _sine_closed_form(t)
    for simulated, exact in ((traj.states[:, 1], x), (traj.states[:, 0] / M, v)):
        error = max_rel_error(simulated, exact)
        assert error <= 1e-6
        assert error <= 1e-9  # cubic Hermite hold, error O(h^4): measured ~1e-10


def test_zero_order_hold_would_not_be_accurate_enough():
    # The same model discretized with a zero-order hold of the sampled load (the usual shortcut)
    # misses the closed form by far more than the 1e-6 the engine meets: the higher-order hold matters.
    t = T_100HZ
    h = t[1] - t[0]
    load = SinesLoad(10.0, (Sine(5.0, 0.3),))
    A = np.array([[-B / M, -K], [1 / M, 0.0]])
    Bm = np.array([[1.0], [0.0]])
    Ad, Bd, *_ = signal.cont2discrete((A, Bm, np.eye(2), np.zeros((2, 1))), h, method="zoh")
    u = load.value(t)
    states = np.zeros((len(t), 2))
    for i in range(len(t) - 1):
        states[i + 1] = Ad @ states[i] + Bd[:, 0] * u[i]
    x, _ = _sine_closed_form(t)
    assert max_rel_error(states[:, 1], x) > 1e-6
    # while the engine's matrices are the same A, B
    mats = models.spring_mass_damper().state_space.matrices(np.array([M, K, B]))
    np.testing.assert_allclose(mats.A, A, rtol=1e-15)
    np.testing.assert_allclose(mats.B, Bm, rtol=1e-15)


def test_drifting_stiffness_matches_a_tight_reference_integrator():
    model = models.spring_mass_damper()
    duration = 200.0
    k_of, parameters = drifting_stiffness(duration)
    t = np.linspace(0.0, duration, 20001)
    load = SinesLoad(10.0, (Sine(5.0, 0.3),))
    traj = run_model(model, t, load, parameters)
    np.testing.assert_allclose(traj.parameters[:, 1], k_of(t), rtol=1e-15)

    def rhs(time, y):  # y = (p, q); the stiffness varies continuously
        p, q = y
        return [load.value(np.array(time)) - k_of(time) * q - B / M * p, p / M]

    ref = solve_ivp(rhs, (0.0, duration), [0.0, 0.0], method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t)
    assert ref.success
    for column in range(2):
        assert max_rel_error(traj.states[:, column], ref.y[column]) <= 1e-6
    # a constant stiffness would be visibly wrong: the drift matters at this tolerance
    constant = run_model(model, t, load)
    assert max_rel_error(constant.states[:, 1], ref.y[1]) > 1e-3


# --------------------------------------------------------------------------------------------------
# compiled kernels


@pytest.mark.parametrize("n", [2, 3, 6, 10])
@pytest.mark.parametrize("norm", [1e-8, 1e-3, 0.1, 1.0, 2.0])
def test_expm_equals_scipy(n, norm):
    # 1-norms up to 2 cover the augmented matrices of the models (about 1 at h = 10 ms); from about 4 scipy
    # scales and squares and drifts from the exact value by ~1e-13 (checked against 40-digit mpmath)
    Z = np.random.default_rng(n).standard_normal((20, n, n))
    Z *= norm / np.abs(Z).sum(axis=1).max(axis=1)[:, None, None]
    exact = linalg.expm(Z)
    scale = np.abs(exact).max(axis=(1, 2), keepdims=True)
    assert np.all(np.abs(expm(Z) - exact) <= 1e-13 * scale)


def test_expm_scales_and_squares_large_matrices():
    # exp([[a, w], [-w, a]] t) = e^{a t} [[cos w t, sin w t], [-sin w t, cos w t]], 1-norm up to 100
    a, w = -0.5, np.array([3.0, 20.0, 99.0])
    Z = np.zeros((3, 2, 2))
    Z[:, 0, 0] = Z[:, 1, 1] = a
    Z[:, 0, 1], Z[:, 1, 0] = w, -w
    exact = np.exp(a) * np.stack([[np.cos(w), np.sin(w)], [-np.sin(w), np.cos(w)]]).transpose(2, 0, 1)
    # s squarings turn the rounding of the scaled matrix into an angle error of ~1e-16 w (measured 3e-15 at w = 99)
    assert np.all(np.abs(expm(Z) - exact) <= 1e-14 * w[:, None, None])
    # batch shape is kept; one matrix is a batch of none
    assert expm(Z.reshape(3, 1, 2, 2)).shape == (3, 1, 2, 2)
    np.testing.assert_array_equal(expm(Z[0]), expm(Z)[0])


def test_discretize_is_the_augmented_exponentials_top_row_to_the_bit():
    # the compiled assembly equals building [[A, B, 0], input chain] h with numpy and taking expm's exponential
    rng = np.random.default_rng(11)
    for batch, nx, nu, h in (((), 2, 1, 0.01), ((5,), 3, 2, 0.1), ((2, 3), 4, 1, 1.0)):
        A, B = rng.standard_normal(batch + (nx, nx)), rng.standard_normal(batch + (nx, nu))
        size = nx + HOLD_ORDER * nu
        Z = np.zeros(batch + (size, size))
        Z[..., :nx, :nx], Z[..., :nx, nx : nx + nu] = A, B
        for j in range(HOLD_ORDER - 1):  # each Taylor coefficient's derivative is the next one
            Z[..., nx + j * nu : nx + (j + 1) * nu, nx + (j + 1) * nu : nx + (j + 2) * nu] = np.eye(nu)
        E = expm(Z * h)
        d = discretize(A, B, h)
        np.testing.assert_array_equal(d.Phi, E[..., :nx, :nx])
        np.testing.assert_array_equal(d.Gamma, E[..., :nx, nx:])


def test_rotated_multisine_equals_the_direct_sum():
    rng = np.random.default_rng(0)
    n, components, h = 5, 20, 0.01
    frequencies = 10.0 - rng.uniform(0.0, 10.0, (n, components))
    phases = rng.uniform(0.0, 2 * np.pi, (n, components))
    # spans several direct evaluations (every 128 samples) and starts at different times
    t = rng.uniform(0.0, 5.0, n)[:, None] + np.arange(301) * h
    omega = 2 * np.pi * frequencies[:, None, :]
    angle = t[..., None] * omega + phases[:, None, :]
    waves, slopes = rotated_multisine(t, phases, multisine_rotations(frequencies, h))
    # angle addition adds ~1e-16 per sample to the direct sum's own rounding
    np.testing.assert_allclose(waves, np.sin(angle).sum(-1), rtol=0, atol=1e-12)
    np.testing.assert_allclose(slopes, (np.cos(angle) * omega).sum(-1), rtol=0, atol=1e-12 * omega.max())
    # each system on its own gives the same, to the bit
    single = rotated_multisine(t[2:3], phases[2:3], multisine_rotations(frequencies[2:3], h))
    np.testing.assert_array_equal(single[0], waves[2:3])
    np.testing.assert_array_equal(single[1], slopes[2:3])


# --------------------------------------------------------------------------------------------------
# chunking


@pytest.mark.parametrize("drift", [False, True], ids=["nominal", "drifting_k"])
def test_chunked_simulation_equals_one_run(drift):
    # a dyadic sample period makes both chunks' time grids bitwise equal to the whole run's
    h = 2.0**-7
    t = np.arange(120 * 128 + 1) * h
    cut = 60 * 128
    load = SinesLoad(10.0, (Sine(5.0, 0.3), Sine(2.0, 1.7, 0.4)))
    parameters = drifting_stiffness()[1] if drift else None
    model = models.spring_mass_damper()
    whole = run_model(model, t, load, parameters)
    first = run_model(model, t[: cut + 1], load, parameters)
    second = run_model(model, t[cut:], load, parameters, initial_state=first.states[-1])
    states = np.concatenate([first.states, second.states[1:]])
    bonds = np.concatenate([first.bonds, second.bonds[1:]])
    scale = np.abs(whole.states).max(axis=0)
    assert np.all(np.abs(states - whole.states) <= 1e-12 * scale)
    assert np.all(np.abs(bonds - whole.bonds) <= 1e-12 * np.abs(whole.bonds).max())
    assert np.all(np.abs(first.bonds[-1] - second.bonds[0]) <= 1e-12 * np.abs(whole.bonds).max())
    np.testing.assert_array_equal(np.concatenate([first.t, second.t[1:]]), whole.t)


# --------------------------------------------------------------------------------------------------
# power balance and constitutive laws at every sample


SINES = SinesLoad(5.0, (Sine(3.0, 0.4), Sine(1.5, 2.3, 1.1), Sine(0.5, 7.0, -0.3)))


def _dc_motor_drifting_k(t):
    """The torque constant K falling from 0.1 to 0.08 N m/A over 20 s, the others nominal."""
    t = np.asarray(t, dtype=float)
    model = models.dc_motor()
    theta = np.repeat(model.parameter_vector()[None], len(t), axis=0)
    theta[:, model.parameter_names.index("K")] = 0.1 - 0.02 * t / 20.0
    return theta


@pytest.mark.parametrize(
    ("factory", "parameters"),
    [
        (models.spring_mass_damper, None),
        (models.rlc_circuit, None),
        (models.dc_motor, None),
        (models.spring_mass_damper, drifting_stiffness(20.0)[1]),
        (models.dc_motor, _dc_motor_drifting_k),
    ],
    ids=["spring_mass_damper", "rlc_circuit", "dc_motor", "spring_mass_damper_drifting_k", "dc_motor_drifting_K"],
)
def test_power_balances_at_every_junction_at_every_sample(factory, parameters):
    model = factory()
    t = np.linspace(0.0, 20.0, 2001)
    traj = run_model(model, t, SINES, parameters)
    n = len(model.graph.bonds)
    largest = np.abs(traj.bonds[:, :n] * traj.bonds[:, n:]).max(axis=1)  # largest bond power per sample
    assert largest[1:].min() > 0  # the system moves after the first sample
    for name, (net, _) in power_residuals(model.graph, traj.bonds).items():
        assert np.all(np.abs(net) <= 1e-9 * largest), (name, np.abs(net[1:] / largest[1:]).max())
    # the element powers of the trajectory agree with the bonds, and the source's power is spent
    # on the R, C and I elements (GY/TF are lossless): sum over the one-port consumers = source power
    absorbed = sum(traj.power[name] for name in model.rco_elements)
    source = traj.power[model.load_source]
    np.testing.assert_allclose(absorbed, source, rtol=0, atol=1e-9 * np.abs(source).max())


def test_spring_mass_damper_signals_obey_the_constitutive_laws():
    model = models.spring_mass_damper()
    _, parameters = drifting_stiffness(30.0)
    t = np.linspace(0.0, 30.0, 3001)
    for params in (None, parameters):
        traj = run_model(model, t, SINES, params)
        theta = traj.parameters
        m, k, b = theta[:, 0], theta[:, 1], theta[:, 2]
        p, q = traj.states[:, 0], traj.states[:, 1]
        scale_f = np.abs(traj.flow["m"]).max()
        scale_e = np.abs(traj.effort["k"]).max()
        np.testing.assert_allclose(traj.effort["b"], b * traj.flow["b"], rtol=0, atol=1e-12 * scale_e)
        np.testing.assert_allclose(traj.flow["m"], p / m, rtol=0, atol=1e-12 * scale_f)
        np.testing.assert_allclose(traj.effort["k"], k * q, rtol=0, atol=1e-12 * scale_e)
        # one common velocity at the 1-junction; the force balance F = e_m + e_k + e_b
        np.testing.assert_allclose(traj.flow["k"], traj.flow["m"], rtol=0, atol=1e-12 * scale_f)
        np.testing.assert_allclose(traj.flow["b"], traj.flow["m"], rtol=0, atol=1e-12 * scale_f)
        np.testing.assert_allclose(traj.effort["F"], SINES.value(t), rtol=1e-14)
        np.testing.assert_allclose(
            traj.effort["m"] + traj.effort["k"] + traj.effort["b"], traj.effort["F"], rtol=0, atol=1e-12 * scale_e
        )
        # power is e * f of each element
        for name in ("m", "k", "b", "F"):
            np.testing.assert_array_equal(traj.power[name], traj.effort[name] * traj.flow[name])


def _hermite_states(Phi, Gamma, index, u, du, h, x0):
    """The blocked kernel's states (N, T, nx) at unit gains; its last states must be the final samples."""
    n, samples, nx = len(x0), u.shape[1], Phi.shape[1]
    signals, last = np.empty((n, nx, samples)), np.empty((n, nx))
    simulate_hermite(Phi, Gamma, index, u, du, np.arange(n), h, x0, np.ones((n, nx)), signals, last)
    np.testing.assert_array_equal(last, signals[..., -1])
    return signals.transpose(0, 2, 1)


def test_blocked_hermite_kernel_equals_propagation_system_by_system():
    # several blocks of systems side by side, the last one partial: every system's states are the
    # plain recursion's to the bit, whatever its neighbours
    rng = np.random.default_rng(6)
    nx, nu, n, samples, h = 3, 2, 2 * SYSTEMS_BLOCK + 3, 12, 0.02
    Phi = 0.3 * rng.standard_normal((5, nx, nx))
    Gamma = rng.standard_normal((5, nx, 4 * nu))
    index = rng.integers(0, 5, n)
    u, du = rng.standard_normal((2, n, samples, nu))
    x0 = rng.standard_normal((n, nx))
    batch = _hermite_states(Phi, Gamma, index, u, du, h, x0)
    expected = propagate(Discretization(Phi[index][:, None], Gamma[index][:, None]), hermite_coefficients(u, du, h), x0)
    np.testing.assert_array_equal(batch, expected)
    last = slice(n - 1, n)
    np.testing.assert_array_equal(_hermite_states(Phi, Gamma, index[last], u[last], du[last], h, x0[last]), batch[last])
