"""The batched Savitzky-Golay filter against scipy's ``savgol_filter``."""

import numpy as np
import pytest
from scipy.signal import savgol_filter

from ea_gym._kernels.smoothing import LANES, filter_lanes
from ea_gym.diagnosis.smoothing import SavitzkyGolay

H = 0.01  # sample period (s)


@pytest.mark.parametrize(("window", "polyorder"), [(51, 2), (51, 3), (5, 2), (3, 1), (1, 0)])
@pytest.mark.parametrize("extra", [0, 1, 52, 301], ids=lambda n: f"window+{n}")
def test_equals_scipy_interp_mode(window, polyorder, extra):
    x = np.random.default_rng(window + extra).standard_normal((4, 3, window + extra)).cumsum(-1)
    sg = SavitzkyGolay(window, polyorder, H)
    for deriv in range(min(polyorder, 1) + 1):
        exact = savgol_filter(x, window, polyorder, deriv=deriv, delta=H, axis=-1, mode="interp")
        np.testing.assert_allclose(sg(x, deriv), exact, rtol=0, atol=1e-12 * np.abs(exact).max())


def test_each_row_is_filtered_alone():
    # the result of a row does not depend on the other rows of the batch, to the bit
    x = np.random.default_rng(0).standard_normal((7, 2, 152))
    sg = SavitzkyGolay(51, 3, H)
    for deriv in (0, 1):
        batch = sg(x, deriv)
        for i in range(len(x)):
            np.testing.assert_array_equal(sg(x[i : i + 1], deriv), batch[i : i + 1])


def test_rejects_signals_shorter_than_the_window():
    with pytest.raises(ValueError, match="shorter than the filter"):
        SavitzkyGolay(51, 3, H)(np.zeros((2, 50)))


def _lanes(sg, x, first, derivative=True):
    smooth, slope = np.full_like(x, np.nan), np.full_like(x, np.nan)
    filter_lanes(x, first, sg.moments(), sg.lane_coefficients(0), sg.lane_coefficients(1), derivative, smooth, slope)
    return smooth, slope


@pytest.mark.parametrize(("window", "polyorder"), [(51, 3), (51, 2), (5, 2), (3, 1), (1, 0)])
@pytest.mark.parametrize("length", [0, 1, 75, 301], ids=lambda n: f"window+{n}")
def test_lanes_match_scipy_within_the_recursion_bound(window, polyorder, length):
    # the running moments drift by round-off between their direct sums: measured below 8e-14 x
    # max|x| x sum|c_k| for these cases (a large offset included), bounded here at 2e-13
    half, length = window // 2, window + length
    sg = SavitzkyGolay(window, polyorder, H)
    rng = np.random.default_rng(length)
    x = rng.standard_normal((length, 2 * LANES)).cumsum(0) + 100.0 * rng.standard_normal(2 * LANES)
    for first in sorted({0, half, min(half + 1, length - 1), length - 1}):
        outputs = _lanes(sg, x, first, derivative=polyorder > 0)
        for deriv in range(min(polyorder, 1) + 1):
            exact = savgol_filter(x, window, polyorder, deriv=deriv, delta=H, axis=0, mode="interp")
            bound = 2e-13 * np.abs(x).max() * np.abs(sg.coefficients(deriv)[0]).sum()
            assert np.isnan(outputs[deriv][:first]).all()
            np.testing.assert_allclose(outputs[deriv][first:], exact[first:], rtol=0, atol=bound)


def test_each_lane_is_filtered_alone():
    sg = SavitzkyGolay(51, 3, H)
    x = np.random.default_rng(1).standard_normal((126, LANES))
    alone = np.zeros_like(x)
    alone[:, 3] = x[:, 3]
    for batch, single in zip(_lanes(sg, x, 25), _lanes(sg, alone, 25)):
        np.testing.assert_array_equal(batch[:, 3], single[:, 3])


def test_lanes_reject_orders_above_three():
    with pytest.raises(ValueError, match="orders up to 3"):
        SavitzkyGolay(51, 4, H).moments()
