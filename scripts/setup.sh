#!/usr/bin/env bash
# Creates .venv and installs ea-gym with its test tools and the documentation's (Sphinx). torch is pinned by constraints.txt to the
# CPU build (a looser requirement pulls several GB of CUDA packages). Re-running is cheap: the
# install is skipped while pyproject.toml and constraints.txt are unchanged.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
stamp=.venv/.ea-gym-installed
want=$(cat pyproject.toml constraints.txt | sha256sum | cut -d' ' -f1)
if [ ! -x .venv/bin/python ]; then
    "$PYTHON" -m venv .venv
fi
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
    .venv/bin/python -m pip install --quiet --upgrade pip
    .venv/bin/python -m pip install --quiet -c constraints.txt -e '.[dev,docs]'
    echo "$want" > "$stamp"
fi
