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
skipped_log="$PWD/target/skipped-tests.log"
mkdir -p target && rm -f "$skipped_log"
# The Rust tests build while setup.sh installs the Python packages (into a new .venv 164 s, 30 s of
# it CPU: pip mostly waits on the disk); its build of the extension waits for cargo's lock. A
# failed build is reported by the `cargo test` below, which builds again.
cargo test --workspace --tests --no-run --quiet >target/test-build.log 2>&1 &
build=$!
bash scripts/setup.sh || { kill "$build" 2>/dev/null; exit 1; }
wait "$build" || true
status=0
# The test targets (unit and integration) and then the doc tests; the examples are not built
# here: clippy in scripts/lint.sh checks every one, and the Python tests build those they run.
UWBIMU_SKIPPED_LOG="$skipped_log" cargo test --workspace --tests --quiet --no-fail-fast || status=$?
cargo test --workspace --doc --quiet || status=$?
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
