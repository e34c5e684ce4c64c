#!/usr/bin/env bash
# The tests that need Ray RLlib (the optional extra ea-gym[rllib]: `ea-gym train --backend rllib`,
# `ea-gym benchmark --ray`, the smoke runs of experiments/integrations/rllib_ppo.py and ray_benchmark.py),
# in a virtual environment of their own: RLlib pins an older gymnasium than
# .venv's. CI does not run them (they skip where ray is missing). RLLIB_VENV names another environment
# to use (created if missing). Keep to one such run at a time: each starts a local Ray of 2 CPUs.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
venv=${RLLIB_VENV:-.venv-rllib}
stamp=$venv/.ea-gym-installed
want=$(cat pyproject.toml constraints.txt | sha256sum | cut -d' ' -f1)
if [ ! -x "$venv/bin/python" ]; then
    "$PYTHON" -m venv "$venv"
fi
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
    "$venv/bin/python" -m pip install --quiet -c constraints.txt -e '.[rllib]' pytest
    echo "$want" > "$stamp"
fi
export MPLBACKEND=Agg
smoke=tests/test_experiments.py::test_smoke_run
"$venv/bin/python" -m pytest -q tests/test_ray.py "$smoke[integrations/rllib_ppo.py]" "$smoke[integrations/ray_benchmark.py]" "$@"
