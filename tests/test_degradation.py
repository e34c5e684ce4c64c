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


@pytest.mark.parametrize("process", ["wiener", "gamma"])
def test_the_wears_random_walk_std_is_that_of_its_increments(process):
    """Wear.advance's increments over 1 s, minus their mean, have the std random_walk_std gives (one rate, one direction)."""
    from ea_gym.degradation import Wear, WearConfig

    config = WearConfig(process=process, direction=1, rate=(0.01, 0.01), arrival=(0.0, 0.0), volatility=0.3)
    nominal, limits = np.array([0.5]), np.array([[0.4, 0.6]])
    n = 4000
    wear = Wear(nominal, limits, [config], n)
    rngs = [np.random.default_rng(i) for i in range(n)]
    wear.start(rngs, np.zeros(n), np.ones(n, dtype=bool))
    values = np.full((n, 1), 0.5)
    wear.advance(values, np.zeros(n), 1.0, rngs)
    increments = values[:, 0] - 0.5
    expected = config.random_walk_std(0.5, (0.4, 0.6))
    assert expected == pytest.approx(0.3 * math.sqrt(10.0) * 0.01 * 0.1)
    assert increments.mean() == pytest.approx(0.001, rel=0.05)
    assert increments.std() == pytest.approx(expected, rel=0.05)  # 4000 draws: the std's own error is ~1 %


def test_linear_wear_has_no_random_walk_and_a_random_direction_averages_both_limits():
    from ea_gym.degradation import WearConfig

    assert WearConfig().random_walk_std(100.0, (85.0, 105.0)) == 0.0
    both = WearConfig(process="wiener", rate=(0.01, 0.02), volatility=0.3).random_walk_std(100.0, (85.0, 105.0))
    # mean square drift: E[r^2] for r uniform on (0.01, 0.02), times the mean of 15^2 and 5^2
    assert both == pytest.approx(0.3 * math.sqrt(10.0 * (0.01**2 + 0.01 * 0.02 + 0.02**2) / 3.0 * (15.0**2 + 5.0**2) / 2.0))


def test_stopped_systems_keep_their_values_and_draw_as_running_ones():
    """Wear.advance of a running mask: the values of all systems worn, then the stopped ones' put back; every
    generator drawn from as if all ran (linear, gamma and Wiener wear, components in a wider parameter row)."""
    from ea_gym.degradation import Wear, WearConfig

    configs = [WearConfig(process=p, rate=(0.01, 0.02), arrival=(0.0, 2.0)) for p in ("linear", "gamma", "wiener")]
    nominal, limits, columns = np.array([1.0, 2.0, 3.0]), np.array([[0.5, 1.5], [1.0, 3.0], [2.0, 4.0]]), np.array([3, 0, 1])
    n = 40
    worn, wearing = (Wear(nominal, limits, configs, n, columns=columns) for _ in range(2))
    rngs, again = ([np.random.default_rng(50 + i) for i in range(n)] for _ in range(2))
    for wear, generators in ((worn, rngs), (wearing, again)):
        wear.start(generators, np.zeros(n), np.ones(n, dtype=bool))
    parameters = np.random.default_rng(7).uniform(1.0, 3.0, (n, 4))
    running = np.arange(n) % 3 != 0
    original, every = parameters.copy(), parameters.copy()
    wearing.advance(every, np.full(n, 1.0), 1.0, again)
    worn.advance(parameters, np.full(n, 1.0), 1.0, rngs, running)
    np.testing.assert_array_equal(parameters, np.where(running[:, None], every, original))
    assert (every[~running] != original[~running]).any() and (parameters[running] != original[running]).any()
    assert all(a.random() == b.random() for a, b in zip(rngs, again))
