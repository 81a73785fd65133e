#!/usr/bin/env bash
# @brief Stroke->ack latency of a cluster owner with replication = "sync", "async" and "none"
# (issue 17), in one run: for each mode a fresh etcd key prefix, members a (the owner) and b (its
# standby, except under "none"), then sculpt-loadgen against a. Prints one JSON object on stdout
# (per mode stroke_ack_p50_ms / p99_ms / max_ms and acks, and sync's p50 minus async's).
# Usage: tests/bench/cluster_sync_bench.sh   (BIN=build/bin, BENCH_SECONDS=15, ROUNDS=1,
#        SCULPTORS=2, RATE=60)
set -euo pipefail
BIN=${BIN:-build/bin}
SECS=${BENCH_SECONDS:-15}
ROUNDS=${ROUNDS:-1}
SCULPTORS=${SCULPTORS:-2}
RATE=${RATE:-60}
. "$(dirname "$0")/bench_etcd.sh"
start_etcd b

member() {  # mode round name
  local mode=$1 round=$2 name=$3 dir="$WORK/$1-$2"
  mkdir -p "$dir"
  cat > "$dir/$name.toml" <<TOML
[cluster]
etcd = ["$ETCD"]
member = "$name"
prefix = "bench-$mode-$round/"
replication = "$mode"
TOML
  "$BIN/sculptd" serve --config "$dir/$name.toml" --listen 127.0.0.1:0 --http off \
    --data "$dir/$name-data" --port-file "$dir/$name.port" > "$dir/$name.log" 2>&1 &
  PIDS+=($!)
  echo $! > "$dir/$name.pid"
  for _ in $(seq 1 300); do [ -s "$dir/$name.port" ] && break; sleep 0.1; done
}

results="{}"
for round in $(seq 1 "$ROUNDS"); do
  for mode in sync async none; do
    dir="$WORK/$mode-$round"
    member "$mode" "$round" a
    sleep 1  # a takes the scene before b registers
    member "$mode" "$round" b
    if [ "$mode" != none ]; then
      # b's copy complete: a's acks wait for it from here on (sync).
      for _ in $(seq 1 300); do
        grep -q "standby copy of scene default complete" "$dir/b.log" && break
        sleep 0.1
      done
      grep -q "standby copy of scene default complete" "$dir/b.log" ||
        { echo "b never followed a under $mode; see $dir/b.log" >&2; cat "$dir/b.log" >&2; exit 1; }
    else
      sleep 2
    fi
    echo "[cluster-sync-bench] round $round: $mode, $SCULPTORS sculptors x $RATE Hz, ${SECS}s" >&2
    "$BIN/sculpt-loadgen" --server "127.0.0.1:$(head -n1 "$dir/a.port")" --sculptors "$SCULPTORS" \
      --rate "$RATE" --viewers 0 --seconds "$SECS" --json > "$dir/load.json"
    if grep -q "acknowledging asynchronously" "$dir/a.log"; then
      fell_back=true
    else
      fell_back=false
    fi
    results=$(jq --arg k "$mode-$round" --argjson fb "$fell_back" --slurpfile r "$dir/load.json" \
      '. + {($k): (($r[0] | {stroke_ack_p50_ms, stroke_ack_p99_ms, stroke_ack_max_ms,
                              strokes_acked, strokes_unacked, acks_in_order, duration_s})
                   + {sync_fell_back: $fb})}' <<< "$results")
    for n in b a; do kill -TERM "$(cat "$dir/$n.pid")" 2>/dev/null || true; done
    for n in b a; do wait "$(cat "$dir/$n.pid")" 2>/dev/null || true; done
  done
done
jq --argjson secs "$SECS" --argjson sculptors "$SCULPTORS" --argjson rate "$RATE" \
  --arg cpus "$(nproc)" --arg cmd "tests/bench/cluster_sync_bench.sh" \
  '. as $runs | {bench: "cluster_sync", command: $cmd, cpus: ($cpus|tonumber), seconds: $secs,
    sculptors: $sculptors, rate_hz: $rate, runs: .,
    mean_p50_ms: (reduce ("sync", "async", "none") as $m ({};
      . + {($m): ([$runs | to_entries[] | select(.key | startswith($m + "-"))
                   | .value.stroke_ack_p50_ms] | add / length)}))}
   | .sync_minus_async_p50_ms = (.mean_p50_ms.sync - .mean_p50_ms.async)' \
  <<< "$results"
