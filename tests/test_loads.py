import math

import numpy as np
import pytest

from ea_gym.loads import ConstantLoad, Load, RandomLoad, Sine, SinesLoad


def test_constant_load_keeps_the_shape_of_t():
    load = ConstantLoad(level=10.0)
    t = np.linspace(0.0, 5.0, 6).reshape(2, 3)
    np.testing.assert_array_equal(load.value(t), np.full((2, 3), 10.0))
    np.testing.assert_array_equal(load.derivative(t), np.zeros((2, 3)))
    assert isinstance(load, Load)


def test_sines_load_against_hand_computed_values():
    # 10 + 5 sin(2 pi 0.25 t) + 2 sin(2 pi 1 t + pi/2) = 10 + 5 sin(pi t / 2) + 2 cos(2 pi t)
    load = SinesLoad(offset=10.0, sines=(Sine(5.0, 0.25), Sine(2.0, 1.0, math.pi / 2)))
    t = np.array([0.0, 0.5, 1.0, 2.0])
    expected = np.array([10.0 + 0.0 + 2.0, 10.0 + 5.0 * math.sqrt(0.5) - 2.0, 10.0 + 5.0 + 2.0, 10.0 + 0.0 + 2.0])
    np.testing.assert_allclose(load.value(t), expected, atol=1e-12)
    # d/dt = 5 (pi/2) cos(pi t / 2) - 2 (2 pi) sin(2 pi t)
    expected_rate = np.array([5 * math.pi / 2, 5 * math.pi / 2 * math.sqrt(0.5) - 0.0, 0.0, -5 * math.pi / 2])
    np.testing.assert_allclose(load.derivative(t), expected_rate, atol=1e-12)


def test_sines_load_derivative_matches_central_difference():
    load = SinesLoad(offset=-1.0, sines=(Sine(3.0, 0.3, 0.7), Sine(0.5, 2.1, -1.2)))
    t = np.linspace(0.0, 10.0, 101)
    h = 1e-5
    numeric = (load.value(t + h) - load.value(t - h)) / (2 * h)
    # central difference error ~ h^2 |f'''| / 6 < 1e-8 here
    np.testing.assert_allclose(load.derivative(t), numeric, atol=1e-7)


def test_sines_load_is_elementwise_over_any_shape():
    load = SinesLoad(offset=1.0, sines=(Sine(1.0, 0.5),))
    t = np.linspace(0.0, 3.0, 12)
    np.testing.assert_array_equal(load.value(t.reshape(3, 4)), load.value(t).reshape(3, 4))
    assert load.value(np.float64(1.0)) == pytest.approx(1.0 + math.sin(math.pi))


def test_sine_rejects_negative_frequency():
    with pytest.raises(ValueError, match="frequency"):
        Sine(1.0, -0.1)


def test_random_load_time_averages_match_mean_and_std():
    # 64 components in (0, 2] Hz: over 4000 s the time averages of the cross terms are
    # O(1 / (2 pi df T)) with df the frequency spacings, well inside 3 % of std.
    mean, std = 10.0, 3.0
    for seed in range(3):
        load = RandomLoad.draw(mean, std, 2.0, np.random.default_rng(seed))
        x = load.value(np.arange(0.0, 4000.0, 0.05))
        assert abs(x.mean() - mean) < 0.03 * std
        assert abs(x.std() - std) < 0.03 * std


def test_random_load_draw_respects_its_ranges():
    load = RandomLoad.draw(0.0, 1.0, 2.0, np.random.default_rng(5), n_components=200)
    assert load.frequencies.shape == load.phases.shape == (200,)
    assert np.all((load.frequencies > 0) & (load.frequencies <= 2.0))
    assert np.all((load.phases >= 0) & (load.phases < 2 * math.pi))
    assert load.amplitude == pytest.approx(math.sqrt(2.0 / 200))


def test_random_load_same_seed_identical_different_seed_different():
    t = np.linspace(0.0, 20.0, 2001)
    a = RandomLoad.draw(1.0, 0.5, 3.0, np.random.default_rng(42)).value(t)
    b = RandomLoad.draw(1.0, 0.5, 3.0, np.random.default_rng(42)).value(t)
    c = RandomLoad.draw(1.0, 0.5, 3.0, np.random.default_rng(43)).value(t)
    np.testing.assert_array_equal(a, b)
    assert np.max(np.abs(a - c)) > 0.1


def test_random_load_is_chunk_independent_and_derivative_matches_difference():
    load = RandomLoad.draw(0.0, 2.0, 1.5, np.random.default_rng(7))
    t = np.linspace(0.0, 30.0, 601)
    whole = load.value(t)
    pieces = np.concatenate([load.value(t[:250]), load.value(t[250:])])
    np.testing.assert_allclose(pieces, whole, rtol=0, atol=1e-12)
    one = np.array([load.value(np.float64(ti)) for ti in t[::50]])
    np.testing.assert_allclose(one, whole[::50], rtol=0, atol=1e-12)
    h = 1e-5
    numeric = (load.value(t + h) - load.value(t - h)) / (2 * h)
    np.testing.assert_allclose(load.derivative(t), numeric, atol=1e-6)


def test_random_load_arrays_are_read_only():
    load = RandomLoad.draw(0.0, 1.0, 1.0, np.random.default_rng(0))
    with pytest.raises(ValueError):
        load.frequencies[0] = 0.5


def test_a_long_run_of_many_sines_is_summed_in_slices() -> None:
    """Beyond _multisine's slice (2**20 angles) the sum comes in slices of times: the same values, a bounded memory."""
    load = SinesLoad(0.5, tuple(Sine(1.0 + i, 0.1 * i, 0.2 * i) for i in range(300)))
    t = np.arange(5000) / 100.0
    sliced = load.value(t)
    whole = np.array([load.value(t[k:k + 1000]) for k in range(0, 5000, 1000)]).ravel()
    np.testing.assert_allclose(sliced, whole, rtol=1e-12, atol=1e-9)
    assert load.derivative(t.reshape(50, 100)).shape == (50, 100)
