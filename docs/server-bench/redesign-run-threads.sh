#!/usr/bin/env bash
# One loadgen run against one build's sculptd, keeping the whole report and sculptd's per-thread CPU
# time (threads.txt, sampled each second): $1 = label, $2 = bin dir, rest = loadgen args.
set -euo pipefail
label=$1; bin=$2; shift 2
d=$(mktemp -d -p "${BENCH_DIR:-/tmp}"); p=$d/port
extra=""
if "$bin/sculptd" serve --help 2>&1 | grep -q -- "--http "; then extra="--http off"; fi
taskset -c 0 "$bin/sculptd" serve --data "$d/data" --listen 127.0.0.1:0 $extra --port-file "$p" > "$d/sculptd.log" 2>&1 &
pid=$!
for i in $(seq 100); do [ -s "$p" ] && break; sleep 0.1; done
load=$(cut -d' ' -f1 /proc/loadavg)
( while kill -0 $pid 2>/dev/null; do ps -L -o tid,comm,time -p $pid | tail -n +2 > "$d/threads.txt"; sleep 1; done ) &
taskset -c 1 "$bin/sculpt-loadgen" --server 127.0.0.1:$(head -1 "$p") --json "$@" > "$d/report.json" 2> "$d/loadgen.err" || true
kill $pid; wait $pid 2>/dev/null || true
echo "$label load=$load dir=$d"
