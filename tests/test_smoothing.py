"""The batched Savitzky-Golay filter against scipy's ``savgol_filter``."""

import numpy as np
import pytest
from scipy.signal import savgol_filter

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
