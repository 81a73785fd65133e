# @brief Sourced by the cluster bench scripts: a work directory ($WORK) removed at exit with every
# process in $PIDS killed, free_port, and start_etcd, which starts one etcd from Debian's
# etcd-server on loopback and waits until it answers; its client URL is then in $ETCD.
WORK=$(mktemp -d)
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill -KILL "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$WORK"
}
trap cleanup EXIT

free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }

start_etcd() {  # name
  local client peer
  client=$(free_port)
  peer=$(free_port)
  ETCD="http://127.0.0.1:$client"
  /usr/bin/etcd --name "$1" --data-dir "$WORK/etcd" --listen-client-urls "$ETCD" \
    --advertise-client-urls "$ETCD" --listen-peer-urls "http://127.0.0.1:$peer" \
    --initial-advertise-peer-urls "http://127.0.0.1:$peer" \
    --initial-cluster "$1=http://127.0.0.1:$peer" > "$WORK/etcd.log" 2>&1 &
  PIDS+=($!)
  for _ in $(seq 1 150); do
    curl -s "$ETCD/health" | grep -q true && return 0
    sleep 0.1
  done
  echo "etcd did not start; see $WORK/etcd.log" >&2
  return 1
}
