"""rl-zoo3 on ea_gym/SpringMassDamper-v0: its train and enjoy as the docs show them, the figures from their output.

What it does
    Runs RL Baselines3 Zoo's ``rl_zoo3.train`` (PPO with experiments/integrations/rl_zoo3/hyperparams/ppo.yml,
    ``-n STEPS --seed 0 --eval-freq -1``) and ``rl_zoo3.enjoy`` (one 500-step episode, deterministic, the
    environment's keyword arguments on enjoy's command line: the zoo does not save the file's
    ``env_kwargs`` with the run) as subprocesses, in a temporary log folder. It writes the last training log
    table (fps, ep_rew_mean, ...), the wall times and enjoy's output; ``summary.md`` is rendered from
    ``summary.json`` (``render``), so the figures the docs include are the run's.

How to run (from the repository root; needs the zoo extra: ``pip install -c constraints.txt -e '.[zoo]'``)
    .venv/bin/python experiments/integrations/rl_zoo3_check.py [--steps 4096] [--out DIR] [--smoke]

    Writes ``DIR/summary.json`` and ``DIR/summary.md`` (default DIR: experiments/results/rl_zoo3).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import subprocess
import sys
import tempfile
import time
from importlib.metadata import version
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))  # this checkout's ea_gym and experiments.common, installed or not

from ea_gym.env import ENV_ID
from ea_gym.files import write_atomic
from experiments.common import parse_with_smoke

HYPERPARAMS = "experiments/integrations/rl_zoo3/hyperparams/ppo.yml"
ENJOY_KWARGS = ("obs_mode:'phm'", "continue_after_failure:True")
#: the smoke run: one update (the zoo completes a rollout of 8 x 256 steps) and a short enjoy
SMOKE = {"steps": 64, "enjoy_steps": 20}
ROW = re.compile(r"^\|\s+(\w+)\s+\|\s+(\S+)\s+\|$")


def train_command(steps: int, logs: str) -> list[str]:
    return ["-m", "rl_zoo3.train", "--algo", "ppo", "--env", ENV_ID, "--gym-packages", "ea_gym", "--conf-file", HYPERPARAMS,
            "-n", str(steps), "--seed", "0", "--eval-freq", "-1", "-f", logs]


def enjoy_command(steps: int, logs: str) -> list[str]:
    return ["-m", "rl_zoo3.enjoy", "--algo", "ppo", "--env", ENV_ID, "--gym-packages", "ea_gym", "-f", logs, "--exp-id", "1",
            "-n", str(steps), "--no-render", "--deterministic", "--env-kwargs", *ENJOY_KWARGS]


def run(arguments: list[str]) -> tuple[str, float]:
    """``python ARGUMENTS`` from the repository root: its output (stdout then stderr) and wall time (s)."""
    started = time.perf_counter()
    done = subprocess.run([sys.executable, *arguments], cwd=ROOT, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"python {' '.join(arguments)} exited with {done.returncode}:\n{done.stderr[-3000:]}")
    return done.stdout + done.stderr, round(time.perf_counter() - started, 1)


def last_table(output: str) -> list[list[str]]:
    """The rows (name, value) of the last log table SB3 printed; a section's own row ("rollout/") has value ''."""
    tables: list[list[list[str]]] = []
    for line in output.splitlines():
        if line.startswith("---"):
            if not tables or tables[-1]:
                tables.append([])
            continue
        section = re.match(r"^\|\s+(\w+/)\s+\|\s+\|$", line)
        row = ROW.match(line)
        if tables and (section or row):
            tables[-1].append([section.group(1), ""] if section else [row.group(1), row.group(2)])
    return next((table for table in reversed(tables) if table), [])


def shown(command: list[str]) -> str:
    """A command as the docs write it: ``python -m ...`` with the log folder ``logs/``."""
    return "python " + " ".join(f'"{part}"' if "'" in part else shlex.quote(part) for part in command)


def render(summary: dict[str, Any]) -> str:
    """summary.md from summary.json's content."""
    table = summary["train"]["last_table"]
    cells = [(("    " + name) if value else name, value) for name, value in table]  # a section's rows indented, as SB3 prints them
    width = max(len(cell) for cell, _ in cells)
    rows = "\n".join(f"| {cell:<{width}} | {value:<12} |" for cell, value in cells)
    fps = dict(table).get("fps", "?")
    versions = summary["versions"]
    return f"""# rl-zoo3 on {summary["env_id"]}

RL Baselines3 Zoo {versions["rl_zoo3"]} (stable-baselines3 {versions["stable_baselines3"]}, gymnasium {versions["gymnasium"]})
with the `zoo` extra (`pip install -c constraints.txt -e '.[zoo]'`), the hyperparameters of `{HYPERPARAMS}`
(PPO, MultiInputPolicy, 8 environments in a DummyVecEnv, phm observations, continue_after_failure): a short run
that checks training and enjoying ({summary["train"]["steps"]} steps; the full setting is 200,000), written by
`experiments/integrations/rl_zoo3_check.py` on {summary["cpu_count"]} cores (load average {summary["load_average"]}).

## Train

```bash
{shown(summary["train"]["command"])}
```

Wall time {summary["train"]["wall_s"]} s, {fps} env-steps/s (SB3's fps). The last log table:

```
{rows}
```

## Enjoy

```bash
{shown(summary["enjoy"]["command"])}
```

`enjoy` makes its environment from the command line's `--env-kwargs` (the yml's `env_kwargs` are not saved with
the run) and loads the normalisation statistics saved beside the model. Wall time {summary["enjoy"]["wall_s"]} s; output:

```
{summary["enjoy"]["output"]}
```
"""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=4096, help="training steps, -n of rl_zoo3.train (default 4096: two updates)")
    parser.add_argument("--enjoy-steps", type=int, default=500, help="steps of rl_zoo3.enjoy (default 500: one episode)")
    parser.add_argument("--out", type=Path, default=ROOT / "experiments" / "results" / "rl_zoo3")
    args = parse_with_smoke(parser, argv, SMOKE)
    with tempfile.TemporaryDirectory(prefix="ea-gym-zoo-") as logs:
        train = train_command(args.steps, "logs/")
        output, train_s = run(train_command(args.steps, logs))
        table = last_table(output)
        enjoy = enjoy_command(args.enjoy_steps, "logs/")
        enjoyed, enjoy_s = run(enjoy_command(args.enjoy_steps, logs))
    lines = [line for line in enjoyed.splitlines() if re.match(r"^(Loading running|with params|Episode|Mean|\d+ Episodes)", line)]
    summary = {
        "env_id": ENV_ID,
        "versions": {name: version(name) for name in ("rl_zoo3", "stable_baselines3", "gymnasium")},
        "cpu_count": os.cpu_count(),
        "load_average": [round(x, 1) for x in os.getloadavg()],
        "train": {"command": train, "steps": args.steps, "wall_s": train_s, "last_table": table},
        "enjoy": {"command": enjoy, "wall_s": enjoy_s, "output": "\n".join(lines)},
    }
    args.out.mkdir(parents=True, exist_ok=True)
    write_atomic(args.out / "summary.json", lambda tmp: Path(tmp).write_text(json.dumps(summary, indent=2) + "\n"))
    write_atomic(args.out / "summary.md", lambda tmp: Path(tmp).write_text(render(summary)))
    print(f"train {train_s} s ({dict(table).get('fps')} fps), enjoy {enjoy_s} s; written to {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
