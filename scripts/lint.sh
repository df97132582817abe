#!/usr/bin/env bash
# Lints and the builds CI adds to the tests: formatting, no import circle between the source
# files of a crate (scripts/module_cycles.py), the extension's build reusing the tests' crates
# (scripts/one_build.py), clippy on every target (warnings are
# errors), the library without default features (the filters alone), each feature alone, and the
# API docs without warnings (broken or private intra-doc links). Fails on the first problem.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo fmt --all --check
python3 scripts/module_cycles.py
python3 scripts/one_build.py
cargo clippy --workspace --all-targets --features python --quiet -- -D warnings
cargo check --quiet -p uwbimu_rs --no-default-features
for feature in sim io cli parallel; do
    cargo check --quiet -p uwbimu_rs --no-default-features --features "$feature"
done
RUSTDOCFLAGS="-D warnings" cargo doc --quiet --workspace --no-deps
echo "lint: ok"
