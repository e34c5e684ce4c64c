"""The README's Python: every import in its code blocks and every dotted ``ea_gym`` name it cites resolves."""

import importlib
import re
from pathlib import Path

import pytest

README = (Path(__file__).parent.parent / "README.md").read_text()
CODE = "\n".join(re.findall(r"```python\n(.*?)```", README, re.S))
IMPORTS = [line.split("#")[0].strip() for line in CODE.splitlines() if re.match(r"\s*(from \S+ import |import )", line)]
CITED = sorted(set(re.findall(r"`(ea_gym(?:\.[A-Za-z_]\w*)+)", README)))


@pytest.mark.parametrize("statement", IMPORTS)
def test_every_import_in_the_readme_runs(statement):
    exec(statement, {})


@pytest.mark.parametrize("dotted", CITED)
def test_every_cited_name_resolves(dotted):
    parts = dotted.split(".")
    for split in range(len(parts), 0, -1):
        try:
            target = importlib.import_module(".".join(parts[:split]))
        except ModuleNotFoundError:
            continue
        for attribute in parts[split:]:
            target = getattr(target, attribute)
        return
    pytest.fail(f"{dotted} is not importable")


def test_the_readme_cites_and_imports_something():
    assert "from ea_gym.bondgraph import BondGraph, StateSpaceModel" in IMPORTS and len(CITED) > 10
