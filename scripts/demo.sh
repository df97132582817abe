#!/usr/bin/env bash
# Runs the main job on simulated demo data: uwb_ls, ekf, riekf and best on the Li & Wang 2020 preset
# (LOS and NLOS) via uwbimu_rs.compare, with accuracy tables and the report figures out/demo.png and
# out/demo_los.png (docs/compare-and-plot.md); then replays the recording written to out/demo.mcap
# with the uwbimu-replay console script that setup.sh's `maturin develop` installed in .venv (one
# compile for both; Foxglove output out/demo_replay.mcap, CSV out/demo_replay.csv).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/python examples/demo.py "$@"
.venv/bin/uwbimu-replay out/demo.mcap --config examples/demo.toml --ground-truth out/demo_truth.csv \
    --out out/demo_replay.mcap --csv out/demo_replay.csv
