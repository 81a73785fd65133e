#!/usr/bin/env bash
# @brief Viewer bandwidth by chunk size and position quantisation (issue 13): for each
# (mesh_chunk_voxels, mesh_position_bits), a fresh sculptd pinned to core 0 on the default sphere
# while sculpt-loadgen on core 1 drives 4 sculptors x 120 Hz and one mesh viewer at 10 Hz.
# Prints one JSON line per setting: the viewer's bytes per second, the chunks it received and the
# sculptors' stroke->ack p50/p99. Usage: tests/bench/viewer_bandwidth.sh [SECONDS]
set -euo pipefail
BIN=${BIN:-build/bin}
SECS=${1:-10}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
for chunk in ${CHUNKS:-16 32 64}; do
  for bits in ${BITS:-11 12 14}; do
    cat > "$WORK/scene.toml" <<TOML
[scene]
mesh_chunk_voxels = $chunk
mesh_position_bits = $bits
TOML
    rm -rf "$WORK/data" "$WORK/port"
    taskset -c 0 "$BIN/sculptd" serve --config "$WORK/scene.toml" --data "$WORK/data" \
      --listen 127.0.0.1:0 --http off --port-file "$WORK/port" > "$WORK/log" 2>&1 &
    pid=$!
    for _ in $(seq 1 300); do [ -s "$WORK/port" ] && break; sleep 0.1; done
    taskset -c 1 "$BIN/sculpt-loadgen" --server "127.0.0.1:$(head -n1 "$WORK/port")" --sculptors 4 \
      --rate 120 --viewers 1 --viewer-mesh-hz 10 --seconds "$SECS" --json > "$WORK/out.json"
    kill -TERM "$pid"; wait "$pid" || true
    python3 - "$chunk" "$bits" "$WORK/out.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[3]))
print(json.dumps({"mesh_chunk_voxels": int(sys.argv[1]), "mesh_position_bits": int(sys.argv[2]),
                  "viewer_bytes_down_per_s": r.get("viewer_bytes_down_per_s"),
                  "viewer_chunks_received": r.get("viewer_chunks_received"),
                  "draco_chunk_encode_ms_p50": r.get("draco_chunk_encode_ms_p50"),
                  "stroke_ack_p50_ms": r.get("ack_p50_ms", r.get("stroke_ack_p50_ms")),
                  "stroke_ack_p99_ms": r.get("ack_p99_ms", r.get("stroke_ack_p99_ms")),
                  "strokes_acked": r.get("strokes_acked")}))
PY
  done
done
