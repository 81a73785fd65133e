#!/usr/bin/env bash
# @brief Installs Sculpt's build and run dependencies from Debian 12 packages. Idempotent.
set -euo pipefail

PACKAGES=(
  build-essential cmake make pkg-config ccache
  libopenvdb-dev libtbb-dev libblosc-dev libimath-dev
  libboost-dev libboost-system-dev libboost-iostreams-dev
  libprotobuf-dev protobuf-compiler
  libdraco-dev draco libeigen3-dev libtinygltf-dev
  libspdlog-dev libfmt-dev libcli11-dev libtomlplusplus-dev nlohmann-json3-dev
  libassimp-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libxxhash-dev libsodium-dev libzstd-dev
  libssl-dev openssl
  gnuplot-nox
  chromium
  python3-prometheus-client
  python3-yaml  # tests/deploy: the Kubernetes manifests are parsed
  etcd-server  # cluster mode (issue 17): the coordination store; its tests start one
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

# The web client is built with Node.js and npm: Debian's, unless this machine already has a node.
if ! command -v node > /dev/null 2>&1 || ! command -v npm > /dev/null 2>&1; then
  for p in nodejs npm; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
fi

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
else
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  echo "install-deps: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# The web client's npm packages, exactly as package-lock.json pins them; skipped when
# node_modules already matches the lock file (npm writes node_modules/.package-lock.json).
WEB="$(cd "$(dirname "$0")/.." && pwd)/client/web"
if [ -f "$WEB/package-lock.json" ]; then
  if [ ! -f "$WEB/node_modules/.package-lock.json" ] ||
     [ "$WEB/package-lock.json" -nt "$WEB/node_modules/.package-lock.json" ]; then
    echo "install-deps: npm ci in client/web"
    (cd "$WEB" && npm ci --no-audit --no-fund --loglevel=error)
  else
    echo "install-deps: client/web node_modules matches package-lock.json"
  fi
fi
