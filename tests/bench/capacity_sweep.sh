#!/usr/bin/env bash
# The server's capacity (issue 11, "Measure"): the highest sculptor count at RATE Hz whose
# stroke->ack p99 stays within GOAL_MS, with sculptd pinned to one core and sculpt-loadgen to the
# other, so the figure is the server's. One fresh data directory per count; one JSON line per run
# on stdout, then a summary line.
#
#   tests/bench/capacity_sweep.sh [BIN] [-- extra sculpt-loadgen arguments]
#   SCULPTORS_LIST="4 8 12 16" RATE=120 SECONDS_EACH=10 GOAL_MS=15 SERVER_CPUS=0 LOADGEN_CPUS=1
#
# SERVER_CPUS=0,1 with LOADGEN_CPUS=0,1 gives "sculptd on both cores, the load generator beside
# it". Progress goes to stderr.
set -euo pipefail

bin=${1:-build/bin}
shift || true
[ "${1:-}" = "--" ] && shift
if [ ! -x "$bin/sculptd" ] || [ ! -x "$bin/sculpt-loadgen" ]; then
  echo "capacity_sweep: no sculptd or sculpt-loadgen in $bin (build first: make build)" >&2
  exit 2
fi
list=${SCULPTORS_LIST:-"2 4 6 8 10 12 16"}
rate=${RATE:-120}
seconds=${SECONDS_EACH:-10}
goal=${GOAL_MS:-15}
server_cpus=${SERVER_CPUS:-0}
loadgen_cpus=${LOADGEN_CPUS:-1}

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
best=0
for n in $list; do
  d=$work/run-$n
  mkdir -p "$d"
  taskset -c "$server_cpus" "$bin/sculptd" serve --data "$d/data" --listen 127.0.0.1:0 \
    --http off --port-file "$d/port" > "$d/sculptd.log" 2>&1 &
  pid=$!
  for _ in $(seq 200); do [ -s "$d/port" ] && break; sleep 0.05; done
  if [ ! -s "$d/port" ]; then
    kill "$pid" 2>/dev/null || true
    echo "capacity_sweep: sculptd did not start; its log:" >&2
    cat "$d/sculptd.log" >&2
    exit 1
  fi
  load=$(cut -d' ' -f1 /proc/loadavg)
  echo "capacity_sweep: $n sculptors x $rate Hz for $seconds s (load $load) ..." >&2
  taskset -c "$loadgen_cpus" "$bin/sculpt-loadgen" --server "127.0.0.1:$(head -1 "$d/port")" \
    --sculptors "$n" --rate "$rate" --seconds "$seconds" --json "$@" > "$d/report.json" \
    2> "$d/loadgen.err" || true
  kill "$pid" 2>/dev/null || true
  wait "$pid" 2>/dev/null || true
  line=$(python3 - "$n" "$rate" "$load" "$goal" "$server_cpus" "$loadgen_cpus" "$d/report.json" <<'PY'
import json, sys
n, rate, load, goal, scpu, lcpu, path = sys.argv[1:8]
try:
    r = json.load(open(path))
except (OSError, ValueError):
    r = {}
keys = ["strokes_sent", "strokes_acked", "strokes_refused", "stroke_ack_p50_ms",
        "stroke_ack_p99_ms", "stroke_ack_max_ms", "server_edit_ms_p50", "server_edit_ms_p99",
        "duration_s", "server_errors"]
out = {"sculptors": int(n), "rate_hz": float(rate), "edits_per_s_offered": int(n) * float(rate),
       "load_before": float(load), "sculptd_cpus": scpu, "loadgen_cpus": lcpu}
out.update({k: r.get(k) for k in keys})
p99 = r.get("stroke_ack_p99_ms")
out["meets_goal"] = bool(r) and p99 is not None and p99 <= float(goal) and \
    r.get("strokes_acked") == r.get("strokes_sent")
print(json.dumps(out))
PY
)
  echo "$line"
  if python3 -c 'import json,sys; sys.exit(0 if json.loads(sys.argv[1])["meets_goal"] else 1)' "$line"; then
    best=$n
  fi
done
echo "{\"summary\": true, \"goal_p99_ms\": $goal, \"rate_hz\": $rate, \"highest_sculptors_meeting_goal\": $best, \"sculptd_cpus\": \"$server_cpus\", \"loadgen_cpus\": \"$loadgen_cpus\"}"
