"""Kernels against independent implementations (scipy's Savitzky-Golay filter and matrix exponential), and the
references' Hermite coefficients against the simulation's; each kernel against its numpy reference is
``test_kernel_references``."""

import numpy as np
import pytest
from scipy import linalg
from scipy.signal import savgol_filter

from ea_gym._kernels.activity import trapezoid_area
from ea_gym._kernels.expm import expm_batch
from ea_gym._kernels.monitor import Smoothing, smooth_rows
from ea_gym._kernels.reference.tracking import hermite_row
from ea_gym._kernels.smoothing import LANES, filter_into, filter_lanes, filter_rows
from ea_gym.bondgraph.simulation import hermite_coefficients
from ea_gym.diagnosis.smoothing import SavitzkyGolay

H = 0.01  # sample period (s)


def _rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


# --- activity: the one EA trapezoid ---------------------------------------------------------------


def test_trapezoid_area_is_the_trapezoid_of_the_magnitudes():
    assert trapezoid_area(-2.0, 4.0, 0.5) == 0.5 * (2.0 + 4.0) * 0.5


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


# --- matrix exponential ---------------------------------------------------------------------------


@pytest.mark.parametrize("norm", [0.01, 1.0, 40.0])
def test_expm_batch_equals_scipy(norm):
    Z = _rng(8).standard_normal((5, 6, 6))
    Z *= norm / np.abs(Z).sum(axis=1).max(axis=1)[:, None, None]
    exact = linalg.expm(Z)
    out = np.empty_like(Z)
    expm_batch(Z, out)
    np.testing.assert_allclose(out, exact, rtol=0, atol=1e-13 * np.abs(exact).max())


# --- propagation: the reference's Hermite coefficients are the simulation's -------------------------


def test_reference_hermite_rows_are_the_simulations_hermite_coefficients_to_the_bit():
    u, du = _rng(10).standard_normal((2, 4, 40, 2))
    rows = np.concatenate(hermite_row(u[:, :-1], u[:, 1:], du[:, :-1], du[:, 1:], H), axis=-1)
    assert rows.tobytes() == hermite_coefficients(u, du, H).tobytes()


# --- monitor ----------------------------------------------------------------------------------------


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


