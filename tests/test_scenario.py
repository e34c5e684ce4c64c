import copy
import json
import math

import numpy as np
import pytest
import yaml

from ea_gym.loads import ConstantLoad, RandomLoad, SinesLoad
from ea_gym.scenario import RandomLoadSpec, ScenarioError, load_scenario

PAPER = {
    "system": "spring_mass_damper",
    "parameters": {"m": 10.0, "k": 100.0, "b": 0.5},
    "limits": {"k": [85, 105]},
    "load": {"kind": "constant", "value": 10.0},
    "duration": 120.0,
    "sample_rate": 100.0,
    "initial_state": {"k": 0.01},
    "fault": {"parameter": "k", "profile": [[0, 100], [5, 100], [50, 86.5], [100, 100]]},
    "sensors": {"noise": 0.01, "seed": 0},
}


def modified(change):
    data = copy.deepcopy(PAPER)
    change(data)
    return data


@pytest.fixture
def paper_json(tmp_path):
    path = tmp_path / "paper.json"
    path.write_text(json.dumps(PAPER))
    return path


def test_paper_scenario_loads_with_its_values(paper_json):
    s = load_scenario(paper_json)
    assert s.source == str(paper_json)
    assert s.system == "spring_mass_damper" and s.model.name == "spring_mass_damper"
    assert dict(s.model.nominal) == {"m": 10.0, "k": 100.0, "b": 0.5}
    assert s.model.safe_limits["k"] == (85.0, 105.0)
    assert s.duration == 120.0 and s.sample_rate == 100.0
    assert s.n_samples == 12000
    times = s.times()
    assert times.shape == (12001,) and times[0] == 0.0 and times[-1] == pytest.approx(120.0, abs=1e-12)
    assert times[1] == pytest.approx(0.01)
    assert s.noise == 0.01 and s.sensor_seed == 0
    assert s.fault.parameter == "k"
    assert s.fault.profile.times == (0.0, 5.0, 50.0, 100.0)
    assert s.fault.profile.values == (100.0, 100.0, 86.5, 100.0)
    load = s.make_load()
    assert isinstance(load, ConstantLoad) and load.level == 10.0
    # state_names of the spring-mass-damper are ('m', 'k'): momentum of m, displacement of k
    np.testing.assert_array_equal(s.initial_state_vector(), [0.0, 0.01])


def test_parameters_at_follows_the_fault_profile(paper_json):
    s = load_scenario(paper_json)
    t = np.array([[0.0, 27.5], [75.0, 200.0]])
    p = s.parameters_at(t)
    assert p.shape == (2, 2, 3)
    assert s.model.parameter_names == ("m", "k", "b")
    np.testing.assert_array_equal(p[..., 0], np.full((2, 2), 10.0))
    np.testing.assert_array_equal(p[..., 2], np.full((2, 2), 0.5))
    np.testing.assert_allclose(p[..., 1], [[100.0, 93.25], [93.25, 100.0]], rtol=0, atol=1e-12)


def test_defaults_without_optional_fields():
    s = load_scenario({"system": "rlc_circuit", "load": {"kind": "constant", "value": 5.0}, "duration": 2.0})
    assert s.sample_rate == 100.0 and s.n_samples == 200
    assert s.fault is None and s.noise == 0.0 and s.sensor_seed == 0 and s.source == "dict"
    np.testing.assert_array_equal(s.initial_state_vector(), [0.0, 0.0])
    np.testing.assert_array_equal(s.parameters_at(np.array([0.0, 1.0])), np.tile([2.0, 1.0, 0.01, 50.0], (2, 1)))


def test_overrides_reach_the_model():
    s = load_scenario(modified(lambda d: d.update(parameters={"b": 0.55}, limits={"m": [9.5, 10.5]})))
    assert s.model.nominal["b"] == 0.55 and s.model.nominal["m"] == 10.0
    assert s.model.safe_limits["m"] == (9.5, 10.5) and s.model.safe_limits["k"] == (85.0, 105.0)


def test_yaml_loads_the_same_as_json(tmp_path, paper_json):
    path = tmp_path / "paper.yaml"
    path.write_text(yaml.safe_dump(PAPER))
    from_yaml, from_json = load_scenario(path), load_scenario(paper_json)
    assert from_yaml.to_dict() == from_json.to_dict()
    assert from_yaml.source.endswith("paper.yaml")


def test_round_trip_through_to_dict(tmp_path, paper_json):
    s = load_scenario(paper_json)
    data = s.to_dict()
    path = tmp_path / "again.json"
    path.write_text(json.dumps(data))  # JSON-serialisable
    again = load_scenario(path)
    assert again.to_dict() == data
    assert dict(again.model.nominal) == dict(s.model.nominal)
    assert again.fault == s.fault and again.initial_state == s.initial_state


def test_sines_load_from_scenario():
    load_data = {"kind": "sines", "offset": 10.0, "sines": [{"amplitude": 5.0, "frequency": 0.25}]}
    s = load_scenario(modified(lambda d: d.update(load=load_data)))
    load = s.make_load()
    assert isinstance(load, SinesLoad)
    np.testing.assert_allclose(load.value(np.array([0.0, 1.0])), [10.0, 15.0], atol=1e-12)
    assert s.to_dict()["load"] == {**load_data, "sines": [{"amplitude": 5.0, "frequency": 0.25, "phase": 0.0}]}


def test_random_load_from_scenario_is_seeded():
    load_data = {"kind": "random", "mean": 10.0, "std": 3.0, "bandwidth": 2.0, "seed": 1}
    s = load_scenario(modified(lambda d: d.update(load=load_data)))
    assert isinstance(s.load_spec, RandomLoadSpec)
    a, b = s.make_load(), s.make_load()
    assert isinstance(a, RandomLoad)
    np.testing.assert_array_equal(a.frequencies, b.frequencies)
    np.testing.assert_array_equal(a.phases, b.phases)
    other = load_scenario(modified(lambda d: d.update(load={**load_data, "seed": 2}))).make_load()
    assert not np.array_equal(a.phases, other.phases)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (lambda d: d.update(system="pendulum"), r"system: unknown system 'pendulum'.*spring_mass_damper"),
        (lambda d: d.update(parameters={"mass": 10.0}), r"parameters\.mass: unknown parameter.*\['m', 'k', 'b'\]"),
        (lambda d: d.update(limits={"c": [1, 2]}), r"limits\.c: unknown parameter.*\['m', 'k', 'b'\]"),
        (lambda d: d["fault"].update(parameter="q"), r"fault\.parameter: unknown parameter.*\['m', 'k', 'b'\]"),
        (lambda d: d.update(parameters={"m": 0.0}), r"parameters\.m: 'm' = 0\.0 is outside its physical range"),
        (lambda d: d.update(parameters={"m": -1.0}), r"parameters\.m: .*> 0 kg"),
        (lambda d: d["fault"]["profile"].__setitem__(2, [50, 0]), r"fault\.profile\[2\]: 'k' = 0\.0"),
        (lambda d: d["fault"]["profile"].__setitem__(2, [50, -5]), r"fault\.profile\[2\]: 'k' = -5\.0"),
        (lambda d: d.update(limits={"k": [105, 85]}), r"limits\.k: lower limit 105\.0 must be below"),
        (lambda d: d.update(limits={"k": [90, 90]}), r"limits\.k: lower limit 90\.0 must be below"),
        (lambda d: d["fault"]["profile"].__setitem__(2, [3, 86.5]), r"fault\.profile\[2\]: .*strictly increasing"),
        (lambda d: d["fault"]["profile"].__setitem__(0, [-1, 100]), r"fault\.profile\[0\]: .*negative"),
        (lambda d: d["sensors"].update(noise=-0.01), r"sensors\.noise: .*greater than or equal to 0"),
        (
            lambda d: d.update(load={"kind": "ramp", "value": 1}),
            r"load\.kind: expected one of 'constant', 'sines', 'random' \(got 'ramp'\)",
        ),
        (lambda d: d.update(load={"value": 1}), r"load\.kind: expected one of .*\(missing\)"),
        (lambda d: d.pop("duration"), r"\n  duration: Field required"),
        (lambda d: d.update(duration=math.nan), r"duration: Input should be a finite number"),
        (lambda d: d.update(parameters={"k": math.inf}), r"parameters\.k: Input should be a finite number"),
        (lambda d: d.update(colour="red"), r"colour: Extra inputs are not permitted"),
        (lambda d: d["sensors"].update(gain=2), r"sensors\.gain: Extra inputs are not permitted"),
        (
            lambda d: d.update(load={"kind": "random", "mean": 10, "std": 3, "bandwidth": 50, "seed": 1}),
            r"load\.bandwidth: 50\.0 Hz must be below the Nyquist frequency sample_rate / 2 = 50\.0 Hz",
        ),
        (lambda d: d.update(load={"kind": "random", "mean": 10, "std": -3, "bandwidth": 2, "seed": 1}), r"load\.std: "),
        (
            lambda d: d.update(load={"kind": "sines", "sines": [{"amplitude": 1, "frequency": -1}]}),
            r"load\.sines\[0\]\.frequency: Input should be greater than or equal to 0",
        ),
        (lambda d: d.update(initial_state={"x": 0.1}), r"initial_state\.x: unknown state 'x'.*\['m', 'k'\]"),
        (lambda d: d.update(duration=1.005), r"duration: duration \* sample_rate = 100\.49.* whole number"),
        (lambda d: d.update(duration="120"), r"duration: Input should be a valid number"),
    ],
    ids=[
        "unknown-system",
        "unknown-parameter",
        "unknown-limit",
        "unknown-fault-parameter",
        "zero-mass",
        "negative-mass",
        "zero-fault-value",
        "negative-fault-value",
        "limits-reversed",
        "limits-equal",
        "unsorted-profile",
        "negative-profile-time",
        "negative-noise",
        "unknown-load-kind",
        "missing-load-kind",
        "missing-duration",
        "nan-duration",
        "inf-parameter",
        "extra-top-level-field",
        "extra-sensors-field",
        "bandwidth-at-nyquist",
        "negative-std",
        "negative-sine-frequency",
        "unknown-initial-state",
        "non-integer-samples",
        "string-duration",
    ],
)
def test_bad_input_names_the_field(change, match):
    with pytest.raises(ScenarioError, match=match) as info:
        load_scenario(modified(change))
    assert str(info.value).startswith("invalid scenario (dict):\n  ")


def test_every_problem_is_listed_one_per_line():
    data = modified(lambda d: d.update(duration=-1.0, sample_rate=0.0, colour="red"))
    with pytest.raises(ScenarioError) as info:
        load_scenario(data)
    assert [p.split(":")[0] for p in info.value.problems] == ["duration", "sample_rate", "colour"]
    assert str(info.value).splitlines()[1:] == ["  " + p for p in info.value.problems]


def test_missing_file(tmp_path):
    path = tmp_path / "absent.json"
    expected = r"invalid scenario \(.*absent\.json\):\n  cannot read the file: No such file"
    with pytest.raises(ScenarioError, match=expected):
        load_scenario(path)


def test_malformed_json(tmp_path):
    path = tmp_path / "broken.json"
    path.write_text('{"system": "spring_mass_damper",')
    with pytest.raises(ScenarioError, match=r"invalid scenario \(.*broken\.json\):\n  the file is not valid JSON"):
        load_scenario(path)


def test_malformed_yaml(tmp_path):
    path = tmp_path / "broken.yml"
    path.write_text("system: [unclosed\n")
    with pytest.raises(ScenarioError, match=r"broken\.yml\):\n  the file is not valid YAML"):
        load_scenario(path)


def test_top_level_must_be_an_object(tmp_path):
    path = tmp_path / "list.json"
    path.write_text("[1, 2]")
    with pytest.raises(ScenarioError, match=r"list\.json\):\n  the top level must be an object, got list"):
        load_scenario(str(path))
