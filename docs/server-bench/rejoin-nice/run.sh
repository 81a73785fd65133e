#!/bin/bash
# Alternating before/after rounds of the rejoin abuse, sculptd pinned to CPU 0, clients to CPU 1.
# usage: rejoin.sh BEFORE_BIN AFTER_BIN ROUNDS OUTDIR
set -u
before=$1; after=$2; rounds=$3; out=$4; mkdir -p "$out"
for r in $(seq 1 "$rounds"); do
  for which in before after; do
    bin=$before; [ $which = after ] && bin=$after
    echo "round $r $which load $(cut -d' ' -f1-3 /proc/loadavg)" >&2
    python3 "$(dirname "$0")/../../../tests/bench/abuse_bench.py" --bin "$bin" --seconds 10 --server-cpus 0 \
      --client-cpus 1 --abuses rejoin > "$out/$which.$r.json" 2> "$out/$which.$r.err"
  done
done
