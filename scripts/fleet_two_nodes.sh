#!/usr/bin/env bash
# The multi-node recipe of docs/fleet.md, run on this machine: a head node and a second node (one
# CPU each, token authentication) joined at 127.0.0.1:PORT, then benches/fleet.py on that cluster
# (outputs checked against serial replay). Both nodes run in the foreground (`--block`) in the
# background of this script and are stopped when it exits, so a Ray of another process survives.
#   bash scripts/fleet_two_nodes.sh [PORT] [benches/fleet.py options...]
set -euo pipefail
cd "$(dirname "$0")/.."
port="${1:-6390}"
shift || true
export PATH="$PWD/.venv/bin:$PATH" RAY_AUTH_MODE=token
pids=()
stop_nodes() {
    for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
    wait 2>/dev/null || true
    # `ray start --head` names its cluster for `ray.init()` in this file; a stopped head's entry
    # would send later local `ray.init()` calls to a dead address.
    bootstrap="${TMPDIR:-/tmp}/ray/ray_current_cluster"
    if [ -f "$bootstrap" ] && grep -q ":$port\$" "$bootstrap"; then rm -f "$bootstrap"; fi
}
trap stop_nodes EXIT
ray start --head --block --num-cpus=1 --port="$port" --include-dashboard=false --disable-usage-stats >/dev/null 2>&1 &
pids+=($!)
for _ in $(seq 60); do
    ray status --address="127.0.0.1:$port" >/dev/null 2>&1 && break
    sleep 0.5
done
ray start --block --address="127.0.0.1:$port" --num-cpus=1 --disable-usage-stats >/dev/null 2>&1 &
pids+=($!)
for _ in $(seq 60); do
    [ "$(ray status --address="127.0.0.1:$port" 2>/dev/null | grep -c '^ 1 node_')" -ge 2 ] && break
    sleep 0.5
done
python benches/fleet.py --address "127.0.0.1:$port" "$@"
