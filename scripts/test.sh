#!/usr/bin/env bash
# Runs every test: Rust (unit, integration, doc) and Python (pytest). Fails if any test fails;
# runs every test binary even after a failure (--no-fail-fast) and ends with a line counting the
# skipped tests of each suite (the real-log tests skip without ../shared/data).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
skipped_log="$PWD/target/skipped-tests.log"
mkdir -p target && rm -f "$skipped_log"
status=0
UWBIMU_SKIPPED_LOG="$skipped_log" cargo test --workspace --quiet --no-fail-fast || status=$?
if [ -s "$skipped_log" ]; then
    echo "Rust: $(cut -d: -f1 "$skipped_log" | sort -u | wc -l) tests skipped:"
    sort -u "$skipped_log" | sed 's/^/  skipped: /'
else
    echo "Rust: 0 tests skipped"
fi
.venv/bin/python -m pytest -q -rs tests/python || status=$?
exit "$status"
