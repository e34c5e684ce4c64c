"""The ``ea-gym simulate`` command: well-formed results, clear errors, nothing written half."""

import json

import numpy as np
import pytest

from ea_gym.cli import main

SCENARIO = {
    "system": "spring_mass_damper",
    "load": {"kind": "sines", "offset": 10.0, "sines": [{"amplitude": 5.0, "frequency": 0.3}]},
    "duration": 20.0,
    "fault": {"parameter": "k", "profile": [[0, 100], [5, 100], [20, 95.5]]},
}


def _write(tmp_path, scenario):
    path = tmp_path / "scenario.json"
    path.write_text(json.dumps(scenario))
    return path


def test_simulate_writes_energy_json_and_png(tmp_path):
    out = tmp_path / "out"
    assert main(["simulate", str(_write(tmp_path, SCENARIO)), "--out", str(out), "--window", "2"]) == 0
    data = json.loads((out / "energy.json").read_text())
    assert data["window"] == 2.0
    assert data["t"] == [0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 14.0, 16.0, 18.0]
    assert set(data["elements"]) == {"F", "m", "k", "b"}
    assert "eai" not in data["elements"]["F"]  # a source reports EA but is no component
    eai = np.array([data["elements"][n]["eai"] for n in ("m", "k", "b")])
    np.testing.assert_allclose(eai.sum(axis=0), 1.0, rtol=0, atol=1e-12)
    ea = np.array(data["elements"]["b"]["ea"])
    assert ea.shape == (10,) and np.all(ea > 0)
    assert (out / "energy.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_simulate_bad_scenario_reports_the_field_and_writes_nothing(tmp_path, capsys):
    bad = dict(SCENARIO, parameters={"m": -1.0})
    out = tmp_path / "out"
    assert main(["simulate", str(_write(tmp_path, bad)), "--out", str(out)]) == 2
    assert "parameters.m" in capsys.readouterr().err
    assert not out.exists()


def test_simulate_window_not_a_whole_number_of_samples_is_an_error(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["simulate", str(_write(tmp_path, SCENARIO)), "--out", str(out), "--window", "0.015"]) == 2
    assert "window" in capsys.readouterr().err
    assert not out.exists()


def test_help_explains_every_option(capsys):
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    text = capsys.readouterr().out
    for option in ("SCENARIO", "--out", "--window"):
        assert option.lower() in text.lower()


def test_agents_commands_come_through_the_entry_point_group(capsys):
    """ea_gym never imports agents: train and benchmark are found in the ``ea_gym.commands`` entry points."""
    from importlib.metadata import entry_points

    from ea_gym.cli_args import COMMAND_GROUP

    assert {e.name: e.value for e in entry_points(group=COMMAND_GROUP)} == {
        "train": "agents.cli:add_train", "benchmark": "agents.cli:add_benchmark", "convert-agent": "agents.cli:add_convert_agent"}
    with pytest.raises(SystemExit):
        main(["--help"])
    text = capsys.readouterr().out
    for command in ("simulate", "phm", "reproduce", "train", "benchmark", "convert-agent"):
        assert command in text
