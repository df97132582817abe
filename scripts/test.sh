#!/usr/bin/env bash
# Runs every test: Rust (unit, integration, doc) and Python (pytest). Fails if any test fails.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cargo test --workspace --quiet --no-fail-fast
.venv/bin/python -m pytest -q tests/python
