#!/usr/bin/env bash
# Runs the main job on simulated demo data: uwb_ls and ekf on the seed-000 preset, with an
# accuracy table and a plot written to out/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/python examples/demo.py "$@"
