#!/usr/bin/env bash
# Instructions per hot-path call (machine-independent, unlike times): runs
# examples/instruction_counts.rs under valgrind's callgrind at two call counts and prints the
# difference per call; `range` and `epoch` have the cost of restoring the filter before each call
# taken off. Needs valgrind (Debian package `valgrind`). Usage:
#   bash scripts/instruction_counts.sh [Filter ...]      (default: every streaming filter)
set -euo pipefail
cd "$(dirname "$0")/.."
command -v valgrind > /dev/null || { echo "valgrind is not installed (apt install valgrind)" >&2; exit 1; }
cargo build --release --quiet --example instruction_counts
bin=target/release/examples/instruction_counts
n1=1000
n2=11000
count() { # filter call n -> instructions of the whole run
    valgrind --tool=callgrind --callgrind-out-file=/dev/null "$bin" "$1" "$2" "$3" 2>&1 | sed -n 's/.*Collected : \([0-9]*\).*/\1/p'
}
per_call() { # filter call -> instructions per call
    echo $(( ($(count "$1" "$2" $n2) - $(count "$1" "$2" $n1)) / (n2 - n1) ))
}
filters=("$@")
[ ${#filters[@]} -gt 0 ] || mapfile -t filters < <("$bin" list)
echo "| filter | predict | range | epoch of 4 |"
echo "|---|---|---|---|"
for f in "${filters[@]}"; do
    restore=$(per_call "$f" restore)
    echo "| $f | $(per_call "$f" predict) | $(( $(per_call "$f" range) - restore )) | $(( $(per_call "$f" epoch) - restore )) |"
done
