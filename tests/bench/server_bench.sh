#!/usr/bin/env bash
# @brief Server benchmarks of issue "sculptd": the 4 x 120 Hz run with 8 viewers, the scaling
# curve (1..16 sculptors at 60 Hz) and fsync always vs group. Each run starts a fresh sculptd on
# a fresh data directory, samples the server's RSS once a second, and writes one JSON per run
# into $OUT (default docs/server-bench/). Usage: tests/bench/server_bench.sh [OUT]
set -euo pipefail
BIN=${BIN:-build/bin}
OUT=${1:-docs/server-bench}
SECS=${BENCH_SECONDS:-30}
SCALE_SECS=${SCALE_SECONDS:-15}
mkdir -p "$OUT"
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

run() {  # name fsync sculptors rate viewers seconds [data-parent]
  local name=$1 fsync=$2 sculptors=$3 rate=$4 viewers=$5 secs=$6 parent=${7:-$WORK}
  local data="$parent/$name" port_file="$WORK/$name.port" rss="$WORK/$name.rss"
  rm -rf "$data"
  "$BIN/sculptd" serve --data "$data" --listen 127.0.0.1:0 --port-file "$port_file" \
    --fsync "$fsync" > "$WORK/$name.log" 2>&1 &
  local pid=$!
  for _ in $(seq 1 300); do [ -s "$port_file" ] && break; sleep 0.1; done
  local port
  port=$(head -n1 "$port_file")
  ( while kill -0 "$pid" 2>/dev/null; do
      awk '/VmRSS/ {print $2}' "/proc/$pid/status" 2>/dev/null || true
      sleep 1
    done ) > "$rss" &
  local sampler=$!
  echo "[server-bench] $name: $sculptors sculptors x $rate Hz, $viewers viewers, fsync $fsync, ${secs}s" >&2
  "$BIN/sculpt-loadgen" --server "127.0.0.1:$port" --sculptors "$sculptors" --rate "$rate" \
    --viewers "$viewers" --seconds "$secs" --json > "$WORK/$name.json"
  kill -TERM "$pid"
  wait "$pid" || true
  kill "$sampler" 2>/dev/null || true
  wait "$sampler" 2>/dev/null || true
  # RSS samples in kB: first, max, last (flat means max ~ last after warm-up).
  local first max last
  first=$(head -1 "$rss"); max=$(sort -n "$rss" | tail -1); last=$(tail -1 "$rss")
  {
    echo "{\"run\": \"$name\", \"fsync\": \"$fsync\", \"sculptors\": $sculptors, \"rate_hz\": $rate,"
    echo " \"viewers\": $viewers, \"seconds\": $secs, \"data_dir_fs\": \"$(df --output=fstype "$parent" | tail -1)\","
    echo " \"server_rss_kb\": {\"first\": ${first:-0}, \"max\": ${max:-0}, \"last\": ${last:-0}, \"samples\": [$(paste -sd, "$rss")]},"
    echo " \"loadgen\": $(cat "$WORK/$name.json")}"
  } > "$OUT/$name.json"
  rm -rf "$data"
}

run main-4x120-group group 4 120 8 "$SECS"
run main-4x120-always always 4 120 8 "$SECS"
# The same on tmpfs, where fdatasync costs nothing: separates the kernel's cost from the disk's.
if [ -d /dev/shm ]; then run main-4x120-tmpfs group 4 120 8 "$SECS" /dev/shm; fi
for n in 1 2 4 8 16; do
  run "scale-${n}x60" group "$n" 60 0 "$SCALE_SECS"
done
echo "[server-bench] results in $OUT/" >&2
