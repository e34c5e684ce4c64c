"""Generated inputs (hypothesis, bounded and derandomized): scenario, model-file (data and typed YAML), measurement and
agent.json parsing and the environments' settings raise nothing but the project's own validation errors, each one line.

A few hundred examples per target (400 each, 2,800 in all) keep the file to seconds; ``derandomize`` makes every run
draw the same examples.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ea_gym.env.config import env_config
from ea_gym.measurements import MeasurementError, read_measurements
from ea_gym.model_files import ModelFileError, load_model_file
from ea_gym.models import spring_mass_damper
from ea_gym.scenario import ScenarioError, load_scenario

FUZZ = settings(max_examples=400, deadline=None, derandomize=True, database=None, suppress_health_check=[HealthCheck.too_slow])

NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(min_value=-(10**400), max_value=10**400), st.booleans(),
    st.sampled_from([0, 1, -1, 0.5, 10.0, 100.0, 1e-20, 1e300]),
)
TEXT = st.sampled_from(["", "k", "m", "b", "x", "constant", "sines", "random", "spring_mass_damper", "dc_motor", "1", "Se"])
VALUES = st.recursive(st.one_of(st.none(), NUMBERS, TEXT), lambda inner: st.lists(inner, max_size=4) | st.dictionaries(TEXT, inner, max_size=4),
                      max_leaves=12)

GOOD_SCENARIO: dict[str, Any] = {
    "system": "spring_mass_damper", "parameters": {"m": 10.0}, "limits": {"k": [85, 105]},
    "load": {"kind": "sines", "offset": 1.0, "sines": [{"amplitude": 1.0, "frequency": 1.0, "phase": 0.0}]},
    "duration": 10.0, "sample_rate": 100.0, "initial_state": {"k": 0.01},
    "fault": {"parameter": "k", "profile": [[0, 100], [5, 90]]}, "sensors": {"noise": 0.01, "seed": 0},
}


def _mutated(document: dict[str, Any], data: st.DataObject) -> dict[str, Any]:
    """``document`` with a few fields replaced, removed or added, at any depth."""
    result = json.loads(json.dumps(document))
    for _ in range(data.draw(st.integers(1, 3))):
        target = result
        while isinstance(target, dict) and target and data.draw(st.booleans()):
            key = data.draw(st.sampled_from(sorted(target)))
            if not isinstance(target[key], dict):
                break
            target = target[key]
        if not isinstance(target, dict):
            continue
        key = data.draw(st.sampled_from(sorted(target)) | TEXT if target else TEXT)
        if data.draw(st.booleans()) and key in target:
            del target[key]
        else:
            target[key] = data.draw(VALUES)
    return result


@FUZZ
@given(st.data())
def test_scenarios(data: st.DataObject) -> None:
    document = _mutated(GOOD_SCENARIO, data)
    try:
        scenario = load_scenario(document)
    except ScenarioError:
        return
    assert scenario.n_samples >= 1


@FUZZ
@given(st.text(max_size=300) | st.binary(max_size=300).map(lambda raw: raw.decode("latin-1")))
def test_scenario_files(text: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "scenario.yaml"
        path.write_text(text, encoding="utf-8", errors="surrogateescape")
        try:
            load_scenario(path)
        except ScenarioError:
            pass


SMD = {
    "name": "smd", "elements": {
        "F": {"kind": "Se", "unit": "N"}, "v": {"kind": "1"},
        "m": {"kind": "I", "value": 10.0, "unit": "kg", "limits": [9.0, 11.0]},
        "k": {"kind": "C", "form": "stiffness", "value": 100.0, "limits": [85.0, 105.0]},
        "b": {"kind": "R", "value": 0.5, "limits": [0.4, 0.6]},
    },
    "bonds": [["v", "m"], ["v", "k"], ["v", "b"], ["F", "v"]],
    "load": {"source": "F", "nominal": 10.0, "bandwidth": 2.0},
}


SMD_YAML = """\
name: smd
elements:
  F: {kind: Se, unit: N}
  v: {kind: "1"}
  m: {kind: I, value: 10.0, unit: kg, limits: [9.0, 11.0]}
  k: {kind: C, form: stiffness, value: 100.0, limits: [85.0, 105.0]}
  b: {kind: R, value: 0.5, limits: [0.4, 0.6]}
bonds: [[v, m], [v, k], [v, b], [F, v]]
load: {source: F, nominal: 10.0, bandwidth: 2.0}
"""


def _one_line(error: Exception) -> None:
    """A refusal is one line of bounded length (the CLI prints it as ``ea-gym CMD: error: <it>``, exit code 2)."""
    message = str(error)
    assert "\n" not in message and len(message) < 4000, message[:4000]


@FUZZ
@given(st.data())
def test_model_files(data: st.DataObject) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.json"
        path.write_text(json.dumps(_mutated(SMD, data)))
        try:
            load_model_file(path)
        except ModelFileError as error:
            _one_line(error)


@FUZZ
@given(st.data())
def test_model_file_texts(data: st.DataObject) -> None:
    """YAML as people type it: a good file's text with characters replaced, inserted or cut."""
    text = SMD_YAML
    for _ in range(data.draw(st.integers(1, 4))):
        at = data.draw(st.integers(0, len(text)))
        text = text[:at] + data.draw(st.sampled_from(["", "e-1", "0" * 5000, "\x1b[2J", "t", "{", "]", ": ", "\n  x: {kind: I}"])) + text[at + 1:]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.yaml"
        path.write_text(text)
        try:
            load_model_file(path)
        except ModelFileError as error:
            _one_line(error)


CELLS = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.integers(-5, 5).map(str), st.sampled_from(["", "x", "1e999", "-"]))


@FUZZ
@given(st.lists(st.lists(CELLS, min_size=0, max_size=6), max_size=8), st.booleans())
def test_measurement_files(rows: list[list[str]], good_header: bool) -> None:
    header = "t,F,m,k" if good_header else ",".join(rows[0]) if rows else ""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "data.csv"
        path.write_text("\n".join([header, *(",".join(row) for row in rows)]) + "\n")
        try:
            read_measurements(path, spring_mass_damper())
        except MeasurementError as error:
            _one_line(error)


AGENT = json.loads((Path(__file__).parents[1] / "agents" / "data" / "ppo_oracle" / "agent.json").read_text())


@FUZZ
@given(st.data())
def test_agent_files(data: st.DataObject) -> None:
    """agent.json with fields replaced, removed or added at any depth: read (torch's spaces built) or refused by name."""
    from agents.agent_files import read_agent

    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "agent.json").write_text(json.dumps(_mutated(AGENT, data)))
        try:
            read_agent(Path(tmp))
        except ValueError as error:
            _one_line(error)


SETTINGS = ["step_seconds", "window_seconds", "sample_rate", "noise", "horizon", "obs_mode", "costs", "wear", "corrective_rate",
            "continue_after_failure", "rul_max", "load_std", "phm"]


@FUZZ
@given(st.dictionaries(st.sampled_from(SETTINGS), VALUES | st.tuples(NUMBERS, NUMBERS), max_size=3))
def test_environment_settings(overrides: dict[str, Any]) -> None:
    try:
        env_config(**overrides)
    except (ValueError, TypeError) as error:  # the settings' own refusals name the field
        assert any(name in str(error) for name in (*SETTINGS, "cost model")), error
