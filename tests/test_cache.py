"""The on-disk cache: keys, the directory, detection thresholds and isolation networks computed once, files read safely."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import torch

import ea_gym.diagnosis.training as training
import ea_gym.phm.thresholds as thresholds_module
from ea_gym.bondgraph import BondGraph, Kind
from ea_gym.cache import CACHE_DIR_VARIABLE, cache_dir, cache_key, model_definition
from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.diagnosis.database import classes_of
from ea_gym.diagnosis.training import IsolationTraining, cached_isolation_path, isolation_network, shipped_classifier_path
from ea_gym.env.config import EnvConfig
from ea_gym.models import MODELS, get_model, spring_mass_damper
from ea_gym.phm import ChainTiming, DetectorConfig, IsolationConfig, PHMConfig, calibrate_thresholds, thresholds_for
from ea_gym.phm.thresholds import calibration_key, shipped_thresholds

# a short calibration (2 runs of 20 s) keeps these tests to seconds; the logic does not depend on the length
SHORT = PHMConfig(timing=ChainTiming(noise=0.01), detector=DetectorConfig(calibration_runs=2, calibration_duration=20.0, balance_span=20.0))


@pytest.fixture(autouse=True)
def cache_in(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Every test gets its own empty cache."""
    monkeypatch.setenv(CACHE_DIR_VARIABLE, str(tmp_path / "cache"))
    return tmp_path / "cache"


def test_the_variable_moves_the_cache(cache_in: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    assert cache_dir() == cache_in
    monkeypatch.delenv(CACHE_DIR_VARIABLE)
    assert cache_dir().name == "ea-gym"  # the user's cache directory for the package


def test_the_key_follows_what_the_result_depends_on() -> None:
    model, config, rng = spring_mass_damper(), SHORT, np.random.default_rng(0)
    key = calibration_key(model, config, rng)
    # equal inputs built anew, and changes that no computation reads: the same key
    assert calibration_key(spring_mass_damper(), dataclasses.replace(SHORT), np.random.default_rng(0)) == key
    assert calibration_key(dataclasses.replace(model, description="another text", units={}), config, rng) == key
    unread = dataclasses.replace(config, isolation=IsolationConfig(confidence=0.5), timing=dataclasses.replace(config.timing, step_time=10.0))
    assert calibration_key(model, unread, rng) == key
    # a parameter, a limit, a setting the calibration reads, the seed: another key each
    changed = [
        calibration_key(model.with_overrides(parameters={"k": 101.0}), config, rng),
        calibration_key(model.with_overrides(limits={"b": (0.41, 0.6)}), config, rng),
        calibration_key(model, dataclasses.replace(config, timing=ChainTiming(noise=0.02)), rng),
        calibration_key(model, dataclasses.replace(config, detector=dataclasses.replace(config.detector, margin=1.3)), rng),
        calibration_key(model, config, np.random.default_rng(1)),
    ]
    assert len({key, *changed}) == 1 + len(changed)
    assert model_definition(get_model("rlc_circuit")) != model_definition(model)


def test_the_key_keeps_the_elements_order() -> None:
    """The same elements listed in another order give other parameter and feature orders: another key."""
    model = spring_mass_damper()
    graph = BondGraph()
    graph.add("F", Kind.SE).add("v", Kind.ONE)
    graph.add("k", Kind.C, c_form="stiffness").add("m", Kind.I).add("b", Kind.R)
    for element in ("k", "m", "b"):
        graph.connect("v", element)
    graph.connect("F", "v")
    reordered = dataclasses.replace(model, graph=graph)
    del reordered.__dict__["state_space"]  # replace copies the cached state space of the original graph
    assert reordered.parameter_names != model.parameter_names
    rng = np.random.default_rng(0)
    assert calibration_key(reordered, SHORT, rng) != calibration_key(model, SHORT, rng)


def test_canonical_keys_refuse_what_they_cannot_write() -> None:
    with pytest.raises(TypeError, match="object"):
        cache_key("thresholds", 1, settings=object())


def test_cached_thresholds_equal_a_fresh_calibration(cache_in: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    model = spring_mass_damper()
    fresh_rng = np.random.default_rng(5)
    fresh = calibrate_thresholds(model, SHORT, fresh_rng)
    first_rng = np.random.default_rng(5)
    first = thresholds_for(model, SHORT, first_rng)
    assert len(list((cache_in / "thresholds").glob("*.json"))) == 1
    # read back without calibrating: the same values and the generator where the calibration leaves it
    monkeypatch.setattr(thresholds_module, "calibrate_thresholds", lambda *args: pytest.fail("calibrated again"))
    second_rng = np.random.default_rng(5)
    second = thresholds_for(model, SHORT, second_rng)
    assert np.array_equal(first, fresh) and np.array_equal(second, fresh)
    draws = [rng.random(3) for rng in (fresh_rng, first_rng, second_rng)]
    assert np.array_equal(draws[0], draws[1]) and np.array_equal(draws[0], draws[2])


@pytest.mark.parametrize("content", ["{not json", json.dumps({"key": "another key", "thresholds": [1.0]}), json.dumps({"thresholds": "x"})])
def test_a_corrupt_threshold_entry_is_rebuilt(cache_in: Path, content: str) -> None:
    model = spring_mass_damper()
    expected = thresholds_for(model, SHORT, np.random.default_rng(3))
    (entry,) = (cache_in / "thresholds").glob("*.json")
    if "thresholds" in content and "key" not in content:  # the right key, a wrong body
        content = json.dumps({"key": entry.stem, "thresholds": "x"})
    entry.write_text(content)
    with pytest.warns(RuntimeWarning, match="ignoring the cache entry"):
        rebuilt = thresholds_for(model, SHORT, np.random.default_rng(3))
    assert np.array_equal(rebuilt, expected)
    assert json.loads(entry.read_text())["thresholds"] == expected.tolist()


def test_shipped_thresholds_are_the_environments_own() -> None:
    """Every built-in at the environments' default settings is in the shipped table; the spring-mass-damper's values
    are a fresh calibration's (the others' calibrations take seconds each: their keys and shapes are checked).

    To 1e-12, not to the bit: the calibration's simulations go through BLAS, whose kernels differ by processor in
    the last bits (up to 1.3e-13 relative on an AMD EPYC against the table made elsewhere)."""
    config = EnvConfig().phm_config
    table = shipped_thresholds()
    for name in MODELS:
        entry = table[calibration_key(get_model(name), config, np.random.default_rng(0))]
        elements = sum(not element.kind.is_junction for element in get_model(name).graph.elements.values())
        assert entry["model"] == name and len(entry["thresholds"]) == elements + 1  # one per element, then the balance
    model = spring_mass_damper()
    rng = np.random.default_rng(0)
    fresh = calibrate_thresholds(model, config, rng)
    np.testing.assert_allclose(table[calibration_key(model, config, np.random.default_rng(0))]["thresholds"], fresh, rtol=1e-12, atol=0)
    assert table[calibration_key(model, config, np.random.default_rng(0))]["rng_after"] == rng.bit_generator.state


def test_shipped_networks_fit_their_systems() -> None:
    for name in MODELS:
        path = shipped_classifier_path(name)
        assert path.stat().st_size < 100_000  # a few small layers, not a whole training run
        assert FaultClassifier.load(path).classes == classes_of(get_model(name))


def _small_training(model, rng, progress=None, variants=("strong",)) -> IsolationTraining:  # type: ignore[no-untyped-def]
    """Stands in for the minute of training: an untrained network of the right shape."""
    classifier = FaultClassifier(classes_of(model), "strong", 7, (4,))
    classifier.mean = rng.normal(size=7)
    return IsolationTraining(database=None, classifiers={"strong": classifier}, evaluation={})  # type: ignore[arg-type]


def test_a_network_is_trained_once_then_read(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    calls = []
    monkeypatch.setattr(training, "train_isolation", lambda *args, **kwargs: calls.append(1) or _small_training(*args, **kwargs))
    model = dataclasses.replace(spring_mass_damper(), name="my_machine")  # no shipped network
    first = isolation_network(model)
    assert "no isolation network for model 'my_machine'" in capsys.readouterr().err
    second = isolation_network(model)
    assert len(calls) == 1 and cached_isolation_path(model).is_file()
    features = np.random.default_rng(0).normal(size=(5, 7))
    assert np.array_equal(first.predict_proba(features), second.predict_proba(features))
    # another limit is another network
    isolation_network(model.with_overrides(limits={"k": (86.0, 105.0)}))
    assert len(calls) == 2


class _Payload:
    """Unpickling it would run ``os.mkdir``: a file that holds it must be refused."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):  # type: ignore[no-untyped-def]
        return (os.mkdir, (str(self.marker),))


def test_a_corrupt_or_pickled_network_is_rebuilt_without_running_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls = []
    monkeypatch.setattr(training, "train_isolation", lambda *args, **kwargs: calls.append(1) or _small_training(*args, **kwargs))
    model = dataclasses.replace(spring_mass_damper(), name="my_machine")
    path = cached_isolation_path(model)
    path.parent.mkdir(parents=True)
    marker = tmp_path / "payload ran"
    torch.save({"state": _Payload(marker)}, path)
    with pytest.raises(ValueError, match="not an isolation network"):
        FaultClassifier.load(path)
    with pytest.warns(RuntimeWarning, match="ignoring the cache entry"):
        isolation_network(model)
    assert not marker.exists() and len(calls) == 1
    path.write_bytes(b"\x00" * 10)  # truncated
    with pytest.warns(RuntimeWarning, match="ignoring the cache entry"):
        isolation_network(model)
    assert len(calls) == 2 and FaultClassifier.load(path).classes == classes_of(model)


def test_a_fresh_start_computes_nothing_and_imports_no_torch(cache_in: Path) -> None:
    """New processes with an empty cache: the first step of the default environment reads the shipped network and
    thresholds (no thresholds or network written to the cache: nothing calibrated or trained) and never imports torch;
    the first process caches the smoothing filter's coefficients, so that the second does not import scipy.signal."""
    script = textwrap.dedent("""
        import sys
        import gymnasium as gym
        import ea_gym
        env = gym.make("ea_gym/SpringMassDamper-v0")
        env.reset(seed=0)
        env.step(0)
        print("torch" in sys.modules, "scipy.signal" in sys.modules)
    """)
    runs = [subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=os.environ, check=True) for _ in range(2)]
    assert runs[0].stdout.split() == ["False", "True"]
    assert runs[1].stdout.split() == ["False", "False"]
    assert sorted(path.name for path in cache_in.iterdir()) == ["savgol"]


def test_cached_filter_coefficients_are_scipys(cache_in: Path) -> None:
    from scipy.signal import savgol_filter

    from ea_gym.diagnosis.smoothing import SavitzkyGolay

    signal = np.random.default_rng(0).normal(size=(3, 200))
    for _ in range(2):  # computed, then read from the cache
        smoother = SavitzkyGolay(21, 3, 0.01)
        assert np.allclose(smoother(signal, deriv=1), savgol_filter(signal, 21, 3, deriv=1, delta=0.01), rtol=0, atol=1e-9)
    (entry,) = (cache_in / "savgol").glob("*.npz")
    entry.write_bytes(b"PK\x03\x04 truncated")
    with pytest.warns(RuntimeWarning, match="ignoring the cache entry"):
        rebuilt = SavitzkyGolay(21, 3, 0.01)
    assert all(np.array_equal(a, b) for a, b in zip(rebuilt.coefficients(1), smoother.coefficients(1)))


def test_train_isolation_command(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    from ea_gym.cli import main

    calls = []
    monkeypatch.setattr(training, "train_isolation", lambda *args, **kwargs: calls.append(1) or _small_training(*args, **kwargs))
    assert main(["train-isolation", "--system", "rlc_circuit"]) == 0
    assert "shipped with the package" in capsys.readouterr().out
    model_file = str(Path(__file__).resolve().parents[1] / "experiments" / "models" / "two_mass_chain.yaml")
    assert main(["train-isolation", "--system", model_file]) == 0
    assert "trained and cached" in capsys.readouterr().out
    assert main(["train-isolation", "--system", model_file]) == 0
    assert "already cached" in capsys.readouterr().out and len(calls) == 1
    assert main(["train-isolation", "--system", "no_such_system"]) == 2
    assert "unknown system 'no_such_system'" in capsys.readouterr().err
