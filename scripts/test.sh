#!/usr/bin/env bash
# Sets everything up, then runs the linter (ruff), the type checker (mypy), the documentation build
# (Sphinx, warnings as errors) and the test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ruff check .
.venv/bin/mypy
.venv/bin/sphinx-build -E -W --keep-going -q -b html docs out/docs
export MPLBACKEND=Agg
.venv/bin/python -m pytest -q "$@"
