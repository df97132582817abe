#!/usr/bin/env bash
# Runs the main job on simulated demo data: uwb_ls and ekf on the Li & Wang 2020 preset, with an
# accuracy table and a plot written to out/; then replays the recording written to out/demo.mcap
# with the uwbimu-replay console script that setup.sh's `maturin develop` installed in .venv (one
# compile for both; Foxglove output out/demo_replay.mcap, CSV out/demo_replay.csv).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/python examples/demo.py "$@"
.venv/bin/uwbimu-replay out/demo.mcap --config examples/demo.toml --ground-truth out/demo_truth.csv \
    --out out/demo_replay.mcap --csv out/demo_replay.csv
