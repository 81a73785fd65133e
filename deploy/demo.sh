#!/usr/bin/env bash
# @brief `make demo`: sculptd on the default data directory, simulated sculptors and a viewer
# for a bounded time, then the result exported. Everything lands in $DEMO_OUT (demo-output/).
set -euo pipefail
BIN=${BIN:-build/bin}
OUT=${DEMO_OUT:-demo-output}
DATA=${SCULPT_DATA:-sculpt-data}
RUN_SECONDS=${DEMO_SECONDS:-10}
SCULPTORS=${DEMO_SCULPTORS:-4}
VIEWERS=${DEMO_VIEWERS:-1}

mkdir -p "$OUT"
PORT_FILE="$OUT/.sculptd.port"
rm -f "$PORT_FILE"
"$BIN/sculptd" serve --data "$DATA" --listen 127.0.0.1:0 --port-file "$PORT_FILE" \
  > "$OUT/sculptd.log" 2>&1 &
PID=$!
trap 'kill "$PID" 2>/dev/null || true' EXIT
for _ in $(seq 1 300); do
  [ -s "$PORT_FILE" ] && break
  if ! kill -0 "$PID" 2>/dev/null; then
    echo "demo: sculptd exited; see $OUT/sculptd.log" >&2
    tail -5 "$OUT/sculptd.log" >&2
    exit 1
  fi
  sleep 0.1
done
PORT=$(head -n1 "$PORT_FILE")
HTTP_PORT=$(sed -n 2p "$PORT_FILE")
SERVER="127.0.0.1:$PORT"
echo "demo: sculptd listening on $SERVER, data directory $DATA ($(grep -o 'recovered.*' "$OUT/sculptd.log" | head -1))"

WEB_URL="http://127.0.0.1:$HTTP_PORT/"
if [ -n "$HTTP_PORT" ] && [ "$HTTP_PORT" != 0 ]; then
  echo "demo: watch it live in a browser while it runs: ${WEB_URL}#role=viewer&token=sculpt-dev-viewer"
  echo "demo: or sculpt along: ${WEB_URL}#role=sculptor&token=sculpt-dev-sculptor&name=you" \
    "(DEMO_SECONDS=300 make demo gives you five minutes)"
fi

echo "demo: $SCULPTORS simulated sculptors and $VIEWERS viewer(s) for $RUN_SECONDS s ..."
"$BIN/sculpt-loadgen" --server "$SERVER" --sculptors "$SCULPTORS" --viewers "$VIEWERS" \
  --rate 60 --seconds "$RUN_SECONDS" --json > "$OUT/loadgen.json" &
LOADGEN=$!
# A picture of the live session as a browser viewer sees it, halfway through the run.
SHOT_SCRIPT="$(dirname "$0")/../client/web/test/screenshot.mjs"
if [ -n "$HTTP_PORT" ] && command -v node > /dev/null && [ -x /usr/bin/chromium ] &&
   [ -d "$(dirname "$0")/../client/web/node_modules/playwright-core" ]; then
  sleep "$(( RUN_SECONDS / 2 ))"
  node "$SHOT_SCRIPT" "${WEB_URL}#role=viewer&token=sculpt-dev-viewer&name=demo-camera" \
    "$OUT/live.png" 1500 > "$OUT/screenshot.log" 2>&1 &&
    echo "demo: $(cat "$OUT/screenshot.log")" ||
    echo "demo: no live screenshot (see $OUT/screenshot.log)"
else
  echo "demo: no live screenshot (node, chromium or client/web/node_modules missing)"
fi
wait "$LOADGEN"

"$BIN/sculpt" export --server "$SERVER" --out "$OUT/sculpture.vdb" > /dev/null
"$BIN/sculpt" export --server "$SERVER" --out "$OUT/sculpture.ply" > /dev/null
"$BIN/sculpt" export --server "$SERVER" --format glb --out "$OUT/sculpture.glb" > /dev/null
"$BIN/sculpt" info --server "$SERVER" > "$OUT/scene.json"
"$BIN/sculpt" info --mesh-stats "$OUT/sculpture.vdb" > "$OUT/summary.json"

kill -TERM "$PID"
wait "$PID" || true
trap - EXIT
rm -f "$PORT_FILE"

field() { grep -o "\"$1\": *[^,}]*" "$OUT/loadgen.json" | head -1 | sed 's/.*: *//'; }
echo "demo: strokes sent $(field strokes_sent), acknowledged $(field strokes_acked), refused $(field strokes_refused)"
echo "demo: stroke->ack p50 $(field stroke_ack_p50_ms) ms, p99 $(field stroke_ack_p99_ms) ms"
echo "demo: result: $(cat "$OUT/summary.json")"
mesh() { grep -o "\"$1\": *[^,}]*" "$OUT/summary.json" | head -1 | sed 's/.*: *//'; }
echo "demo: surface: $(mesh components) piece(s), genus $(mesh genus), $(mesh boundary_edges) open and" \
  "$(mesh non_manifold_edges) non-manifold edges, enclosed/tracked volume $(mesh signed_volume_over_tracked)"
echo "demo: results in $OUT/: sculpture.vdb, sculpture.ply, sculpture.glb, summary.json, scene.json, loadgen.json, live.png, sculptd.log"
echo "demo: the scene persists in $DATA/ (edit log and snapshots); run again to keep sculpting it"
