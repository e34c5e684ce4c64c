#!/usr/bin/env bash
# Sets everything up, then runs the linter (ruff), the type checker (mypy) and the test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ruff check .
.venv/bin/mypy
export MPLBACKEND=Agg
.venv/bin/python -m pytest -q "$@"
