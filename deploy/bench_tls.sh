#!/usr/bin/env bash
# @brief Stroke->ack latency over TLS vs plaintext in one run: two sculptds pinned to CPU 0 (one
# with a throw-away certificate), one sculpt-loadgen sculptor pinned to CPU 1, runs alternating
# ROUNDS times, plain and TLS side by side. Prints one JSON line per run with the server CPU seconds.
# Usage: deploy/bench_tls.sh [BUILD_BIN_DIR] [ROUNDS] [SECONDS]
set -euo pipefail
BIN="$(realpath "${1:-build/bin}")"; ROUNDS="${2:-3}"; SECS="${3:-10}"
DIR="$(mktemp -d)"
trap 'kill $PLAIN_PID $TLS_PID 2>/dev/null || true; wait 2>/dev/null || true; rm -rf "$DIR"' EXIT
cd "$DIR"
EC=(-newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes)
openssl req -x509 "${EC[@]}" -keyout ca.key -out ca.pem -days 2 -subj /CN=bench-ca 2>/dev/null
openssl req "${EC[@]}" -keyout server.key -out server.csr -subj /CN=localhost 2>/dev/null
echo "subjectAltName=DNS:localhost,IP:127.0.0.1" > san.ext
openssl x509 -req -in server.csr -CA ca.pem -CAkey ca.key -CAcreateserial -out server.pem \
  -days 2 -extfile san.ext 2>/dev/null
taskset -c 0 "$BIN/sculptd" serve --data plain-data --listen 127.0.0.1:0 --http off \
  --port-file plain.port > plain.log 2>&1 & PLAIN_PID=$!
taskset -c 0 "$BIN/sculptd" serve --data tls-data --listen 127.0.0.1:0 --http off \
  --port-file tls.port --tls-cert server.pem --tls-key server.key > tls.log 2>&1 & TLS_PID=$!
for _ in $(seq 100); do [ -s plain.port ] && [ -s tls.port ] && break; sleep 0.1; done
cpu() { awk '{print ($14 + $15) / 100}' "/proc/$1/stat"; }
# Each round runs both loadgens at the same time (one sculptor each, both on CPU 1), so the
# plaintext and the TLS figures see the same machine load.
run() {  # mode round
  local mode=$1 r=$2 port pid flags=()
  port=$(head -1 "$mode.port"); pid=$PLAIN_PID
  if [ "$mode" = tls ]; then pid=$TLS_PID; flags=(--ca ca.pem); fi
  local c0 c1 out
  c0=$(cpu "$pid")
  out=$(taskset -c 1 "$BIN/sculpt-loadgen" --server "127.0.0.1:$port" --sculptors 1 \
    --seconds "$SECS" --replay-replicas 0 --leafdelta-replicas 0 --seed "$r" --json "${flags[@]}")
  c1=$(cpu "$pid")
  echo "$out" | python3 -c "import json,sys; d=json.load(sys.stdin); print(json.dumps({'round': $r, 'mode': '$mode', 'acked': d['strokes_acked'], 'p50_ms': d['stroke_ack_p50_ms'], 'p99_ms': d['stroke_ack_p99_ms'], 'server_cpu_s': round($c1 - $c0, 3)}))"
}
for r in $(seq "$ROUNDS"); do
  run plain "$r" > "plain.$r.json" & a=$!
  run tls "$r" > "tls.$r.json" & b=$!
  wait $a $b
  cat "plain.$r.json" "tls.$r.json"
done
