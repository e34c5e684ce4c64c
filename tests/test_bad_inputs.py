"""Bad inputs, one table: each case is the input and a fragment of the message it must be refused with.

Command-line cases also check the refusal's form: exit code 2, one line on stderr (``ea-gym CMD: error: ...``), no
traceback, and nothing written. The CLI reference (docs/cli.md) states how many cases this table holds (``test_the_docs_state_the_count``).
"""

from __future__ import annotations

import errno
import io
import json
import math
import os
import shutil
import subprocess
import sys
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from payloads import malicious_agent  # tests/payloads.py

import ea_gym.files
from ea_gym.cli import main
from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.energy import activity_index, energy_activity
from ea_gym.env.maintenance import BondGraphMaintenanceEnv
from ea_gym.env.vector import BondGraphMaintenanceVectorEnv

GOOD = {"system": "spring_mass_damper", "load": {"kind": "constant", "value": 10.0}, "duration": 10.0, "sample_rate": 100.0}

NO_LIMITS_MODEL = """\
name: smd_no_limits
elements:
  F: {kind: Se, unit: N}
  v: {kind: "1"}
  m: {kind: I, value: 10.0, unit: kg}
  k: {kind: C, form: stiffness, value: 100.0, unit: N/m}
  b: {kind: R, value: 0.5, unit: N s/m}
bonds: [[v, m], [v, k], [v, b], [F, v]]
load: {source: F, nominal: 10.0, bandwidth: 2.0}
"""


def scenario(**changes: Any) -> dict[str, Any]:
    return {**GOOD, **changes}


def _write(path: Path, content: Any) -> Path:
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    return path


# Each command-line case: (id, a function making the files in a directory and returning the arguments, message fragment).
Setup = Callable[[Path], list[str]]


def _scenario_case(data: Any, command: str = "simulate", *extra: str) -> Setup:
    def setup(tmp: Path) -> list[str]:
        return [command, str(_write(tmp / "bad.json", data)), "--out", str(tmp / "out"), *extra]

    return setup


def _fifo(tmp: Path) -> list[str]:
    os.mkfifo(tmp / "x.json")
    return ["simulate", str(tmp / "x.json"), "--out", str(tmp / "out")]


def _deep(tmp: Path) -> list[str]:
    return ["simulate", str(_write(tmp / "deep.json", "[" * 200_000 + "]" * 200_000)), "--out", str(tmp / "out")]


def _out_at(where: Callable[[Path], Path]) -> Setup:
    def setup(tmp: Path) -> list[str]:
        return ["simulate", str(_write(tmp / "ok.json", GOOD)), "--out", str(where(tmp))]

    return setup


def _existing_file(tmp: Path) -> Path:
    return _write(tmp / "taken", "a file")


def _under_a_file(tmp: Path) -> Path:
    return _write(tmp / "taken", "a file") / "out"


def _evil(tmp: Path) -> Path:
    """stable-baselines3's files of an agent whose pickles would create ``tmp/ran``: a refusal writes nothing, not even that."""
    return malicious_agent(tmp / "evil", tmp / "ran", {"obs_mode": "oracle", "n_envs": 2})


def _made(directory: Path) -> Path:
    directory.mkdir()
    return directory


def _classifier(make: Callable[[Path], Path]) -> Setup:
    def setup(tmp: Path) -> list[str]:
        return ["phm", str(_write(tmp / "ok.json", GOOD)), "--out", str(tmp / "out"), "--classifier", str(make(tmp))]

    return setup


def _torch_dict_without_classes(tmp: Path) -> Path:
    import torch

    torch.save({"variant": "strong"}, tmp / "net.pt")
    return tmp / "net.pt"


def _no_limits(command: str) -> Setup:
    def setup(tmp: Path) -> list[str]:
        _write(tmp / "model.yaml", NO_LIMITS_MODEL)
        return [command, str(_write(tmp / "s.json", scenario(system="model.yaml"))), "--out", str(tmp / "out")]

    return setup


TINY_MASS_MODEL = NO_LIMITS_MODEL.replace("value: 10.0, unit: kg", "value: 1.0e-20, unit: kg").replace(
    "value: 100.0, unit: N/m", "value: 100.0, unit: N/m, limits: [80.0, 120.0]")


def _tiny_mass(command: str) -> Setup:
    def setup(tmp: Path) -> list[str]:
        _write(tmp / "model.yaml", TINY_MASS_MODEL)
        return [command, str(_write(tmp / "s.json", scenario(system="model.yaml"))), "--out", str(tmp / "out")]

    return setup


def _model_case(text: str) -> Setup:
    def setup(tmp: Path) -> list[str]:
        return ["model", str(_write(tmp / "model.yaml", text))]

    return setup


def _slow_measurements(tmp: Path) -> list[str]:
    """A spring-mass-damper record at 0.1 Hz: its 0.5 Hz resonance is beyond Nyquist."""
    rows = "".join(f"{10.0 * i},10.0,0.0,0.0\n" for i in range(30))
    csv = _write(tmp / "slow.csv", "t,F,m,k\n" + rows)
    return ["phm", "--system", "spring_mass_damper", "--measurements", str(csv), "--out", str(tmp / "out")]


#: a valid spring-mass-damper record: 3 s at 100 Hz, at rest under 10 N
RECORD = "t,F,m,k\n" + "".join(f"{i / 100:.2f},10,0,0.1\n" for i in range(300))


def _phm_record(*extra: str, healthy_rate: float | None = None) -> Setup:
    """``phm --measurements`` on RECORD with ``extra`` arguments; with ``healthy_rate``, --commission a record at that rate."""

    def setup(tmp: Path) -> list[str]:
        csv = _write(tmp / "data.csv", RECORD)
        more = []
        if healthy_rate is not None:
            rows = "".join(f"{i / healthy_rate:.4f},10,0,0.1\n" for i in range(600))
            more = ["--commission", str(_write(tmp / "healthy.csv", "t,F,m,k\n" + rows))]
        return ["phm", "--system", "spring_mass_damper", "--measurements", str(csv), "--out", str(tmp / "out"), *more, *extra]

    return setup


def _measurements_case(content: str) -> Setup:
    def setup(tmp: Path) -> list[str]:
        csv = _write(tmp / "data.csv", content)
        return ["phm", "--system", "spring_mass_damper", "--measurements", str(csv), "--out", str(tmp / "out")]

    return setup


HUGE_MODEL = NO_LIMITS_MODEL.replace("value: 10.0, unit: kg", "value: 1.0e+308, unit: kg").replace(
    "value: 100.0, unit: N/m", "value: 1.0e+308, unit: N/m")

#: a committed agent directory, copied and edited by the agent cases
SHIPPED_AGENT = Path(__file__).parents[1] / "agents" / "data" / "ppo_oracle"


def _agent(tmp: Path, edit: Callable[[dict[str, Any]], object] = lambda data: None) -> Path:
    """A copy of a committed agent in ``tmp/agent``, its agent.json edited by ``edit``."""
    agent = tmp / "agent"
    shutil.copytree(SHIPPED_AGENT, agent)
    data = json.loads((agent / "agent.json").read_text())
    edit(data)
    _write(agent / "agent.json", data)
    return agent


def _resume_edited(edit: Callable[[dict[str, Any]], object]) -> Setup:
    return lambda tmp: ["train", "--resume", str(_agent(tmp, edit)), "--out", str(tmp / "out")]


def _benchmark_edited(edit: Callable[[dict[str, Any]], object]) -> Setup:
    return lambda tmp: ["benchmark", "--ppo", str(_agent(tmp, edit)), "--episodes", "1", "--out", str(tmp / "out")]


def _resume_in_place_with_a_link(link: str) -> Setup:
    """train --resume R --out R, ``R/<link>`` a symbolic link to a directory outside R."""

    def setup(tmp: Path) -> list[str]:
        agent = _agent(tmp)
        (agent / link).parent.mkdir(parents=True, exist_ok=True)
        (tmp / "elsewhere").mkdir()
        (agent / link).symlink_to(tmp / "elsewhere", target_is_directory=True)
        return ["train", "--resume", str(agent), "--out", str(agent)]

    return setup


def _linked_to_dev_zero(name: str) -> Setup:
    def setup(tmp: Path) -> list[str]:
        agent = _agent(tmp)
        (agent / name).unlink()
        (agent / name).symlink_to("/dev/zero")
        return ["benchmark", "--ppo", str(agent), "--episodes", "1", "--out", str(tmp / "out")]

    return setup


def _model_yaml(tmp: Path, text: str) -> list[str]:
    return ["model", str(_write(tmp / "model.yaml", text))]


def _many(kind: str, count: int) -> str:
    """NO_LIMITS_MODEL with ``count`` more elements of ``kind`` (C elements bonded to the mass's junction)."""
    extra = "".join(f"  x{i}: {{kind: C, form: stiffness, value: 1.0}}\n" if kind == "C" else f"  x{i}: {{kind: \"0\"}}\n" for i in range(count))
    bonds = "".join(f", [v, x{i}]" for i in range(count)) if kind == "C" else ""
    return NO_LIMITS_MODEL.replace("bonds: [", extra + "bonds: [").replace("[F, v]]", "[F, v]" + bonds + "]")


ISLAND_MODEL = NO_LIMITS_MODEL.replace(
    "bonds: [", "  w: {kind: \"1\"}\n  m2: {kind: I, value: 1.0}\n  b2: {kind: R, value: 1.0}\nbonds: [[w, m2], [w, b2], ")


def _many_columns(tmp: Path) -> list[str]:
    return _measurements_case(",".join(f"c{i}" for i in range(60_000)) + "\n")(tmp)


def _late_times(tmp: Path) -> list[str]:
    """A record at 100 Hz whose times are seconds since 1970 (around 1.7e9 s) written to 1e12 s: float64 holds 1e-4 s there."""
    return _measurements_case("t,F,m,k\n" + "".join(f"{1e12 + i / 100:.2f},10,0,0\n" for i in range(300)))(tmp)


def _truncated_weights(tmp: Path) -> list[str]:
    """policy.safetensors with one tensor cut to another shape."""
    from safetensors.numpy import load_file, save_file

    agent = _agent(tmp)
    tensors = load_file(agent / "policy.safetensors")
    name = sorted(tensors)[0]
    tensors[name] = tensors[name][..., :1].copy()
    save_file(tensors, agent / "policy.safetensors")
    return ["benchmark", "--ppo", str(agent), "--episodes", "1", "--out", str(tmp / "out")]


def _sines(count: int, **changes: Any) -> dict[str, Any]:
    return scenario(load={"kind": "sines", "sines": [{"amplitude": 1.0, "frequency": 1.0}] * count}, **changes)


CLI_CASES: list[tuple[str, Setup, str]] = [
    ("duration 1e9", _scenario_case(scenario(duration=1e9)), "at most 1000000 per run"),
    ("sample_rate 1e7", _scenario_case(scenario(sample_rate=1e7)), "at most 1000000 per run"),
    ("1e6 Hz over 10 s", _scenario_case(scenario(sample_rate=1e6)), "at most 1000000 per run"),
    ("/dev/zero", lambda tmp: ["simulate", "/dev/zero", "--out", str(tmp / "out")], "not a regular file"),
    ("a FIFO named x.json", _fifo, "not a regular file"),
    ("JSON nested 200,000 deep", _deep, "nests deeper than 32 levels"),
    ("1000 Hz sine at 100 Hz", _scenario_case(scenario(load={"kind": "sines", "sines": [{"amplitude": 1.0, "frequency": 1000.0}]})),
     "load.sines[0].frequency: 1000.0 Hz must be below the Nyquist frequency"),
    ("m = 1e-20", _scenario_case(scenario(parameters={"m": 1e-20})), "parameters.m: 'm' = 1e-20 is more than a factor 1000"),
    ("fault profile at 1e6 x nominal", _scenario_case(scenario(fault={"parameter": "k", "profile": [[0, 100], [5, 1e8]]})),
     "fault.profile[1]"),
    ("sensor noise 1e6", _scenario_case(scenario(sensors={"noise": 1e6})), "sensors.noise: Input should be less than 1"),
    ("fault and faults together", _scenario_case(scenario(fault={"parameter": "k", "profile": [[0, 100]]},
                                                          faults=[{"parameter": "b", "profile": [[0, 0.5]]}])),
     "faults: give either fault (one) or faults (a list of them), not both"),
    ("a parameter listed twice in faults", _scenario_case(scenario(faults=[{"parameter": "k", "profile": [[0, 100]]},
                                                                           {"parameter": "k", "profile": [[0, 90]]}]), "phm"),
     "faults[1].parameter: 'k' is already faulty (faults[0]); expected each parameter at most once"),
    ("faults as an object", _scenario_case(scenario(faults={"parameter": "k", "profile": [[0, 100]]})), "faults: Input should be a valid list"),
    ("a second fault's profile at 1e6 x nominal", _scenario_case(scenario(faults=[{"parameter": "k", "profile": [[0, 100]]},
                                                                                  {"parameter": "b", "profile": [[0, 0.5], [5, 5e5]]}])),
     "faults[1].profile[1]: 'b' = 500000.0 is more than a factor 1000"),
    ("load noise 2", _scenario_case(scenario(sensors={"load_noise": 2.0})), "sensors.load_noise: Input should be less than 1"),
    ("phm --load-noise 1.5", _phm_record("--load-noise", "1.5"), "argument --load-noise: expected a load noise fraction in [0, 1), got '1.5'"),
    ("phm --load-noise with a scenario", _scenario_case(GOOD, "phm", "--load-noise", "0.01"), "--load-noise goes with --measurements"),
    ("phm --commission-seconds 0", _phm_record("--commission-seconds", "0"), "argument --commission-seconds: expected a positive number"),
    ("phm --commission-seconds beyond the record", _phm_record("--commission-seconds", "1e9"),
     "--commission-seconds: 1e+09 s; expected at least 2 s and at most the duration of"),
    ("phm --commission with a scenario", _scenario_case(GOOD, "phm", "--commission", "healthy.csv"), "--commission goes with --measurements"),
    ("phm --commission and --commission-seconds", _phm_record("--commission-seconds", "2", healthy_rate=100.0),
     "--commission: give a healthy record or --commission-seconds S (the record's first seconds), not both"),
    ("phm --commission at another rate", _phm_record(healthy_rate=200.0), "healthy.csv is sampled at 200 Hz, "),
    ("phm --commission missing", _phm_record("--commission", "absent.csv"), "absent.csv: cannot read the measurements"),
    ("limits excluding the nominal", _scenario_case(scenario(limits={"k": [200, 300]})), "limits.k: 'k' = 100.0 is not inside its safe limits"),
    ("parameter outside its limits", _scenario_case(scenario(parameters={"k": 120.0})), "parameters.k: 'k' = 120.0 is not inside"),
    ("load 1e300", _scenario_case(scenario(load={"kind": "constant", "value": 1e300})),
     "load.value: Input should be less than or equal to 1000000000"),
    ("sine amplitude 1e300", _scenario_case(scenario(load={"kind": "sines", "sines": [{"amplitude": 1e300, "frequency": 1.0}]})),
     "load.sines[0].amplitude"),
    ("phm at 0.1 Hz", _scenario_case(scenario(sample_rate=0.1, duration=100.0), "phm"),
     "sample_rate: the model's fastest mode, |lambda| = 3.16 1/s, set by "),
    ("phm at 1.5 Hz", _scenario_case(scenario(sample_rate=1.5, duration=100.0), "phm"), "sample_rate: 1.5 Hz gives 1.5 samples per 1 s step"),
    ("m: 1e-20 in the model file", _tiny_mass("simulate"), "m = 1e-20 kg, is not resolved at 100 Hz; expected |lambda| < pi * sample_rate"),
    ("a fault profile faster than the sample rate",
     _scenario_case(scenario(sample_rate=10.0, fault={"parameter": "k", "profile": [[0, 100], [5, 1e5]]})),
     "fault.profile[1]: the model's fastest mode, |lambda| = 100 1/s"),
    ("measurements too slow for the model", _slow_measurements, "sample rate: the model's fastest mode, |lambda| = 3.16 1/s"),
    ("a C element's form as a list", _model_case(NO_LIMITS_MODEL.replace("form: stiffness", "form: [1]")),
     "elements.k.form: expected stiffness (effort = value x q) or compliance (effort = q / value), got a list"),
    ("phm on a bad scenario", _scenario_case(scenario(duration=-1.0), "phm"), "duration: Input should be greater than 0"),
    ("simulate --window 1e9", _scenario_case(GOOD, "simulate", "--window", "1e9"), "--window: 1e+09 s is longer than the run (10 s)"),
    ("simulate --window 0.015", _scenario_case(GOOD, "simulate", "--window", "0.015"), "--window: window = 0.015 s must be a positive whole number"),
    ("simulate --window -1", _scenario_case(GOOD, "simulate", "--window", "-1"), "argument --window: expected a positive number"),
    ("simulate without --out or --csv", lambda tmp: ["simulate", str(_write(tmp / "ok.json", GOOD))], "give --out DIR"),
    ("--out at an existing file", _out_at(_existing_file), "is an existing file; expected a directory"),
    ("--out under a file", _out_at(_under_a_file), "is a file, not a directory"),
    ("--classifier at a text file", _classifier(lambda tmp: _write(tmp / "net.pt", "not a network")), "not an isolation network"),
    ("--classifier without classes", _classifier(_torch_dict_without_classes), "not an isolation network (KeyError: 'classes')"),
    ("--classifier missing", _classifier(lambda tmp: tmp / "absent.pt"), "absent.pt: not an isolation network"),
    ("phm on a model without limits", _no_limits("phm"), "has no degradable parameter"),
    ("train --out at an existing file", lambda tmp: ["train", "--out", str(_existing_file(tmp))], "is an existing file; expected a directory"),
    ("benchmark --out under a file", lambda tmp: ["benchmark", "--out", str(_under_a_file(tmp))], "is a file, not a directory"),
    ("train --out at a non-empty directory", lambda tmp: ["train", "--out", str(_write(_made(tmp / "out") / "notes.txt", "kept").parent)],
     "exists and is not empty; expected a new or empty directory, or the --resume agent's own directory"),
    ("benchmark --write-tuned at a directory", lambda tmp: ["benchmark", "--out", str(tmp / "out"), "--tune", "--write-tuned", str(tmp)],
     "is a directory; expected a file to write"),
    ("train --resume an SB3 zip holding a payload", lambda tmp: ["train", "--resume", str(_evil(tmp) / "model.zip"), "--out", str(tmp / "out")],
     "model.zip is a stable-baselines3 zip, whose data is unpickled on loading"),
    ("train --resume a vecnormalize.pkl payload", lambda tmp: ["train", "--resume", str(_evil(tmp) / "vecnormalize.pkl"), "--out", str(tmp / "o")],
     "vecnormalize.pkl is a pickle"),
    ("benchmark --ppo a directory of pickles", lambda tmp: ["benchmark", "--ppo", str(_evil(tmp)), "--out", str(tmp / "out")],
     "would run any code it holds"),
    ("--classifier holding a pickle payload", _classifier(lambda tmp: _evil(tmp) / "blob"), "blob: not an isolation network"),
    ("train --env horizon=true", lambda tmp: ["train", "--out", str(tmp / "out"), "--env", "horizon=true"], "horizon must be an int in"),
    ("--window abc", lambda tmp: ["simulate", "x.json", "--window", "abc"], "argument --window: invalid positive_float value: 'abc'"),
    ("a CSV with CR-only line endings", _measurements_case("t,F,m,k\r0,10,0,0\r0.01,x,0,0\r"),
     "line 3, column 'F': 'x' where a number is expected"),
    ("a 200,000-character CSV cell", _measurements_case("t,F,m,k\n0," + "1" * 200_000 + ",0,0\n"),
     "data.csv: line 2: field larger than field limit (131072)"),
    ("m = k = 1e308 in a model file", _model_case(HUGE_MODEL), "elements.m.value: 1e+308 is outside [1e-30, 1e+30]"),
    ("agent.json net_arch [-1]", _benchmark_edited(lambda d: d["policy"]["kwargs"].update(net_arch=[-1])),
     "policy.kwargs.net_arch must be a list of layer widths (integers >= 1)"),
    ('agent.json learning_rate "fast"', _resume_edited(lambda d: d["hyperparameters"].update(learning_rate="fast")),
     "hyperparameters.learning_rate must be a finite number > 0, got 'fast'"),
    ("agent.json _init_setup_model false", _resume_edited(lambda d: d["hyperparameters"].update(_init_setup_model=False)),
     "hyperparameters._init_setup_model is not a hyperparameter ppo takes from a file"),
    ("agent.json clip_obs -1", _benchmark_edited(lambda d: d["normalization"].update(clip_obs=-1)),
     "normalization.clip_obs must be a finite number > 0, got -1"),
    ("agent.json num_timesteps -5", _resume_edited(lambda d: d.update(num_timesteps=-5)), "num_timesteps must be an integer >= 0"),
    ("train --resume R --out R, R/checkpoints a link", _resume_in_place_with_a_link("checkpoints"),
     "agent/checkpoints is a symbolic link; expected"),
    ("train --resume R --out R, a checkpoint a link", _resume_in_place_with_a_link("checkpoints/ppo_1000_steps"),
     "agent/checkpoints/ppo_1000_steps is a symbolic link; expected"),
    ("benchmark --ppo an agent.json linked to /dev/zero", _linked_to_dev_zero("agent.json"), "agent/agent.json is a symbolic link"),
    # bounds on what a file asks for, checked before anything is allocated (these also run under a memory cap: BOUNDED)
    ("a scenario of 24,000 sines", _scenario_case(_sines(24_000)), "load.sines: List should have at most 1000 items"),
    ("999 sines above Nyquist", _scenario_case(scenario(load={"kind": "sines", "sines": [{"amplitude": 1.0, "frequency": 1e3}] * 999})),
     "load.sines[7].frequency: 1000.0 Hz must be below the Nyquist frequency sample_rate / 2 = 50.0 Hz; ... (999 problems in all)"),
    ("1000 sines over 1e6 samples", _scenario_case(_sines(1000, duration=10_000.0)),
     "load.sines: 1000 sines over 1e+06 samples are 1e+09 sine terms; at most 100000000 per run"),
    ("a model file of 15,000 unbonded junctions", lambda tmp: _model_yaml(tmp, _many("0", 15_000)),
     "elements: 15005 elements; a model file holds at most 500"),
    ("a model file of 400 unbonded junctions", lambda tmp: _model_yaml(tmp, _many("0", 400)),
     "elements.x7: a 0-junction needs at least 2 bonds, has 0; ... (400 problems in all)"),
    ("a model file of 14,000 C elements", lambda tmp: _model_yaml(tmp, _many("C", 14_000)),
     "elements: 14005 elements; a model file holds at most 500"),
    ("a model file of 101 states", lambda tmp: _model_yaml(tmp, _many("C", 100)),
     "elements: 102 storage elements (I, C), each a state; a model holds at most 100 states"),
    ("a model file of 1001 bonds", lambda tmp: _model_yaml(tmp, NO_LIMITS_MODEL.replace("[F, v]]", "[F, v]" + ", [v, m]" * 997 + "]")),
     "bonds: 1001 bonds; a model file holds at most 1000"),
    ("a CSV header of 60,000 columns", _many_columns, "the header has 60000 columns; a record has at most 1024"),
    ("agent.json net_arch [30000, 30000]", _benchmark_edited(lambda d: d["policy"]["kwargs"].update(net_arch=[30_000, 30_000])),
     "policy.kwargs.net_arch [30000, 30000] makes a network of 1.8e+09 parameters; at most 1e+07"),
    ("agent.json action n 1e9", _benchmark_edited(lambda d: d["action_space"].update(n=10**9)),
     "action_space.n must be an integer in [1, 1024], got 1000000000"),
    ("agent.json n_steps 1e8", _resume_edited(lambda d: d["hyperparameters"].update(n_steps=10**8)),
     "hyperparameters.n_steps = 100000000 makes a training buffer of 22.4 GiB per environment; at most 1 GiB"),
    # silently wrong before
    ("parts not connected to any source", lambda tmp: _model_yaml(tmp, ISLAND_MODEL),
     "bonds: w, m2, b2 not connected to any source (their EA would stay 0)"),
    ("an element named t", lambda tmp: _model_yaml(tmp, NO_LIMITS_MODEL.replace("  k:", "  t:").replace("[v, k]", "[v, t]")),
     "elements.t: the name 't' is reserved (the time column of measurement files)"),
    ("a terminal escape in a unit", lambda tmp: _model_yaml(tmp, NO_LIMITS_MODEL.replace("unit: kg", 'unit: "\\e[2Jkg"')),
     "elements.m.unit: expected text such as N/m (no control characters), got '\\x1b[2Jkg'"),
    # unclear before
    ("a 5,000-digit integer", lambda tmp: _model_yaml(tmp, NO_LIMITS_MODEL.replace("value: 0.5", "value: 1" + "0" * 5000)),
     "model.yaml: line 7, field 'value': a number of 5001 digits; expected a number of at most 4300 digits"),
    ("t around 1e12 s", _late_times,
     "column 't': times up to 1e+12 s are too large for their resolution: a float64 there resolves 0.000122 s"),
    ("a policy tensor of another shape", _truncated_weights, "has shape ["),
    ("benchmark --ppo a policy.safetensors linked to /dev/zero", _linked_to_dev_zero("policy.safetensors"),
     "agent/policy.safetensors is a symbolic link"),
]

#: the cases of bounds, run again in a process whose memory is capped (``test_bounds_hold_under_a_memory_cap``)
BOUNDED = ["a scenario of 24,000 sines", "1000 sines over 1e6 samples", "a model file of 15,000 unbonded junctions",
           "a model file of 14,000 C elements", "a model file of 101 states", "a CSV header of 60,000 columns",
           "agent.json net_arch [30000, 30000]", "agent.json action n 1e9", "agent.json n_steps 1e8"]


def _snapshot(directory: Path) -> set[str]:
    return {str(path.relative_to(directory)) for path in directory.rglob("*")}


@pytest.mark.parametrize("setup, fragment", [case[1:] for case in CLI_CASES], ids=[case[0] for case in CLI_CASES])
def test_a_bad_command_line_is_one_clean_line(setup: Setup, fragment: str, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    argv = setup(tmp_path)
    before = _snapshot(tmp_path)
    try:
        code: object = main(argv)
    except SystemExit as exit_:  # argparse's refusals
        code = exit_.code
    stderr = capsys.readouterr().err
    assert code == 2
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith(f"ea-gym {argv[0]}: error: ")
    assert fragment in lines[0]
    assert "Traceback" not in stderr
    assert _snapshot(tmp_path) == before  # nothing written


#: the address space a bound's refusal runs in: numpy, pydantic and gymnasium imported, far from what the inputs asked for
MEMORY_CAP = 2 << 30
#: Python's first line in such a process
CAPPED = f"import resource, sys, warnings; resource.setrlimit(resource.RLIMIT_AS, ({MEMORY_CAP}, {MEMORY_CAP})); "


@pytest.mark.parametrize("name", BOUNDED)
def test_bounds_hold_under_a_memory_cap(name: str, tmp_path: Path) -> None:
    """The refusal comes before the allocation: the command runs in a process of at most MEMORY_CAP bytes."""
    setup, fragment = next(case[1:] for case in CLI_CASES if case[0] == name)
    argv = setup(tmp_path)
    code = CAPPED + "from ea_gym.cli import main; sys.exit(main(sys.argv[1:]))"
    result = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, cwd=tmp_path,
                            env={**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"})
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and fragment in result.stderr, result.stderr[-2000:]


def test_an_error_line_stays_short(tmp_path: Path) -> None:
    """400 problems are counted, not listed: the line names the first few."""
    with pytest.raises(ValueError) as info:
        main(["--debug", *_model_yaml(tmp_path, _many("0", 400))])
    assert len(str(info.value)) < 1200


def test_a_description_is_printed_with_its_escapes_shown(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = NO_LIMITS_MODEL.replace("name: smd_no_limits", 'name: smd_no_limits\ndescription: "\\e]0;owned\\a a model"')
    assert main(_model_yaml(tmp_path, text)) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert first == "smd_no_limits: \\x1b]0;owned\\x07 a model"


def test_a_float_without_a_dot_is_a_number(tmp_path: Path) -> None:
    """YAML 1.1 reads 5e-1 as text; model files and scenarios read it as the number JSON does."""
    from ea_gym.model_files import load_model_file

    model = load_model_file(_write(tmp_path / "model.yaml", NO_LIMITS_MODEL.replace("value: 0.5", "value: 5e-1")))
    assert model.nominal["b"] == 0.5


def test_a_cache_entry_declaring_a_huge_array_is_rebuilt(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A member whose header declares shape (1e11,): ignored with a warning, from its header, before any array is made;
    the read runs under a memory cap."""
    from ea_gym.cache import CACHE_DIR_VARIABLE, entry_path, write_arrays_entry

    monkeypatch.setenv(CACHE_DIR_VARIABLE, str(tmp_path))
    path = write_arrays_entry("thresholds", "k", {"values": np.zeros(3)})
    with zipfile.ZipFile(path, "a") as archive:  # a second member declaring 800 GB, holding 24 bytes
        header = io.BytesIO()
        np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": (10**11,)})
        archive.writestr("huge.npy", header.getvalue() + bytes(24))
    code = CAPPED + "from ea_gym.cache import read_arrays_entry; warnings.simplefilter('error'); read_arrays_entry('thresholds', 'k')"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env={**os.environ, CACHE_DIR_VARIABLE: str(tmp_path)})
    assert "RuntimeWarning: ignoring the cache entry" in result.stderr and "rebuilding it" in result.stderr, result.stderr[-2000:]
    assert entry_path("thresholds", "k", ".npz") == path


def test_debug_shows_the_traceback(tmp_path: Path) -> None:
    bad = _write(tmp_path / "bad.json", scenario(duration=1e9))
    with pytest.raises(ValueError, match="at most 1000000 per run"):
        main(["--debug", "simulate", str(bad), "--out", str(tmp_path / "out")])


def test_an_internal_error_is_one_line_naming_the_inputs(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """An exception no check foresaw (here an IndexError while reading the scenario) says it is the program's, names the
    inputs and writes nothing; with --debug it comes through, traceback and all."""
    import ea_gym.scenario

    def broken(*args: Any, **kwargs: Any) -> None:
        raise IndexError("index 0 is out of bounds")

    monkeypatch.setattr(ea_gym.scenario, "load_scenario", broken)
    good = _write(tmp_path / "ok.json", GOOD)
    argv = ["simulate", str(good), "--system", "spring_mass_damper", "--out", str(tmp_path / "out")]
    assert main(argv) == 2
    assert capsys.readouterr().err == (f"ea-gym simulate: error: internal error (IndexError: index 0 is out of bounds) on {good}, "
                                       "--system spring_mass_damper; rerun with --debug for the traceback\n")
    assert _snapshot(tmp_path) == {"ok.json"}
    with pytest.raises(IndexError):
        main(["--debug", *argv])


def _refuse_writes_in(directory: Path, monkeypatch: pytest.MonkeyPatch, access_says_writable: bool) -> None:
    """What the kernel does in a directory of mode 0o555 to a user other than root (who may write anywhere): creating a
    file or directory in it fails with EACCES, and access() reports it unwritable, or, ``access_says_writable``, does
    not (access() can be wrong: ACLs, network file systems, a mode changed after the check)."""
    real_access, real_mkdir, real_open = os.access, os.mkdir, os.open

    def denied(path: Any) -> PermissionError:
        return PermissionError(errno.EACCES, os.strerror(errno.EACCES), os.fsdecode(path))

    def access(path: Any, mode: int, **kwargs: Any) -> bool:
        if Path(os.fsdecode(path)) == directory and mode & os.W_OK:
            return access_says_writable
        return real_access(path, mode, **kwargs)

    def mkdir(path: Any, mode: int = 0o777, **kwargs: Any) -> None:
        if Path(os.fsdecode(path)).parent == directory:
            raise denied(path)
        real_mkdir(path, mode, **kwargs)

    def open_(path: Any, flags: int, mode: int = 0o777, **kwargs: Any) -> int:
        if Path(os.fsdecode(path)).parent == directory and flags & os.O_CREAT:
            raise denied(path)
        return real_open(path, flags, mode, **kwargs)

    monkeypatch.setattr(os, "access", access)
    monkeypatch.setattr(os, "mkdir", mkdir)
    monkeypatch.setattr(os, "open", open_)


@pytest.mark.parametrize("access_says_writable, fragment", [(False, "locked is not writable"), (True, "out: Permission denied")],
                         ids=["refused before any work", "refused when the staging directory cannot be made"])
def test_an_unwritable_out_directory_is_refused(access_says_writable: bool, fragment: str, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    """As any user, root included: the directory's mode is 0o555, and the kernel's refusal is what a user other than
    root meets (``_refuse_writes_in``)."""
    scenario_file = _write(tmp_path / "ok.json", GOOD)
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o555)
    _refuse_writes_in(locked, monkeypatch, access_says_writable)
    assert main(["simulate", str(scenario_file), "--out", str(locked / "out")]) == 2
    stderr = capsys.readouterr().err
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("ea-gym simulate: error: ") and fragment in lines[0], stderr
    assert "Traceback" not in stderr
    assert not any(locked.iterdir())


def test_a_full_disk_leaves_nothing_behind(tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    """energy.png is drawn, then energy.json cannot be written: neither appears, nor the directories above --out."""

    def full(path: Any, data: Any) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(ea_gym.files, "write_json", full)
    before = _snapshot(tmp_path)
    code = main(["simulate", str(_write(tmp_path / "ok.json", GOOD)), "--out", str(tmp_path / "new" / "out")])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "No space left on device" in lines[0]
    assert _snapshot(tmp_path) == before | {"ok.json"}


def test_a_new_out_directory_has_the_modes_of_a_made_one(tmp_path: Path) -> None:
    """The staging directory (mkdtemp's 0700) becomes --out: it gets the mode mkdir would give, as the files do."""
    assert main(["simulate", str(_write(tmp_path / "ok.json", GOOD)), "--out", str(tmp_path / "out")]) == 0
    (tmp_path / "made").mkdir()
    assert (tmp_path / "out").stat().st_mode == (tmp_path / "made").stat().st_mode


def test_outputs_move_into_an_existing_directory_together(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    _write(out / "notes.txt", "kept")
    assert main(["simulate", str(_write(tmp_path / "ok.json", GOOD)), "--out", str(out)]) == 0
    assert sorted(path.name for path in out.iterdir()) == ["energy.json", "energy.png", "notes.txt"]
    assert [path.name for path in tmp_path.iterdir() if path.name.startswith(".")] == []  # no staging left


def test_a_link_in_an_existing_out_is_replaced_not_written_through(tmp_path: Path) -> None:
    """An output file and an output directory whose names are links in --out (to a file, to a directory elsewhere): the
    outputs take the links' places, the links' targets are left as they were."""
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    out.mkdir()
    elsewhere.mkdir()
    _write(elsewhere / "kept.txt", "kept")
    (out / "report.md").symlink_to(elsewhere / "kept.txt")
    (out / "figures").symlink_to(elsewhere, target_is_directory=True)
    with ea_gym.files.staged_output(out) as staging:
        _write(staging / "report.md", "new report")
        (staging / "figures").mkdir()
        _write(staging / "figures" / "a.png", "new figure")
    assert not (out / "report.md").is_symlink() and (out / "report.md").read_text() == "new report"
    assert not (out / "figures").is_symlink() and _snapshot(out / "figures") == {"a.png"}
    assert _snapshot(elsewhere) == {"kept.txt"} and (elsewhere / "kept.txt").read_text() == "kept"


def test_out_at_the_working_directory_is_written_in_place(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``--out .`` (a path without parents) is the working directory, not a traceback."""
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", str(_write(tmp_path / "ok.json", GOOD)), "--out", "."]) == 0
    assert sorted(path.name for path in tmp_path.iterdir()) == ["energy.json", "energy.png", "ok.json"]


def test_a_run_that_continues_the_working_directory_stages_beside_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``carry_existing`` with ``--out .`` (train --resume . --out .): the copy goes beside the directory, not into it."""
    work = tmp_path / "work"
    work.mkdir()
    _write(work / "earlier.txt", "kept")
    monkeypatch.chdir(work)
    with ea_gym.files.staged_output(".", carry_existing=True) as staging:
        assert sorted(path.name for path in staging.iterdir()) == ["earlier.txt"] and staging.parent == tmp_path
        _write(staging / "new.txt", "added")
    assert sorted(path.name for path in work.iterdir()) == ["earlier.txt", "new.txt"]
    assert [path.name for path in tmp_path.iterdir()] == ["work"]


def test_a_bad_scenario_is_refused_before_heavy_imports(tmp_path: Path) -> None:
    """Validation comes first: neither numba, scipy, torch nor Stable-Baselines3 is imported to refuse a bad file."""
    bad = _write(tmp_path / "bad.json", scenario(duration=1e9))
    for command in ("simulate", "phm"):
        code = (
            "import sys; from ea_gym.cli import main; "
            f"assert main([{command!r}, {str(bad)!r}, '--out', {str(tmp_path / 'out')!r}]) == 2; "
            "print(sorted(m for m in ('numba', 'scipy', 'torch', 'stable_baselines3') if m in sys.modules))"
        )
        result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
        assert result.stdout.strip() == "[]", (command, result.stdout, result.stderr)


def _env(**kwargs: Any) -> BondGraphMaintenanceEnv:
    return BondGraphMaintenanceEnv(**kwargs)


def _stepped_before_reset() -> None:
    _env(obs_mode="oracle").step(0)


def _stepped_after_truncation() -> None:
    env = _env(obs_mode="oracle", horizon=1)
    env.reset(seed=0)
    assert env.step(0)[3]  # truncated
    env.step(0)


def _stepped_after_failure() -> None:
    env = _env(obs_mode="oracle", step_seconds=1e5, window_seconds=1.0)  # the drift crosses a limit within the first step
    env.reset(seed=0)
    assert env.step(0)[2]  # terminated by the failure
    env.step(0)


def _stepped_with(action: Any) -> Callable[[], None]:
    def step() -> None:
        env = _env(obs_mode="oracle")
        env.reset(seed=0)
        env.step(action)

    return step


def _vector_reset(seed: Any) -> None:
    BondGraphMaintenanceVectorEnv(num_envs=2, obs_mode="oracle").reset(seed=seed)


def _no_limits_env(tmp: Path) -> None:
    _env(system=str(_write(tmp / "model.yaml", NO_LIMITS_MODEL)))


def _classifier_variant() -> None:
    FaultClassifier(["none", "k"], "mystery", 4)


# Each API case: (id, a call that must raise, the exception type, message fragment); the call may take tmp_path.
API_CASES: list[tuple[str, Callable[..., Any], type[Exception], str]] = [
    ("step before reset", _stepped_before_reset, RuntimeError, "step() needs reset() first"),
    ("step after truncation", _stepped_after_truncation, RuntimeError, "step() needs reset() first"),
    ("step after a failure", _stepped_after_failure, RuntimeError, "step() needs reset() first"),
    ("step(True)", _stepped_with(True), ValueError, "action must be an int in"),
    ("step(99)", _stepped_with(99), ValueError, "action must be an int in"),
    ("horizon=True", lambda: _env(horizon=True), ValueError, "horizon must be an int in"),
    ("horizon=10**10", lambda: _env(horizon=10**10), ValueError, "horizon must be an int in [1, 1000000000]"),
    ('window_seconds="1"', lambda: _env(window_seconds="1"), ValueError, "window_seconds must be a positive number"),
    ("window_seconds=1e9", lambda: _env(window_seconds=1e9), ValueError, "window_seconds * sample_rate = 1e+11 samples per step"),
    ("step_seconds=1e9", lambda: _env(step_seconds=1e9), ValueError, "step_seconds must be at most 1e+07 s"),
    ("sample_rate=True", lambda: _env(sample_rate=True), ValueError, "sample_rate must be a positive number"),
    ("noise=1.5", lambda: _env(noise=1.5), ValueError, "noise must be in [0, 1)"),
    ("costs with an unknown field", lambda: _env(costs={"fail": 1.0}), TypeError, "costs: unknown field 'fail'"),
    ("costs with a text value", lambda: _env(costs={"failure": "high"}), TypeError, "costs: failure must be a number"),
    ("costs as a list", lambda: _env(costs=[1.0]), TypeError, "costs must be a CostModel or a dict of its fields"),
    ('render_mode="human"', lambda: _env(render_mode="human"), ValueError, "render_mode must be one of ['rgb_array', 'ansi']"),
    ('continue_after_failure="no"', lambda: _env(continue_after_failure="no"), TypeError, "continue_after_failure must be a bool"),
    ("an unknown keyword", lambda: _env(horizn=5), TypeError, "unexpected keyword argument 'horizn'"),
    ("vector reset(seed=1.5)", lambda: _vector_reset(1.5), TypeError, "seed must be an int, None or a list"),
    ("vector reset(seed=True)", lambda: _vector_reset(True), TypeError, "seed must be an int, None or a list"),
    ("an env on a model without limits", _no_limits_env, ValueError, "has no degradable parameter"),
    ("an env on a model with m: 1e-20", lambda tmp: _env(system=str(_write(tmp / "model.yaml", TINY_MASS_MODEL))), ValueError,
     "sample_rate: the model's fastest mode, |lambda| = 5e+19 1/s"),
    ("an env sampled below its resonance", lambda: _env(sample_rate=0.2), ValueError, "is not resolved at 0.2 Hz"),
    ("an env whose parts wear out of its sample rate", lambda: _env(system="dc_motor", sample_rate=7.0), ValueError,
     "sample_rate (with Ra at its limit 1.3): the model's fastest mode, |lambda| = 25.2 1/s"),
    ("classifier=123", lambda: _env(classifier=123), TypeError, "classifier must be a FaultClassifier, a path to one or None, got int"),
    ("classifier at a missing path", lambda tmp: _env(classifier=tmp / "absent.pt"), ValueError, "absent.pt: not an isolation network"),
    ("activity_index with NaN", lambda: activity_index({"m": np.array([math.nan]), "k": np.array([1.0])}), ValueError,
     "activity_index: the EA of 'm' must be finite and >= 0 J"),
    ("activity_index with negative EA", lambda: activity_index({"m": np.array([1.0]), "k": np.array([-1.0])}), ValueError,
     "the EA of 'k' must be finite and >= 0 J, got -1.0"),
    ("energy_activity with sample_period=0", lambda: energy_activity(np.ones(10), 0.0, window=1.0), ValueError,
     "sample_period must be a finite number of seconds > 0"),
    ("a classifier of an unknown variant", _classifier_variant, ValueError, "variant must be one of paper, strong"),
    ("an env at 1e6 Hz", lambda: _env(sample_rate=1e6, window_seconds=0.5), ValueError,
     "sample_rate: 1e+06 Hz makes the threshold calibration simulate 1.44e+09 samples (8 runs of 180 s); at most 10000000"),
    ("num_envs=10**6", lambda: BondGraphMaintenanceVectorEnv(num_envs=10**6), ValueError, "num_envs must be an int in [1, 4096], got 1000000"),
    ('vector reset(options={"reset_mak": ...})', lambda: BondGraphMaintenanceVectorEnv(num_envs=2, obs_mode="oracle").reset(
        options={"reset_mak": np.array([True, False])}), ValueError, "options: unknown key 'reset_mak'; the known keys are ['reset_mask']"),
    ("single reset(options={...})", lambda: _env(obs_mode="oracle").reset(options={"reset_mask": True}), ValueError,
     "options: unknown key 'reset_mask'; the known keys are []"),
    ("single reset(seed=True)", lambda: _env(obs_mode="oracle").reset(seed=True), TypeError, "seed must be an int or None, got True"),
]


@pytest.mark.parametrize("call, kind, fragment", [case[1:] for case in API_CASES], ids=[case[0] for case in API_CASES])
def test_a_bad_api_call_raises_a_clear_error(call: Callable[..., Any], kind: type[Exception], fragment: str, tmp_path: Path) -> None:
    with pytest.raises(kind) as info:
        call(tmp_path) if call.__code__.co_argcount else call()
    assert fragment in str(info.value)


def test_costs_as_a_dict_are_the_cost_model() -> None:
    env = _env(obs_mode="oracle", costs={"failure": 100.0, "replace_downtime": 2})
    assert env.config.costs.failure == 100.0 and env.config.costs.replace_downtime == 2
    assert env.config.costs.replacement == 40.0  # the rest at their defaults


def test_continuing_after_a_failure_keeps_stepping() -> None:
    env = _env(obs_mode="oracle", step_seconds=1e5, window_seconds=1.0, continue_after_failure=True)
    env.reset(seed=0)
    _, reward, terminated, _, info = env.step(0)
    assert info["failed"] and not terminated and info["cost"]["failure"] == 400.0 and reward == -(400.0 + info["cost"]["lost_production"])
    env.step(0)  # the episode goes on


N_CASES = len(CLI_CASES) + len(API_CASES) + 1  # and the full disk


def test_the_docs_state_the_count() -> None:
    page = " ".join((Path(__file__).parents[1] / "docs" / "cli.md").read_text().split())
    assert f"{N_CASES} bad inputs tried, {N_CASES} refused cleanly" in page
