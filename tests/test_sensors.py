"""The measurement model: each I element's sensor reads its flow p / I, each C element's its displacement q."""

import numpy as np

from ea_gym.models import get_model, spring_mass_damper
from ea_gym.sensors import Sensors


def test_a_mass_is_read_as_its_velocity_and_a_spring_as_its_extension():
    model = spring_mass_damper()  # states (p of m, q of k), parameters (m, k, b)
    sensors = Sensors(model)
    assert sensors.signals == ("m", "k") and sensors.momenta == ((0, 0),)
    theta = np.array([[10.0, 100.0, 0.5], [8.0, 90.0, 0.4]])  # two systems, the second worn
    states = np.array([[[20.0, 0.1], [30.0, 0.2]], [[16.0, 0.3], [8.0, 0.4]]])  # (N, T, nx)
    signals = sensors.measure(theta, states, 0.0, np.random.default_rng(0))
    np.testing.assert_array_equal(signals, [[[2.0, 3.0], [0.1, 0.2]], [[2.0, 1.0], [0.3, 0.4]]])  # (N, nx, T)
    np.testing.assert_array_equal(sensors.matrix(theta[0]), [[0.1, 0.0], [0.0, 1.0]])
    np.testing.assert_array_equal(sensors.inverse_gain(theta), [[10.0, 1.0], [8.0, 1.0]])
    # parameters that change over the window, (N, T, P): each sample measured under its own values
    over_time = np.array([[[10.0, 100.0, 0.5], [20.0, 100.0, 0.5]]])  # the mass doubled at the second sample
    np.testing.assert_array_equal(sensors.measure(over_time, states[:1], 0.0, np.random.default_rng(0))[0, 0], [2.0, 1.5])


def test_every_storage_element_has_a_sensor_and_only_inertias_scale_it():
    model = get_model("dc_motor")
    sensors = Sensors(model)
    assert sensors.signals == tuple(model.state_names)
    nominal = model.parameter_vector()
    gain = sensors.gain(nominal)
    inertias = [j for j, _ in sensors.momenta]
    assert inertias and all(gain[j] == 1.0 / nominal[p] for j, p in sensors.momenta)
    assert all(gain[j] == 1.0 for j in range(len(gain)) if j not in inertias)
    # measuring without noise then scaling back by the inverse gain gives the energy variables again
    states = np.random.default_rng(1).normal(size=(1, 5, len(gain)))
    back = sensors.measure(nominal[None], states, 0.0, np.random.default_rng(0)) * sensors.inverse_gain(nominal)[None, :, None]
    np.testing.assert_allclose(back, states.transpose(0, 2, 1), rtol=1e-15)
