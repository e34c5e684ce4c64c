"""An interrupted command leaves nothing behind: SIGTERM cleans up as SIGINT does.

Each command runs in its own process with a private temporary directory; the signal arrives once the command's
staging directory (``.OUT.xxxx`` beside ``--out``) has appeared, or once a first output has appeared in it, mid-run.
Afterwards: exit code 128 + the signal, one line on stderr, no staging directory, no partial output, nothing of the run
in the temporary directory, and a directory resumed in place byte for byte as it was.
"""

from __future__ import annotations

import getpass
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

#: a command line of a few seconds' work or more, given the directory it works in; --out is always DIR/out
Command = Callable[[Path], list[str]]

LONG_SCENARIO = {"system": "spring_mass_damper", "load": {"kind": "constant", "value": 10.0}, "duration": 3000.0, "sample_rate": 100.0}
#: training that runs until it is stopped: A2C on two environments, short episodes
ENDLESS_TRAIN = ["train", "--algo", "a2c", "--obs-mode", "oracle", "--n-envs", "2", "--timesteps", "1000000", "--eval-every", "32",
                 "--eval-episodes", "1", "--env", "horizon=50", "--no-progress"]


def _scenario(tmp: Path) -> str:
    (tmp / "long.json").write_text(json.dumps(LONG_SCENARIO))
    return str(tmp / "long.json")


def _resume_in_place(tmp: Path) -> list[str]:
    """A finished tiny run continued in its own directory (a copy of it is staged, then the signal)."""
    from ea_gym.cli import main

    tiny = [*ENDLESS_TRAIN]
    tiny[tiny.index("1000000")] = "64"
    assert main([*tiny, "--out", str(tmp / "out")]) == 0
    return [*ENDLESS_TRAIN, "--resume", str(tmp / "out"), "--out", str(tmp / "out")]


COMMANDS: dict[str, Command] = {
    "simulate": lambda tmp: ["simulate", _scenario(tmp), "--out", str(tmp / "out")],
    "phm": lambda tmp: ["phm", _scenario(tmp), "--out", str(tmp / "out")],
    "train": lambda tmp: [*ENDLESS_TRAIN, "--out", str(tmp / "out")],
    "benchmark": lambda tmp: ["benchmark", "--episodes", "2", "--no-ppo", "--no-progress", "--env", "horizon=50", "--allow-stale",
                              "--out", str(tmp / "out")],
    "train --resume in place": _resume_in_place,
}
#: where the signal arrives: the command, and what has appeared in its staging directory ("": the directory itself)
POINTS = [("simulate", ""), ("phm", ""), ("phm", "*.png"), ("train", ""), ("train", "checkpoints/*/agent.json"), ("benchmark", ""),
          ("train --resume in place", "")]


def _files(directory: Path) -> dict[str, bytes]:
    return {str(path.relative_to(directory)): path.read_bytes() for path in sorted(directory.rglob("*")) if path.is_file()}


def _wait_for_staging(process: subprocess.Popen[str], work: Path, inside: str, timeout: float = 600.0) -> None:
    """Until the staging directory beside --out appears (the command is writing its outputs), and in it ``inside``."""
    deadline = time.monotonic() + timeout
    while not any(work.glob(f".out.*/{inside}")):
        assert process.poll() is None, f"the command ended before its outputs were staged: {process.communicate()}"
        assert time.monotonic() < deadline, "no staging directory appeared"
        time.sleep(0.01)


@pytest.mark.parametrize("number", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
@pytest.mark.parametrize("command, inside", POINTS, ids=[f"{command} {inside or 'staged'}" for command, inside in POINTS])
def test_an_interrupted_command_leaves_nothing_behind(command: str, inside: str, number: signal.Signals, tmp_path: Path) -> None:
    work, private = tmp_path / "work", tmp_path / "tmp"
    work.mkdir()
    private.mkdir()
    argv = COMMANDS[command](work)
    before = _files(work)
    environment = {**os.environ, "TMPDIR": str(private), "MPLBACKEND": "Agg"}
    process = subprocess.Popen([sys.executable, "-m", "ea_gym.cli", *argv], cwd=work, env=environment, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        _wait_for_staging(process, work, inside)
        process.send_signal(number)
        _, stderr = process.communicate(timeout=120)
    finally:
        process.kill()
    assert process.returncode == 128 + number, stderr
    lines = stderr.strip().splitlines()
    assert lines[-1].startswith(f"ea-gym {argv[0]}: ") and ("SIGTERM" if number == signal.SIGTERM else "SIGINT") in lines[-1], stderr
    assert "Traceback" not in stderr
    assert not [path.name for path in work.iterdir() if path.name.startswith(".")]  # no staging directory
    assert _files(work) == before  # no partial output; a resumed directory as it was
    # torch's own cache directory, one per user, made on its first optimizer and kept for every later torch program
    assert [path.name for path in private.iterdir()] in ([], [f"torchinductor_{getpass.getuser()}"])
    assert not any((private / f"torchinductor_{getpass.getuser()}").glob("*"))


def test_a_signal_inside_a_held_section_waits_for_its_end_and_a_second_one_is_ignored() -> None:
    from ea_gym.interrupts import Terminated, interruptions_held, interrupts_raised

    finished = False
    with interrupts_raised(), pytest.raises(Terminated):
        with interruptions_held():
            os.kill(os.getpid(), signal.SIGTERM)
            os.kill(os.getpid(), signal.SIGINT)  # during the first one's cleanup: ignored
            time.sleep(0.05)
            finished = True
    assert finished
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the handlers are back


def test_an_interruption_that_another_error_swallowed_is_still_the_interruption() -> None:
    """pybind11 reports an exception raised inside an extension's init as ``ImportError: initialization failed``: the
    signal that caused it is what leaves, with the other error as its cause."""
    from ea_gym.interrupts import Terminated, interrupts_raised

    with pytest.raises(Terminated) as caught, interrupts_raised():
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1.0)
        except KeyboardInterrupt:
            raise ImportError("initialization failed") from None
    assert isinstance(caught.value.__cause__, ImportError)
    with pytest.raises(ImportError), interrupts_raised():  # with no signal, an error is itself
        raise ImportError("initialization failed")
