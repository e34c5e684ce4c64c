"""The documentation's own Sphinx extension: pages generated from the code and the committed results.

On ``builder-inited`` (before autosummary, whose module pages under ``docs/_autosummary/`` it clears) it
writes, under ``docs/_generated/`` (not committed; the pages ``{include}`` them):

- ``env_docstring.md``: the maintenance environment's class docstring (``BondGraphMaintenanceEnv``),
  which is Gymnasium-style Markdown, so the environment pages show the code's own text;
- ``throughput.md`` and ``throughput.png``: the throughput by regime, table and figure, from
  ``experiments/results/throughput/regimes.json`` (written by ``bench_throughput.py --json``).

A file is rewritten only when its content changes, so an unchanged build stays incremental.

On ``autodoc-process-docstring`` (before napoleon) it reads the project's docstrings as they are written:
``|x|`` is an absolute value, not a reStructuredText substitution, so bars outside inline literals are
escaped; an inline literal that runs over a line break is joined onto one line (napoleon splits a
``Returns:`` line at its first colon outside literals); and the environments' Markdown class docstrings,
rendered on their own pages, are replaced in the API reference by a link there.
"""

from __future__ import annotations

import inspect
import json
import re
import shutil
from pathlib import Path
from typing import Any

from sphinx.application import Sphinx

ROOT = Path(__file__).resolve().parents[2]
REGIMES = ROOT / "experiments" / "results" / "throughput" / "regimes.json"
THROUGHPUT_COMMAND = (
    "python experiments/benchmarks/bench_throughput.py --steps 100 --repeats 5 --profile "
    "--json experiments/results/throughput/regimes.json"
)


def _write(path: Path, content: str | bytes) -> None:
    """Write ``content`` unless the file already holds it."""
    data = content.encode() if isinstance(content, str) else content
    if path.exists() and path.read_bytes() == data:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)


def env_docstring() -> str:
    """The single environment's class docstring, dedented (it is Markdown, as Gymnasium's are)."""
    from ea_gym.env.maintenance import BondGraphMaintenanceEnv

    return inspect.cleandoc(BondGraphMaintenanceEnv.__doc__ or "") + "\n"


def _rate(record: dict[str, Any] | None) -> str:
    if record is None:
        return ""
    runs = record.get("runs") or []
    text = f"{record['env_steps_per_s']:,.0f}"
    if len(runs) > 1:
        text += f" ({min(runs):,.0f}-{max(runs):,.0f})"
    return text


def throughput_table(results: dict[str, Any]) -> str:
    """Markdown table of env-steps/s per regime and batch size: the medians with their ranges."""
    lines = [
        "| regime | N | batched env, kernel threads of the run (range) | batched, 1 thread | single env (`gym.make`) "
        "| SyncVectorEnv | batched / sync | alarm share |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for regime, sizes in results["regimes"].items():
        for size, row in sorted(sizes.items(), key=lambda item: int(item[0])):
            batched, sync = row.get("batched"), row.get("sync")
            ratio = f"{batched['env_steps_per_s'] / sync['env_steps_per_s']:.1f}x" if batched and sync else ""
            share = f"{batched['alarm_share']:.0%}" if batched else ""
            cells = [regime, size, _rate(batched), _rate(row.get("batched_one_thread")), _rate(row.get("single")), _rate(sync), ratio, share]
            lines.append("| " + " | ".join(cells) + " |")
    machine = results.get("machine", {})
    lines += ["", f"Machine: {machine.get('cores', '?')} cores, Python {machine.get('python', '?')}."]
    profiles = results.get("profiles") or {}
    if profiles:
        stages = list(next(iter(profiles.values())))
        lines += [
            "",
            "Where a batched step's time goes at N = 256 on one kernel thread (ms of wall time per step, cProfile's own time):",
            "",
            "| stage | " + " | ".join(profiles) + " |",
            "|---|" + "---|" * len(profiles),
        ]
        for stage in stages:
            lines.append(f"| {stage} | " + " | ".join(f"{profiles[r].get(stage, 0.0):.1f}" for r in profiles) + " |")
    return "\n".join(lines) + "\n"


def throughput_figure(results: dict[str, Any], path: Path) -> None:
    """Env-steps/s against batch size per regime, batched env and SyncVectorEnv, log-log."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(7, 4), dpi=100)
    for colour, (regime, sizes) in enumerate(results["regimes"].items()):
        ordered = sorted(sizes.items(), key=lambda item: int(item[0]))
        for kind, style in (("batched", "-o"), ("sync", ":s")):
            points = [(int(n), row[kind]["env_steps_per_s"]) for n, row in ordered if kind in row]
            if points:
                xs, ys = zip(*points)
                axis.plot(xs, ys, style, color=f"C{colour}", label=f"{regime}, {'batched env' if kind == 'batched' else 'SyncVectorEnv'}")
    axis.set(xscale="log", yscale="log", xlabel="systems per batch N", ylabel="env-steps/s", title="Throughput by regime")
    axis.grid(True, which="both", alpha=0.3)
    axis.legend(fontsize=7, ncol=2)
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    scratch = path.with_suffix(".tmp.png")
    figure.savefig(scratch, metadata={"Software": None})
    plt.close(figure)
    _write(path, scratch.read_bytes())
    scratch.unlink()


def generate(app: Sphinx) -> None:
    # autosummary writes its module pages afresh after this: a module since removed or renamed leaves no stale page
    shutil.rmtree(Path(app.srcdir) / "_autosummary", ignore_errors=True)
    out = Path(app.srcdir) / "_generated"
    _write(out / "env_docstring.md", env_docstring())
    results = json.loads(REGIMES.read_text())
    _write(out / "throughput.md", throughput_table(results) + f"\n![Throughput by regime](throughput.png)\n\nCommand: `{THROUGHPUT_COMMAND}`\n")
    throughput_figure(results, out / "throughput.png")


#: the Markdown (Gymnasium-style) class docstrings, shown on these pages
MARKDOWN_DOCSTRINGS = {
    "ea_gym.env.maintenance.BondGraphMaintenanceEnv": "environments/bondgraph-maintenance",
    "ea_gym.env.maintenance.SpringMassDamperEnv": "environments/spring-mass-damper",
}
_LITERAL = re.compile(r"(``.*?``)")


def _join_open_literals(lines: list[str]) -> list[str]:
    joined: list[str] = []
    for line in lines:
        if joined and joined[-1].count("``") % 2 == 1:
            joined[-1] = joined[-1] + " " + line.strip()
        else:
            joined.append(line)
    return joined


def _escape_bars(line: str) -> str:
    if line.lstrip().startswith(("..", "+-", "|")) and line.count("|") > 2:  # a table or a directive: left alone
        return line
    parts = _LITERAL.split(line)
    return "".join(part if index % 2 else re.sub(r"(?<!\\)\|", r"\\|", part) for index, part in enumerate(parts))


def process_docstring(app: Sphinx, what: str, name: str, obj: Any, options: Any, lines: list[str]) -> None:
    if name in MARKDOWN_DOCSTRINGS:
        lines[:] = [f"The environment's documentation (spaces, rewards, starting state, episode end, arguments, version history) "
                    f"is this class's docstring, rendered on its page: :doc:`/{MARKDOWN_DOCSTRINGS[name]}`."]
        return
    lines[:] = [_escape_bars(line) for line in _join_open_literals(lines)]


def setup(app: Sphinx) -> dict[str, Any]:
    app.connect("builder-inited", generate, priority=100)  # before autosummary generates
    app.connect("autodoc-process-docstring", process_docstring, priority=400)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
