#!/usr/bin/env bash
# Runs every test: Rust (unit, integration, doc) and Python (pytest). Fails if any test fails;
# runs every test binary even after a failure (--no-fail-fast) and ends with a line counting the
# skipped tests of each suite (the real-log tests skip without ../shared/data). The Python tests
# but the real-log ones (marker needs_isas) run as on a user's clone, with UWBIMU_SHARED naming a
# directory that does not exist: one that reads ../shared without the marker fails here.
# pytest runs on every core (pytest-xdist, `-n auto`); the tests that must not run beside each
# other share one worker (tests/python/conftest.py, ONE_WORKER).
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
xdist=(-n auto --dist loadgroup)
UWBIMU_SHARED="$PWD/target/no-shared" .venv/bin/python -m pytest -q -rs "${xdist[@]}" -m "not needs_isas" tests/python || status=$?
.venv/bin/python -m pytest -q -rs "${xdist[@]}" -m needs_isas tests/python || status=$?
exit "$status"
