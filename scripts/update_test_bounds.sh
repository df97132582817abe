#!/usr/bin/env bash
# Re-measures the figures the accuracy tests hold (tests/figures/*.csv: each figure may not rise
# more than 10 % above its stored value) and lists the figures that moved by more than 1 %, then
# `git diff --stat` of the files. A figure that got worse (higher) by more than 1 % is not stored:
# it is listed as `worse: ... not stored` and the script fails. After naming each such figure and
# its reason in the commit message, `bash scripts/update_test_bounds.sh --allow-worse` stores them.
#
#   bash scripts/update_test_bounds.sh                # store improvements and new figures only
#   bash scripts/update_test_bounds.sh --allow-worse  # also store the worsened ones
set -euo pipefail
cd "$(dirname "$0")/.."
case "${1:-}" in
    "") ;;
    --allow-worse) export UPDATE_BOUNDS_ALLOW_WORSE=1 ;;
    *) echo "usage: bash scripts/update_test_bounds.sh [--allow-worse]" >&2; exit 2 ;;
esac
bash scripts/setup.sh > /dev/null
log="$(mktemp)"
trap 'rm -f "$log"' EXIT
{
    UPDATE_BOUNDS=1 cargo test --workspace --tests --quiet --no-fail-fast -- --nocapture 2>&1
    UPDATE_BOUNDS=1 .venv/bin/python -m pytest -q -s tests/python 2>&1
} | grep -oE "(moved|new|worse): .*" | sort > "$log" || true
if [ -s "$log" ]; then cat "$log"; else echo "no figure moved by more than 1 %"; fi
git diff --stat -- tests/figures
refused=$(grep -c "not stored" "$log" || true)
if [ "$refused" -gt 0 ]; then
    echo "$refused figures got worse by more than 1 % and were not stored: name each and its reason in the commit message, then rerun with --allow-worse" >&2
    exit 1
fi
