#!/usr/bin/env bash
# @brief Aggregate capacity of a cluster (issue 17): six scenes sculpted at once, each by
# SCULPTORS simulated sculptors at RATE Hz, served by one member or by three members started
# together (placement spreads the scenes two a member), with replication "none" and "async" (a
# standby replays every scene on another member). For each layout it runs one sculpt-loadgen per
# scene against the scene's owner (read from etcd), all at once, and reads the members' CPU time
# from /proc. Prints one JSON object: per layout and sculptor count, strokes sent and acknowledged
# per second over all scenes, the worst scene's stroke->ack p50/p99, the members' CPU seconds, and
# the CPU cost per scene of being a standby (async minus none, three members, divided by the
# scenes). Everything shares this machine's cores (no pinning: three members and six load
# generators on 2 cores), so the figures say what one machine sustains, not what three would.
# A layout "sustains" a load when every stroke sent was acknowledged and the worst scene's p99 is
# at most SUSTAIN_P99_MS.
# Usage: tests/bench/cluster_capacity_bench.sh   (BIN=build/bin, BENCH_SECONDS=15,
#        SCULPTORS_LIST="1 2", RATE=60, POSES=4, SUSTAIN_P99_MS=100)
set -euo pipefail
BIN=${BIN:-build/bin}
SECS=${BENCH_SECONDS:-15}
SCULPTORS_LIST=${SCULPTORS_LIST:-"1 2"}
RATE=${RATE:-60}
POSES=${POSES:-4}
SUSTAIN_P99_MS=${SUSTAIN_P99_MS:-100}
SCENES=(default s1 s2 s3 s4 s5)
. "$(dirname "$0")/bench_etcd.sh"
start_etcd cap

# The JSON value of an etcd key (v3 gateway), empty when absent.
etcd_get() {
  local key64
  key64=$(printf '%s' "$1" | base64 -w0)
  curl -s -X POST "$ETCD/v3/kv/range" -d "{\"key\":\"$key64\"}" | python3 -c '
import base64, json, sys
r = json.load(sys.stdin)
kvs = r.get("kvs") or []
print(base64.b64decode(kvs[0]["value"]).decode() if kvs else "")'
}
field() { python3 -c "import json,sys; v=sys.stdin.read(); print(json.loads(v)['$1'] if v.strip() else '')"; }
cpu_s() {  # utime + stime of a process, seconds
  awk -v hz="$(getconf CLK_TCK)" '{print ($14 + $15) / hz}' "/proc/$1/stat" 2>/dev/null || echo 0
}

run() {  # members replication sculptors
  local n=$1 mode=$2 s=$3 tag="$1-$2-$3" dir="$WORK/$1-$2-$3"
  mkdir -p "$dir"
  local mpids=()
  local also=()
  for sc in "${SCENES[@]:1}"; do also+=(--also-scene "$sc"); done
  for m in $(seq 1 "$n"); do
    cat > "$dir/m$m.toml" <<TOML
[cluster]
etcd = ["$ETCD"]
member = "m$m"
prefix = "cap-$tag/"
replication = "$mode"
TOML
    "$BIN/sculptd" serve --config "$dir/m$m.toml" --listen 127.0.0.1:0 --http off \
      --data "$dir/m$m-data" --port-file "$dir/m$m.port" "${also[@]}" > "$dir/m$m.log" 2>&1 &
    PIDS+=($!)
    mpids+=($!)
  done
  # Every scene owned, and (async, three members) every scene's standby following.
  for _ in $(seq 1 300); do
    local ready=1
    for sc in "${SCENES[@]}"; do
      [ -n "$(etcd_get "cap-$tag/scenes/$sc/owner")" ] || ready=0
      if [ "$mode" = async ] && [ "$n" -gt 1 ]; then
        [ -n "$(etcd_get "cap-$tag/scenes/$sc/standby")" ] || ready=0
      fi
    done
    [ $ready = 1 ] && break
    sleep 0.2
  done
  [ "$mode" = async ] && [ "$n" -gt 1 ] && sleep 3  # standbys load their copies
  local before=() i=0
  for p in "${mpids[@]}"; do before+=("$(cpu_s "$p")"); done
  local lpids=()
  for sc in "${SCENES[@]}"; do
    local owner
    owner=$(etcd_get "cap-$tag/scenes/$sc/owner" | field tcp)
    "$BIN/sculpt-loadgen" --server "$owner" --scene "$sc" --sculptors "$s" --rate "$RATE" \
      --poses-per-stroke "$POSES" --seconds "$SECS" --replay-replicas 0 \
      --leafdelta-replicas 0 --viewer-mesh-hz 0 --io-threads 1 --drain-seconds 20 \
      --seed $((i + 1)) --json > "$dir/load-$sc.json" 2> "$dir/load-$sc.err" &
    lpids+=($!)
    i=$((i + 1))
  done
  for p in "${lpids[@]}"; do wait "$p" || true; done
  local cpu=0 j=0
  for p in "${mpids[@]}"; do
    cpu=$(python3 -c "print($cpu + $(cpu_s "$p") - ${before[$j]})")
    j=$((j + 1))
  done
  for p in "${mpids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  for p in "${mpids[@]}"; do wait "$p" 2>/dev/null || true; done
  python3 - "$dir" "$n" "$mode" "$s" "$cpu" "$SECS" "$SUSTAIN_P99_MS" > "$dir/result.json" <<'PY'
import glob, json, sys
d, n, mode, s, cpu, secs = sys.argv[1], int(sys.argv[2]), sys.argv[3], int(sys.argv[4]), float(sys.argv[5]), float(sys.argv[6])
limit = float(sys.argv[7])
loads = []
for f in sorted(glob.glob(d + "/load-*.json")):
    try:
        loads.append(json.load(open(f)))
    except Exception:
        loads.append({})
sent = sum(l.get("strokes_sent", 0) for l in loads)
acked = sum(l.get("strokes_acked", 0) for l in loads)
print(json.dumps({
    "members": n, "replication": mode, "scenes": len(loads), "sculptors_per_scene": s,
    "strokes_sent_per_s": round(sent / secs, 1), "strokes_acked": acked, "strokes_sent": sent,
    "strokes_refused": sum(l.get("strokes_refused", 0) for l in loads),
    "strokes_unacked": sum(l.get("strokes_unacked", 0) for l in loads),
    "worst_scene_p50_ms": max((l.get("stroke_ack_p50_ms", 0) for l in loads), default=0),
    "worst_scene_p99_ms": max((l.get("stroke_ack_p99_ms", 0) for l in loads), default=0),
    "members_cpu_s": round(cpu, 2),
    "sustained": bool(loads) and acked == sent and sent > 0 and
                 max(l.get("stroke_ack_p99_ms", 1e9) for l in loads) <= limit}))
PY
  cat "$dir/result.json"
}

results=()
for s in $SCULPTORS_LIST; do
  results+=("$(run 1 none "$s")")
  results+=("$(run 3 none "$s")")
  results+=("$(run 3 async "$s")")
done
printf '%s\n' "${results[@]}" | python3 -c '
import json, sys
runs = [json.loads(l) for l in sys.stdin if l.strip()]
standby = {}
for r in runs:
    if r["members"] == 3 and r["replication"] == "async":
        base = [b for b in runs if b["members"] == 3 and b["replication"] == "none"
                and b["sculptors_per_scene"] == r["sculptors_per_scene"]]
        if base:
            standby[str(r["sculptors_per_scene"])] = round(
                (r["members_cpu_s"] - base[0]["members_cpu_s"]) / r["scenes"], 3)
print(json.dumps({"seconds": float(sys.argv[1]), "rate_hz": int(sys.argv[2]),
                  "poses_per_stroke": int(sys.argv[3]), "runs": runs,
                  "standby_cpu_s_per_scene": standby}, indent=1))' "$SECS" "$RATE" "$POSES"
