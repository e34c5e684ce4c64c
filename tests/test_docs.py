"""The documentation's pages (README.md, docs/**/*.md) and the experiments' reports are checked as code:

- every ``python`` block runs, a page's blocks in order in one namespace, from the repository root;
- every relative link (and image) resolves to a file, and to a heading where it names an anchor;
- every ``ea_gym.…`` or ``agents.…`` name cited in backticks imports;
- every ``ea-gym SUBCOMMAND`` and each of its ``--options`` in a shell block or inline command exists in the
  parser (``ea_gym.cli.build_parser``, the entry points' subcommands included);
- every ``experiments/….py`` (and other experiments file) named exists.

Each check is a function of a page's text, and the ``test_*_catches_*`` tests show that it fails on a wrong subject.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import io
import os
import re
import shlex
import textwrap
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
REPORTS = ROOT / "experiments" / "reports"
GENERATED = {"_generated", "_autosummary", "_build", "_templates"}

PAGES = [ROOT / "README.md"] + sorted(p for p in DOCS.rglob("*.md") if not GENERATED & set(p.relative_to(DOCS).parts))
CHECKED = PAGES + sorted(REPORTS.glob("*.md"))  # links, names and paths; the reports' code is history, not run


def page_id(path: Path) -> str:
    return str(path.relative_to(ROOT))


FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<ticks>`{3,})(?P<info>[^\n`]*)\n(?P<body>.*?)^(?P=indent)(?P=ticks)[ \t]*$", re.M | re.S)


def code_blocks(text: str, languages: tuple[str, ...]) -> list[str]:
    """The bodies of the fenced blocks whose info string starts with one of ``languages``, dedented, in order."""
    blocks = []
    for match in FENCE.finditer(text):
        info = match["info"].strip()
        if info.split(" ")[0] in languages:
            blocks.append(textwrap.dedent(match["body"]))
    return blocks


def prose(text: str) -> str:
    """The text outside fenced blocks."""
    return FENCE.sub("", text)


# --- python blocks ---------------------------------------------------------------------------------------------------


def run_python_blocks(text: str, name: str) -> str:
    """Run the page's python blocks in order in one namespace, from the repository root; their printed output."""
    namespace: dict[str, object] = {"__name__": f"docs:{name}"}
    printed = io.StringIO()
    cwd = os.getcwd()
    try:
        os.chdir(ROOT)
        with contextlib.redirect_stdout(printed):
            for index, block in enumerate(code_blocks(text, ("python", "py"))):
                exec(compile(block, f"{name}[python block {index + 1}]", "exec"), namespace)
    finally:
        os.chdir(cwd)
    return printed.getvalue()


RUNNABLE = [p for p in PAGES if code_blocks(p.read_text(), ("python", "py"))]


@pytest.mark.parametrize("page", RUNNABLE, ids=page_id)
def test_every_python_block_runs(page: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MPLBACKEND", "Agg")
    run_python_blocks(page.read_text(), page_id(page))


def test_the_python_check_catches_a_failing_block() -> None:
    with pytest.raises(NameError):
        run_python_blocks("```python\nx = 1\n```\n\ntext\n\n```python\nprint(x + y)\n```\n", "bad.md")
    assert run_python_blocks("```python\nx = 1\n```\n\n```python\nprint(x + 1)\n```\n", "good.md") == "2\n"


# --- links -----------------------------------------------------------------------------------------------------------

LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
INLINE_CODE = re.compile(r"`[^`\n]*`")


def slug(heading: str) -> str:
    """The anchor of a heading, as GitHub and MyST (``myst_heading_anchors``) make it."""
    text = re.sub(r"[`*_]|\[([^\]]*)\]\([^)]*\)", lambda m: m.group(1) or "", heading.strip().lower())
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    text = prose(path.read_text())
    return {slug(m.group(1)) for m in re.finditer(r"^#{1,6}\s+(.*?)\s*#*\s*$", text, re.M)}


def broken_links(text: str, where: Path) -> list[str]:
    """The relative links of a page (outside code) whose file or anchor does not exist."""
    broken = []
    for target in LINK.findall(INLINE_CODE.sub("", prose(text))):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto:
            continue
        file, _, anchor = target.partition("#")
        resolved = where.parent / file if file else where
        if not resolved.exists():
            broken.append(f"{target}: no file {resolved}")
        elif anchor and resolved.suffix == ".md" and anchor not in anchors(resolved):
            broken.append(f"{target}: no heading with anchor #{anchor} in {resolved.name}")
    return broken


@pytest.mark.parametrize("page", CHECKED, ids=page_id)
def test_every_relative_link_resolves(page: Path) -> None:
    assert broken_links(page.read_text(), page) == []


def test_the_link_check_catches_a_broken_link() -> None:
    page = ROOT / "README.md"
    assert broken_links("[docs](docs/index.md) and [me](#the-environment)", page) == []
    assert len(broken_links("[gone](docs/nowhere.md) ![f](docs/no.png) [anchor](docs/index.md#no-such-heading) [x](#nope)", page)) == 4
    assert broken_links("`[not a link](nowhere.md)` and [web](https://example.org/x.md)", page) == []


# --- names -----------------------------------------------------------------------------------------------------------

CITED = re.compile(r"`((?:ea_gym|agents)(?:\.[A-Za-z_]\w*)+)")


def unresolved_names(text: str) -> list[str]:
    """The dotted ``ea_gym``/``agents`` names cited in backticks that do not import."""
    missing = []
    for dotted in sorted(set(CITED.findall(text))):
        parts = dotted.split(".")
        for split in range(len(parts), 0, -1):
            try:
                target = importlib.import_module(".".join(parts[:split]))
            except ModuleNotFoundError:
                continue
            try:
                for attribute in parts[split:]:
                    target = getattr(target, attribute)
            except AttributeError:
                missing.append(dotted)
            break
        else:
            missing.append(dotted)
    return missing


@pytest.mark.parametrize("page", CHECKED, ids=page_id)
def test_every_cited_name_resolves(page: Path) -> None:
    assert unresolved_names(page.read_text()) == []


def test_the_name_check_catches_a_wrong_name() -> None:
    assert unresolved_names("`ea_gym.phm.PHMChain` and `agents.policies.RunToFailure`") == []
    assert unresolved_names("`ea_gym.phm.NoSuchChain`, `ea_gym.nosuchmodule.x`, `agents.nowhere`") == [
        "agents.nowhere", "ea_gym.nosuchmodule.x", "ea_gym.phm.NoSuchChain"]


def test_the_pages_cite_names_and_run_code() -> None:
    names = set().union(*(CITED.findall(p.read_text()) for p in PAGES))
    assert len(names) > 40 and len(RUNNABLE) >= 8


# --- the command line ------------------------------------------------------------------------------------------------


@cache
def subcommands() -> dict[str, set[str]]:
    """Each ``ea-gym`` subcommand with its option strings; ``""`` holds the top level's."""
    from ea_gym.cli import build_parser

    parser = build_parser()
    options = {"": {o for a in parser._actions for o in a.option_strings}}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                options[name] = {o for a in sub._actions for o in a.option_strings}
    return options


def shell_commands(text: str) -> list[str]:
    """The ``ea-gym`` command lines of a page: in its shell blocks and its inline code."""
    lines = []
    for block in code_blocks(text, ("bash", "sh", "shell", "console")):
        lines += [line.split(" # ")[0].removeprefix("$ ") for line in block.replace("\\\n", " ").splitlines()]
    lines += [code.strip("`") for code in INLINE_CODE.findall(prose(text))]
    return [line for line in lines if re.search(r"(^|[/\s])ea-gym(\s|$)", line)]


def unknown_cli(text: str) -> list[str]:
    """The subcommands and options named on ``ea-gym`` command lines that the parser does not have."""
    known = subcommands()
    unknown = []
    for line in shell_commands(text):
        try:
            words = shlex.split(line, comments=True)
        except ValueError:
            words = line.split()
        start = next(i for i, w in enumerate(words) if w == "ea-gym" or w.endswith("/ea-gym"))
        words = [w for w in words[start + 1 :] if w not in known[""]]  # --debug
        if not words or words[0].isupper() or words[0] in {"CMD", "COMMAND", "..."}:
            continue  # `ea-gym --help`, `ea-gym COMMAND --help`: a placeholder
        command = words[0]
        if command not in known:
            unknown.append(f"ea-gym {command}")
            continue
        for word in words[1:]:
            if word.startswith("--") and word.split("=")[0] not in known[command] | {"--help"}:
                unknown.append(f"ea-gym {command} {word.split('=')[0]}")
    return unknown


@pytest.mark.parametrize("page", CHECKED, ids=page_id)
def test_every_cli_name_exists(page: Path) -> None:
    assert unknown_cli(page.read_text()) == []


def test_the_cli_check_catches_a_wrong_name() -> None:
    good = "```bash\nea-gym phm SCENARIO --out DIR   # a comment --not-an-option\n.venv/bin/ea-gym train --algo ppo \\\n    --timesteps 10\n```\n"
    assert unknown_cli(good + "and `ea-gym benchmark --episodes 5`, `ea-gym --debug models`") == []
    assert unknown_cli("```bash\nea-gym simulate x.json --no-such-option 1\nea-gym frobnicate\n```\n`ea-gym phm --colour`") == [
        "ea-gym simulate --no-such-option", "ea-gym frobnicate", "ea-gym phm --colour"]


def test_the_pages_name_every_subcommand() -> None:
    named = set()
    for page in PAGES:
        for line in shell_commands(page.read_text()):
            words = line.split()
            named |= {words[i + 1] for i, w in enumerate(words[:-1]) if w.endswith("ea-gym")}
    assert set(subcommands()) - {""} <= named | {"convert-agent"}


# --- experiments' files ----------------------------------------------------------------------------------------------

EXPERIMENT_FILE = re.compile(r"(?<![\w/.])(experiments/[\w./-]+\.(?:py|json|jsonl|ya?ml|md|png|csv))\b")


def missing_experiment_files(text: str) -> list[str]:
    """The ``experiments/…`` files a page names (scripts, scenarios, models, results) that do not exist."""
    return sorted({path for path in EXPERIMENT_FILE.findall(text) if not (ROOT / path).exists()})


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_every_experiments_file_named_exists(page: Path) -> None:
    assert missing_experiment_files(page.read_text()) == []


def test_the_experiments_check_catches_a_missing_file() -> None:
    assert missing_experiment_files("`python experiments/benchmarks/no_such_script.py --smoke`") == [
        "experiments/benchmarks/no_such_script.py"]
    assert missing_experiment_files("experiments/models/two_mass_chain.yaml") == []


def test_the_results_page_shows_every_committed_report() -> None:
    shown = set(re.findall(r"```\{(?:include|literalinclude)\} \.\./(experiments/results/\S+)", (DOCS / "results.md").read_text()))
    committed = {str(p.relative_to(ROOT)) for p in (ROOT / "experiments" / "results").rglob("*.md")}
    assert committed <= shown


# --- the README as the front page ------------------------------------------------------------------------------------


def test_the_readme_is_a_short_front_page() -> None:
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 200
    for needed in ("bash scripts/run.sh", "bash scripts/test.sh", 'gym.make("ea_gym/', "run_scenario", "load_system", "docs/results.md"):
        assert needed in text
    linked = {m for m in LINK.findall(text) if m.startswith("docs/")}
    assert {"docs/getting-started.md#install", "docs/concepts.md", "docs/cli.md", "docs/api.md"} <= linked
