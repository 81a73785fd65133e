#!/usr/bin/env bash
# @brief Replication benchmarks of issue 4 (and the haptic client of issue 5): (1) 4 sculptors x 120 Hz + 8 mesh viewers with one
# replay replica and one leaf-delta replica of the whole object, (2) a late join of a radius-128
# voxel sphere. Each run starts a fresh sculptd on a fresh data directory and writes one JSON into
# $OUT (default docs/replication-bench/). Usage: tests/bench/replication_bench.sh [OUT]
set -euo pipefail
BIN=${BIN:-build/bin}
OUT=${1:-docs/replication-bench}
SECS=${BENCH_SECONDS:-30}
mkdir -p "$OUT"
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

serve() {  # name [config]
  local name=$1 config=${2:-}
  local args=(serve --data "$WORK/$name-data" --listen 127.0.0.1:0 --port-file "$WORK/$name.port")
  if [ -n "$config" ]; then args+=(--config "$config"); fi
  "$BIN/sculptd" "${args[@]}" > "$WORK/$name.log" 2>&1 &
  echo $! > "$WORK/$name.pid"
  for _ in $(seq 1 600); do [ -s "$WORK/$name.port" ] && break; sleep 0.1; done
}
stop() { kill -TERM "$(cat "$WORK/$1.pid")"; wait "$(cat "$WORK/$1.pid")" || true; }

echo "[replication-bench] 4 sculptors x 120 Hz, 8 mesh viewers at 10 Hz, replay + leaf-delta replicas, ${SECS}s" >&2
serve main
"$BIN/sculpt-loadgen" --server "127.0.0.1:$(head -n1 "$WORK/main.port")" --sculptors 4 --rate 120 \
  --viewers 8 --viewer-mesh-hz 10 --replay-replicas 1 --leafdelta-replicas 1 --seconds "$SECS" \
  --json > "$OUT/main-4x120-8viewers.json"
stop main

# The same replicas without mesh viewers and at half the load: what replay costs when the
# machine is not saturated (server and replicas share these 2 cores).
echo "[replication-bench] 2 sculptors x 60 Hz, replay + leaf-delta replicas, no viewers, ${SECS}s" >&2
serve light
"$BIN/sculpt-loadgen" --server "127.0.0.1:$(head -n1 "$WORK/light.port")" --sculptors 2 --rate 60 \
  --viewers 0 --replay-replicas 1 --leafdelta-replicas 1 --seconds "$SECS" \
  --json > "$OUT/light-2x60.json"
stop light

# Issue 5: the haptic loop of one client on its own replica while 4 sculptors edit at 120 Hz.
echo "[replication-bench] 4 sculptors x 120 Hz with a haptic client, ${SECS}s" >&2
serve haptic
"$BIN/sculpt-loadgen" --server "127.0.0.1:$(head -n1 "$WORK/haptic.port")" --sculptors 4 --rate 120 \
  --viewers 0 --replay-replicas 0 --leafdelta-replicas 0 --haptic-client --seconds "$SECS" \
  --json > "$OUT/haptic-4x120.json"
stop haptic

echo "[replication-bench] late join of a radius-128-voxel sphere" >&2
serve late deploy/bench/sphere-r128.toml
for i in 1 2 3; do
  "$BIN/sculpt-loadgen" --server "127.0.0.1:$(head -n1 "$WORK/late.port")" --late-join --json \
    > "$OUT/late-join-r128-$i.json"
done
stop late
echo "[replication-bench] results in $OUT/" >&2
