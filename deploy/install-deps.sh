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
  gnuplot-nox
  python3-prometheus-client
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
