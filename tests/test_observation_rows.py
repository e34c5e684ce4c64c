"""The compiled observation (``Observer.observe``) equals its numpy form to the bit, in every mode, with
idle (down) systems and with NaN, inf and out-of-range values."""

import numpy as np
import pytest

from ea_gym.env.config import env_config
from ea_gym.env.observations import OBSERVATION_BOUND, PARAMETER_POSITION_BOUNDS, RESIDUAL_FLOOR, Observer, OracleTruth


def numpy_observation(observer, outputs, since_maintenance, down, oracle):
    """The observation as numpy arrays compute it, key by key."""
    idle, config = observer.idle, observer.config
    merged = {key: np.where(down.reshape((-1,) + (1,) * (idle[key].ndim - 1)), idle[key], outputs.get(key, idle[key])) for key in idle}
    low, span = observer.limits[:, 0], observer.limits[:, 1] - observer.limits[:, 0]
    obs = {
        "ea": merged["ea"],
        "eai": merged["eai"],
        "residual": (merged["ea"] - merged["ea_reference"]) / np.maximum(merged["ea_reference"], RESIDUAL_FLOOR),
        "time_since_maintenance": np.minimum(since_maintenance[:, None], observer.longest_run),
        "maintenance_in_progress": down.astype(float)[:, None],
    }
    if config.obs_mode == "oracle":
        diagnosis = np.zeros((observer.n, len(observer.classes)))
        diagnosis[np.arange(observer.n), oracle.diagnosis_class] = 1.0
        obs |= {"diagnosis": diagnosis, "parameter_estimate": oracle.values, "rul": np.repeat(oracle.rul[:, None], 3, axis=1)}
    elif config.obs_mode == "phm":
        obs |= {"diagnosis": merged["diagnosis"], "parameter_estimate": merged["estimates"], "rul": merged["rul"]}
    if "rul" in obs:
        obs["parameter_estimate"] = np.clip((obs["parameter_estimate"] - low) / span, *PARAMETER_POSITION_BOUNDS)
        obs["rul"] = np.clip(np.where(np.isnan(obs["rul"]), config.rul_max, obs["rul"]), 0.0, config.rul_max)
    return {key: np.clip(value, -OBSERVATION_BOUND, OBSERVATION_BOUND).astype(np.float32) for key, value in obs.items()}


@pytest.mark.parametrize("mode", ["phm", "oracle", "sensors"])
def test_observation_is_its_numpy_form_to_the_bit(mode):
    n, elements, components, classes = 7, ("Se", "R", "C", "I"), ("R", "C", "I"), ("none", "R", "C")
    limits = np.array([[0.5, 2.0], [10.0, 40.0]])
    config = env_config(None, obs_mode=mode)
    observer = Observer(config, n, elements, components, classes, limits, np.array([1.0, 20.0]))
    rng = np.random.default_rng(3)
    special = np.array([np.nan, np.inf, -np.inf, 0.0, 5e6, -5e6, 1e-13])

    def values(shape):
        x = rng.normal(size=shape) * 10.0 ** rng.integers(-3, 7, size=shape)
        x.flat[rng.integers(0, x.size, size=x.size // 3)] = rng.choice(special, size=x.size // 3)
        return x

    outputs = {
        "ea": np.abs(values((n, 4))), "ea_reference": np.abs(values((n, 4))), "eai": rng.dirichlet(np.ones(3), size=n),
        "diagnosis": rng.dirichlet(np.ones(3), size=n), "estimates": limits[:, 0] + values((n, 2)), "rul": values((n, 3)),
    }
    since = np.abs(values(n))
    down = np.arange(n) % 3 == 1
    oracle = OracleTruth(values=values((n, 2)), diagnosis_class=rng.integers(0, 3, n), rul=values(n))
    for systems_down in (down, np.zeros(n, dtype=bool)):
        got = observer.observe(outputs, since, systems_down, oracle)
        with np.errstate(invalid="ignore"):  # inf / inf: NaN, as the kernel gives it
            expected = numpy_observation(observer, outputs, since, systems_down, oracle)
        assert list(got) == list(expected)
        for key in expected:
            assert got[key].dtype == np.float32
            np.testing.assert_array_equal(got[key].view(np.int32), expected[key].view(np.int32), err_msg=key)
