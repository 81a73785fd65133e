#!/usr/bin/env bash
# One loadgen run against one build's sculptd: $1 = label, $2 = bin dir, rest = loadgen args.
set -euo pipefail
label=$1; bin=$2; shift 2
d=$(mktemp -d -p /work/bench12); p=$d/port
extra=""
if "$bin/sculptd" serve --help 2>&1 | grep -q -- "--http "; then extra="--http off"; fi
taskset -c 0 "$bin/sculptd" serve --data "$d/data" --listen 127.0.0.1:0 $extra --port-file "$p" > "$d/sculptd.log" 2>&1 &
pid=$!
for i in $(seq 100); do [ -s "$p" ] && break; sleep 0.1; done
load=$(cut -d' ' -f1 /proc/loadavg)
taskset -c 1 "$bin/sculpt-loadgen" --server 127.0.0.1:$(head -1 "$p") --json "$@" > "$d/report.json" 2> "$d/loadgen.err" || true
kill $pid; wait $pid 2>/dev/null || true
python3 - "$label" "$load" "$d/report.json" <<'PY'
import json,sys
label,load,path=sys.argv[1:4]
r=json.load(open(path))
keys=["stroke_ack_p50_ms","stroke_ack_p99_ms","stroke_ack_max_ms","strokes_sent","strokes_acked","server_edit_ms_p50","server_edit_ms_p99","duration_s"]
print(json.dumps({"label":label,"load":float(load),**{k:r.get(k) for k in keys}}))
PY
