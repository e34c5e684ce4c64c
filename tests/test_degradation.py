import math
import pickle

import numpy as np
import pytest

from ea_gym.degradation import PiecewiseLinearProfile, ProfileError


def test_profile_interpolates_the_papers_stiffness_fault():
    profile = PiecewiseLinearProfile((0.0, 5.0, 50.0, 100.0), (100.0, 100.0, 86.5, 100.0))
    t = np.array([0.0, 2.0, 5.0, 27.5, 50.0, 75.0, 100.0])
    # 27.5 s is half way from (5, 100) to (50, 86.5); 75 s half way from (50, 86.5) to (100, 100)
    expected = np.array([100.0, 100.0, 100.0, 93.25, 86.5, 93.25, 100.0])
    np.testing.assert_allclose(profile.value(t), expected, rtol=0, atol=1e-12)


def test_profile_is_held_before_the_first_and_after_the_last_point():
    profile = PiecewiseLinearProfile((1.0, 3.0), (2.0, 6.0))
    t = np.array([[0.0, 0.5], [2.0, 10.0]])
    np.testing.assert_allclose(profile.value(t), [[2.0, 2.0], [4.0, 6.0]], rtol=0, atol=1e-12)


def test_single_point_profile_is_constant():
    profile = PiecewiseLinearProfile((0.0,), (7.0,))
    np.testing.assert_array_equal(profile.value(np.array([0.0, 1.0, 1e6])), [7.0, 7.0, 7.0])


@pytest.mark.parametrize(
    ("times", "values", "match"),
    [
        ((0.0, 5.0, 5.0), (1.0, 1.0, 1.0), "point 2.*strictly increasing"),
        ((0.0, 5.0, 3.0), (1.0, 1.0, 1.0), "point 2.*strictly increasing"),
        ((-1.0, 5.0), (1.0, 1.0), "point 0.*negative"),
        ((0.0, math.inf), (1.0, 1.0), "point 1.*not finite"),
        ((0.0, math.nan), (1.0, 1.0), "point 1.*not finite"),
        ((0.0, 1.0), (1.0, math.nan), "point 1.*value"),
        ((0.0, 1.0), (1.0,), "2 times but 1 values"),
        ((), (), "at least one point"),
    ],
)
def test_profile_rejects_bad_points(times, values, match):
    with pytest.raises(ValueError, match=match):
        PiecewiseLinearProfile(times, values)


def test_profile_error_carries_the_index_and_pickles():
    with pytest.raises(ProfileError) as info:
        PiecewiseLinearProfile((0.0, 2.0, 1.0), (1.0, 1.0, 1.0))
    assert info.value.index == 2
    copy = pickle.loads(pickle.dumps(info.value))
    assert (copy.index, str(copy)) == (2, str(info.value))
