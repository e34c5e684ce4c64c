#!/usr/bin/env bash
# Sets everything up, then runs the main job: the paper's spring-mass-damper under its Fig 10 fault,
# simulated with a persistently exciting load; writes out/simulate/energy.json and energy.png.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ea-gym simulate experiments/scenarios/paper_fig10_sines.json --out out/simulate "$@"
