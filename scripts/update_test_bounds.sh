#!/usr/bin/env bash
# Re-measures the figures the accuracy tests hold (tests/figures/*.csv: each figure may not rise
# more than 10 % above its stored value) and lists the figures that moved by more than 1 %, then
# `git diff --stat` of the files. Run it after a change that moves a figure on purpose, and say
# in the commit which moved and why.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh > /dev/null
{
    UPDATE_BOUNDS=1 cargo test --workspace --tests --quiet --no-fail-fast -- --nocapture 2>&1
    UPDATE_BOUNDS=1 .venv/bin/python -m pytest -q -s tests/python 2>&1
} | grep -oE "(moved|new): .*" || echo "no figure moved by more than 1 %"
git diff --stat -- tests/figures
