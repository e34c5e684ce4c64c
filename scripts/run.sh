#!/usr/bin/env bash
# Sets everything up, then runs the main job: the paper's section 4 reproduced end to end (isolation
# network trained on the fault database, the Fig 10 fault under the paper's constant load and under a
# persistently exciting load, End of Life beside Table 3); writes out/reproduce/report.md.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ea-gym reproduce --out out/reproduce "$@"
