"""Model files: bad files named precisely, a file equal to a built-in, more than one source, and the
places where a model file stands in for a built-in name (scenario, env, CLI)."""

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from ea_gym.cli import main
from ea_gym.env import ENV_IDS
from ea_gym.loads import ConstantLoad
from ea_gym.model_files import ModelFileError, load_model_file, load_system, model_from_data
from ea_gym.models import ParameterError, spring_mass_damper
from ea_gym.plant import run_model
from ea_gym.scenario import ScenarioError, load_scenario

# the built-in spring_mass_damper written as a file: elements and bonds in the built-in's order
SMD = """\
name: smd_file
description: the paper's spring-mass-damper
elements:
  F: {kind: Se, unit: N}
  v: {kind: "1"}
  m: {kind: I, value: 10.0, unit: kg, limits: [9.0, 11.0]}
  k: {kind: C, form: stiffness, value: 100.0, unit: N/m, limits: [85.0, 105.0]}
  b: {kind: R, value: 0.5, unit: N s/m, limits: [0.4, 0.6]}
bonds: [[v, m], [v, k], [v, b], [F, v]]
load: {source: F, nominal: 10.0, bandwidth: 2.0}
"""


def _write(tmp_path, text, name="model.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


BAD = [
    # (file text, fragment of the message)
    (SMD.replace("[v, b], [F, v]", "[v, x], [F, v]"), "bonds[2]: [v, x]: unknown element 'x'"),
    (SMD.replace("{kind: I, value: 10.0, unit: kg, limits: [9.0, 11.0]}", "{kind: I, unit: kg}"), "elements.m.value: missing"),
    (SMD.replace("value: 0.5", "value: -0.5"), "elements.b.value: expected a finite number > 0 (SI), got -0.5"),
    (SMD.replace("value: 0.5", "value: true"), "elements.b.value: expected a finite number > 0 (SI), got True"),
    (SMD.replace("[85.0, 105.0]", "[85.0, 95.0]"), "elements.k.limits: [85.0, 95.0] must satisfy lower < upper and contain the value 100.0"),
    (SMD.replace("[85.0, 105.0]", "[85.0]"), "elements.k.limits: expected [lower, upper]"),
    (
        SMD.replace('  v: {kind: "1"}', '  v: {kind: "1"}\n  j: {kind: "0"}').replace("[F, v]]", "[F, v], [v, j]]"),
        "elements.j: a 0-junction needs at least 2 bonds, has 1",
    ),
    (SMD.replace("[F, v]]", "[F, v], [m, v]]"), "elements.m: a I element needs exactly 1 bond, has 2"),
    (
        SMD.replace("  b: {", "  m2: {kind: I, value: 2.0}\n  b: {").replace("[F, v]]", "[F, v], [v, m2]]"),
        "bonds: storage elements ['m2'] are in derivative causality",
    ),
    (SMD.replace("  b: {kind: R", "  m: {kind: R"), "the key 'm' appears twice"),
    (SMD.replace("name: smd_file", "name: smd-file"), "name: expected a name of letters, digits and _"),
    (SMD.replace("  v: {", "  2v: {"), "elements.2v: expected a name of letters"),
    (SMD.replace("name: smd_file", "name: spring_mass_damper"), "name: 'spring_mass_damper' is a built-in system's name"),
    (
        SMD.replace("  v: {", "  G: {kind: Se, unit: N}\n  v: {").replace("[F, v]]", "[F, v], [G, v]]"),
        "elements.G.value: missing: a source other than the load source",
    ),
    (SMD.replace("{kind: Se, unit: N}", "{kind: Se, unit: N, value: 3.0}"), "elements.F.value: the load source takes its value from the scenario"),
    (
        SMD.replace("form: stiffness", "form: spring"),
        "elements.k.form: expected stiffness (effort = value x q) or compliance (effort = q / value), got 'spring'",
    ),
    (SMD.replace("kind: R", "kind: Q"), "elements.b.kind: expected one of Se, Sf, R, C, I, TF, GY, 0, 1, got 'Q'"),
    (SMD.replace("kind: R, value", "kind: R, colour: red, value"), "elements.b.colour: not a field of a R element"),
    (SMD.replace("source: F", "source: m"), "load.source: expected one of the sources ['F'], got 'm'"),
    (SMD.replace("bandwidth: 2.0", "bandwidth: 0"), "load.bandwidth: expected a finite number of Hz > 0, got 0"),
    (SMD.replace("load: {source: F, nominal: 10.0, bandwidth: 2.0}", ""), "load: missing (required)"),
    (SMD + "colour: red\n", "colour: unknown field"),
    ("- a\n- b\n", "top level: expected a mapping"),
    (SMD.replace("bonds: [[v, m]", "bonds: [[v, m, k]"), "bonds[0]: expected [tail, head], two element names, got ['v', 'm', 'k']"),
    (SMD.replace("[F, v]]", "[F, v], [F, F]]"), "bonds[4]: [F, F] joins an element to itself"),
    (SMD.replace("[v, m], [v, k], [v, b], [F, v]", "[v, m], [v, k], [v, b], [F, v], [F, m]"), "elements.F: a Se element needs exactly 1 bond, has 2"),
    ("name: [unclosed\n", "the file is not valid YAML"),
    (SMD.replace("value: 0.5", "value: " + "9" * 400), "elements.b.value: expected a finite number > 0 (SI), got 999"),
]


@pytest.mark.parametrize("text, fragment", BAD, ids=[f"{i}" for i in range(len(BAD))])
def test_bad_model_files_name_the_culprit(tmp_path, text, fragment):
    with pytest.raises(ModelFileError) as error:
        load_model_file(_write(tmp_path, text))
    message = str(error.value)
    assert fragment in message
    assert "\n" not in message and message.startswith(f"model file {tmp_path}")


def test_a_two_port_needs_one_bond_in_and_one_out(tmp_path):
    text = SMD.replace("  v: {", "  T: {kind: TF, value: 2.0}\n  v: {").replace("[F, v]]", "[F, T], [v, T]]")
    with pytest.raises(ModelFileError, match=r"elements\.T: a TF element needs exactly one bond in .* has 2 in and 0 out"):
        load_model_file(_write(tmp_path, text))


def test_files_beyond_the_limits_are_refused(tmp_path):
    deep = "[" * 40 + "]" * 40
    with pytest.raises(ModelFileError, match="nests deeper than 32 levels"):
        load_model_file(_write(tmp_path, deep, "deep.json"))
    with pytest.raises(ModelFileError, match="not a regular file"):
        load_model_file(tmp_path)
    with pytest.raises(ModelFileError, match="bytes"):
        load_model_file(_write(tmp_path, " " * ((1 << 20) + 1), "big.json"))
    with pytest.raises(ModelFileError, match="appears twice"):
        load_model_file(_write(tmp_path, '{"name": "a", "name": "b"}', "twice.json"))


def test_every_problem_is_reported_on_one_line(tmp_path):
    text = SMD.replace("value: 0.5", "value: 0").replace("[85.0, 105.0]", "[101.0, 105.0]")
    with pytest.raises(ModelFileError) as error:
        load_model_file(_write(tmp_path, text))
    assert "elements.b.value" in str(error.value) and "elements.k.limits" in str(error.value)


def test_a_file_equal_to_the_builtin_gives_byte_identical_matrices(tmp_path):
    from_file, builtin = load_model_file(_write(tmp_path, SMD)), spring_mass_damper()
    assert from_file.parameter_names == builtin.parameter_names and from_file.state_names == builtin.state_names
    assert dict(from_file.safe_limits) == dict(builtin.safe_limits) and dict(from_file.nominal) == dict(builtin.nominal)
    theta = np.random.default_rng(0).uniform(0.5, 2.0, (7, 3)) * builtin.parameter_vector()
    for a, b in zip(vars(from_file.state_space.matrices(theta)).values(), vars(builtin.state_space.matrices(theta)).values()):
        assert a.tobytes() == b.tobytes()
    # JSON reads the same
    data = __import__("yaml").safe_load(SMD)
    as_json = load_model_file(_write(tmp_path, json.dumps(data), "model.json"))
    assert as_json.state_space.matrices(theta).A.tobytes() == builtin.state_space.matrices(theta).A.tobytes()


def test_a_constant_second_source_gives_the_analytic_static_offset():
    """F (the load) and G = 3 N (constant) push one damped mass on a spring: it settles at q = (F + G) / k;
    started there it does not move; with the Sf form a constant velocity source turns the spring at rate v."""
    data = __import__("yaml").safe_load(SMD)
    data["elements"]["G"] = {"kind": "Se", "value": 3.0, "unit": "N"}
    data["elements"]["b"]["value"] = 20.0  # damping ratio 0.32: settled to 1e-9 within 30 s
    data["elements"]["b"]["limits"] = [15.0, 25.0]
    data["bonds"].append(["G", "v"])
    model = model_from_data(data)
    assert model.state_space.input_names == ("F", "G")
    t = np.arange(3001) * 0.01
    run = run_model(model, t, ConstantLoad(level=10.0))
    k = model.nominal["k"]
    q = run.states[:, model.state_names.index("k")]
    assert q[-1] == pytest.approx(13.0 / k, rel=1e-9)
    np.testing.assert_allclose(run.effort["G"], 3.0)
    at_rest = run_model(model, t, ConstantLoad(level=10.0), initial_state=np.array([0.0, 13.0 / k]))
    np.testing.assert_allclose(at_rest.states[:, 1], 13.0 / k, rtol=1e-12)
    np.testing.assert_allclose(at_rest.power["G"], 0.0, atol=1e-12)


def test_a_constant_flow_source_winds_the_spring_at_its_rate():
    """A damped mass pulled through a spring whose far end an Sf drags at 0.2 m/s (the 0-junction: spring
    rate = 0.2 - mass velocity): at steady state the mass moves at 0.2 m/s and the spring holds the
    damper's force, k q = b v."""
    data = {
        "name": "dragged",
        "elements": {
            "F": {"kind": "Se"}, "v": {"kind": "1"}, "m": {"kind": "I", "value": 2.0}, "b": {"kind": "R", "value": 4.0},
            "e": {"kind": "0"}, "k": {"kind": "C", "form": "stiffness", "value": 50.0}, "S": {"kind": "Sf", "value": 0.2},
        },
        "bonds": [["F", "v"], ["v", "m"], ["v", "b"], ["e", "v"], ["e", "k"], ["S", "e"]],
        "load": {"source": "F", "nominal": 1.0, "bandwidth": 1.0},
    }
    model = model_from_data(data)
    t = np.arange(4001) * 0.01
    run = run_model(model, t, ConstantLoad(level=0.0))
    # steady state: the mass at 0.2 m/s, the damper's force b v balanced by the spring: k q = b v
    assert run.flow["m"][-1] == pytest.approx(0.2, rel=1e-8)
    assert run.states[-1, model.state_names.index("k")] == pytest.approx(4.0 * 0.2 / 50.0, rel=1e-8)


def test_a_c_element_without_its_form_is_refused_naming_it_and_the_forms(tmp_path):
    text = SMD.replace("form: stiffness, ", "")
    with pytest.raises(ModelFileError) as error:
        load_model_file(_write(tmp_path, text))
    assert str(error.value).endswith(
        "elements.k.form: expected stiffness (effort = value x q) or compliance (effort = q / value), got nothing (a C element states its form)"
    )


def test_every_model_file_in_the_repository_states_its_c_forms():
    root = Path(__file__).resolve().parents[1]
    files = [path for path in sorted(root.glob("experiments/**/*.yaml")) if "elements:" in path.read_text()]
    assert files  # the examples are found wherever they move
    for path in files:
        load_model_file(path)  # a C element without its form is refused


# a damped mass on a spring whose far end a road's vertical velocity moves: zero-mean, the load an Sf
ROAD = """name: on_the_road
elements:
  zr: {kind: Sf, unit: m/s}
  e: {kind: "0"}
  k: {kind: C, form: stiffness, value: 100.0, unit: N/m, limits: [85.0, 105.0]}
  v: {kind: "1"}
  m: {kind: I, value: 10.0, unit: kg, limits: [9.0, 11.0]}
  b: {kind: R, value: 5.0, unit: N s/m}
bonds: [[zr, e], [e, k], [e, v], [v, m], [v, b]]
load: {source: zr, nominal: 0.0, scale: 0.1, bandwidth: 2.0}
"""


def test_a_zero_mean_flow_source_is_a_load_whose_random_loads_follow_its_scale(tmp_path):
    from ea_gym.diagnosis.database import draw_loads

    model = load_model_file(_write(tmp_path, ROAD))
    assert model.load_source == "zr" and model.nominal_load == 0.0 and model.random_load_scale == 0.1
    t = np.arange(20001) * 0.01
    values = np.array([load.value(t) for load in draw_loads(model, 8, np.random.default_rng(0))])
    assert np.all(np.abs(values.mean(axis=1)) < 0.01) and np.all((0.015 < values.std(axis=1)) & (values.std(axis=1) < 0.05))
    assert spring_mass_damper().random_load_scale == spring_mass_damper().nominal_load  # the built-ins: as before
    assert main(["model", str(tmp_path / "model.yaml")]) == 0


@pytest.mark.parametrize(
    ("load", "fragment"),
    [
        ("{source: zr, nominal: 0.0, bandwidth: 2.0}", "load.scale: missing: a zero-mean load (nominal 0) needs the size of its variation"),
        ("{source: zr, nominal: zero, scale: 0.1, bandwidth: 2.0}", "load.nominal: expected a finite number (the load's operating level"),
        ("{source: zr, nominal: 0.0, scale: -1, bandwidth: 2.0}", "load.scale: expected a finite number > 0"),
    ],
)
def test_a_bad_load_field_is_blamed_not_the_load_source(tmp_path, load, fragment):
    text = ROAD.replace("{source: zr, nominal: 0.0, scale: 0.1, bandwidth: 2.0}", load)
    with pytest.raises(ModelFileError) as error:
        load_model_file(_write(tmp_path, text))
    assert fragment in str(error.value) and "elements.zr" not in str(error.value)


def test_a_scenario_names_a_model_file_relative_to_itself(tmp_path):
    (tmp_path / "models").mkdir()
    _write(tmp_path / "models", SMD, "smd.yaml")
    scenario = {"system": "models/smd.yaml", "load": {"kind": "constant", "value": 10.0}, "duration": 1.0,
                "fault": {"parameter": "k", "profile": [[0, 100], [1, 95]]}}
    path = _write(tmp_path, json.dumps(scenario), "scenario.json")
    loaded = load_scenario(path)
    assert loaded.model.name == "smd_file" and loaded.system == "models/smd.yaml"
    assert load_scenario(loaded.to_dict()).model.name == "smd_file"  # the dict names the file from anywhere
    with pytest.raises(ScenarioError, match=r"system: model file .*absent\.yaml: cannot read the file"):
        load_scenario(dict(scenario, system="absent.yaml"))
    with pytest.raises(ParameterError, match=r"^unknown system 'pendulum'.* or a model file"):
        load_system("pendulum")


def test_the_environment_takes_a_model_file(tmp_path):
    path = _write(tmp_path, SMD)
    env = gym.make(ENV_IDS[1], system=str(path), obs_mode="sensors")
    observation, _ = env.reset(seed=0)
    assert env.unwrapped.core.model.name == "smd_file"
    assert env.observation_space.contains(observation)
    env.close()


def test_the_model_command_prints_the_causality_and_a_bad_file_exits_2(tmp_path, capsys):
    assert main(["model", str(_write(tmp_path, SMD))]) == 0
    text = capsys.readouterr().out
    assert "F -> v: stroke at v (F sets the effort)" in text and "k = 100 N/m, limits [85, 105]" in text
    assert "m (I): its input is its effort (integral)" in text
    assert "fastest mode: |lambda| = 3.16 1/s at the nominal values; a sample rate above 1.01 Hz resolves it" in text  # sqrt(10)/pi
    assert main(["model", str(_write(tmp_path, SMD.replace("value: 0.5", "value: -0.5")))]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1
    assert captured.err.startswith("ea-gym model: error: model file ") and "elements.b.value" in captured.err


def test_simulate_with_a_bad_system_exits_2_and_writes_nothing(tmp_path, capsys):
    scenario = _write(tmp_path, json.dumps({"system": "spring_mass_damper", "load": {"kind": "constant", "value": 1.0}, "duration": 1.0}), "s.json")
    bad = _write(tmp_path, SMD.replace("[F, v]]", "[F, v], [v, x]]"))
    out = tmp_path / "out"
    assert main(["simulate", str(scenario), "--system", str(bad), "--out", str(out)]) == 2
    assert "bonds[4]: [v, x]: unknown element 'x'" in capsys.readouterr().err
    assert not out.exists()
    good = _write(tmp_path, SMD, "good.yaml")
    assert main(["simulate", str(scenario), "--system", str(good), "--out", str(out)]) == 0
    assert set(json.loads((out / "energy.json").read_text())["elements"]) == {"F", "m", "k", "b"}


def test_models_lists_the_builtins(capsys):
    assert main(["models"]) == 0
    text = capsys.readouterr().out
    for name in ("spring_mass_damper", "rlc_circuit", "dc_motor"):
        assert f"{name}: " in text
    assert "C1 = 0.01 F, limits [0.008, 0.012]" in text


@pytest.mark.parametrize("command", ["train", "benchmark"])
def test_train_and_benchmark_refuse_a_bad_system_before_anything_is_written(tmp_path, capsys, command):
    bad = _write(tmp_path, SMD.replace("value: 0.5", "value: 0"))
    out = tmp_path / "out"
    assert main([command, "--system", str(bad), "--env", "horizon=60", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"ea-gym {command}: error: model file ") and "elements.b.value" in err and err.count("\n") == 1
    assert not out.exists()


def test_environment_options_are_read_as_json():
    from ea_gym.cli_args import env_option

    assert env_option("horizon=600") == ("horizon", 600)
    assert env_option("obs_mode=sensors") == ("obs_mode", "sensors")
    assert env_option('costs={"failure": 500}') == ("costs", {"failure": 500})
    with pytest.raises(Exception, match="KEY=VALUE"):
        env_option("600")


def _gravity_model():
    """The spring-mass-damper file with a constant second source G (a weight of 3 N) on the mass."""
    data = __import__("yaml").safe_load(SMD)
    data["elements"]["G"] = {"kind": "Se", "value": 3.0, "unit": "N"}
    data["bonds"].append(["G", "v"])
    return model_from_data(data)


def test_the_tracking_step_of_a_model_with_a_constant_source_equals_the_plant():
    from ea_gym.bondgraph.simulation import hermite_coefficients
    from ea_gym.loads import Sine, SinesLoad
    from ea_gym.phm.tracking import transition

    model, h = _gravity_model(), 0.01
    load = SinesLoad(10.0, (Sine(4.0, 0.3), Sine(1.0, 1.1)))
    t = np.arange(201) * h
    run = run_model(model, t, load)
    step = transition(model, model.parameter_vector(), h)
    assert step.shape == (2, 2 + 4 + 1)  # Phi, the load's four Taylor columns, the constant sources' column
    w = hermite_coefficients(load.value(t)[:, None], load.derivative(t)[:, None], h)
    predicted = run.states[:-1] @ step[:, :2].T + w @ step[:, 2:6].T + step[:, 6]
    np.testing.assert_allclose(predicted, run.states[1:], rtol=0, atol=1e-12 * np.abs(run.states).max())


def test_the_monitor_adds_what_a_constant_source_puts_on_every_bond():
    """Nominal-law powers of the R and C elements and both sources from smoothed signals equal the bond
    values' products with the whole input vector, the constant source included."""
    from ea_gym.diagnosis.monitor import Monitor
    from ea_gym.loads import Sine, SinesLoad

    model = _gravity_model()
    monitor = Monitor(model, 0.01)
    load = SinesLoad(10.0, (Sine(4.0, 0.3),))
    t = np.arange(301) * 0.01
    run = run_model(model, t, load)
    signals = np.concatenate([run.states.T / np.array([10.0, 1.0])[:, None], load.value(t)[None]])
    power, smooth = monitor.powers(signals, 0)
    mats = model.state_space.matrices(model.parameter_vector())
    x = smooth[:2] * np.array([10.0, 1.0])[:, None]  # momentum and displacement
    u = np.stack([smooth[2], np.full(smooth.shape[1], 3.0)])  # F, then G
    z = mats.Cy @ x + mats.Dy @ u
    names, efforts, flows, signs = model.state_space.element_bonds()
    for name in ("k", "b", "F", "G"):
        i = names.index(name)
        expected = z[efforts[i]] * signs[i] * z[flows[i]]
        np.testing.assert_allclose(power[monitor.elements.index(name)], expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    assert np.abs(power[monitor.elements.index("G")]).max() > 0.1  # the weight does work as the mass moves


@pytest.mark.parametrize("scenario", ["two_mass_k2_ramp.json", "two_mass_weighted_k2_ramp.json"])
def test_the_committed_model_files_and_their_scenarios_load(scenario):
    from pathlib import Path

    loaded = load_scenario(Path(__file__).parent.parent / "experiments" / "scenarios" / scenario)
    assert loaded.fault is not None and loaded.fault.parameter == "k2"
    assert loaded.model.state_names == ("m1", "k1", "k2", "m2") and "k2" in loaded.model.safe_limits


def test_the_fastest_mode_must_be_resolved_at_the_sample_rate():
    """|lambda| < pi * sample_rate: the spring-mass-damper's |lambda| = sqrt(k / m) = sqrt(10) 1/s (its eigenvalues
    -b/2m +- i sqrt(k/m - (b/2m)^2), modulus sqrt(k/m)) passes just above sqrt(10) / pi Hz, not just below; a tiny mass
    gives the real mode -b/m, set by m and b, not k."""
    model = spring_mass_damper()
    edge = np.sqrt(10.0) / np.pi
    model.check_resolved(1.001 * edge, "sample_rate")
    assert model.fastest_mode() == pytest.approx(np.sqrt(10.0), rel=1e-12)
    with pytest.raises(ParameterError, match=r"sample_rate: the model's fastest mode, \|lambda\| = 3.16 1/s") as info:
        model.check_resolved(0.999 * edge, "sample_rate")
    assert "m = 10 kg" in str(info.value) and "k = 100 N/m" in str(info.value) and "b = " not in str(info.value)
    tiny_mass = model_from_data(__import__("yaml").safe_load(SMD.replace("value: 10.0, unit: kg, limits: [9.0, 11.0]", "value: 1.0e-20, unit: kg")))
    with pytest.raises(ParameterError, match=r"\|lambda\| = 5e\+19 1/s") as info:
        tiny_mass.check_resolved(100.0, "sample_rate")
    assert "m = 1e-20 kg" in str(info.value) and "b = 0.5 N s/m" in str(info.value) and "k = " not in str(info.value)
