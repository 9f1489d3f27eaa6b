#!/usr/bin/env bash
# Installs aosr's build dependencies from Debian 12 packages (only those missing), then configures and
# builds everything in ./build (Release). Idempotent: a second run installs nothing and rebuilds only
# what changed. Usage: scripts/setup.sh [extra cmake -D options]
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(cmake g++ make pkg-config
          libeigen3-dev libceres-dev libfftw3-dev libopencv-dev libopenimageio-dev libcfitsio-dev
          nlohmann-json3-dev libcli11-dev libgtest-dev libgmock-dev
          # OpenImageIO's CMake config names its command-line tools as imported targets and fails
          # when they are absent, which --no-install-recommends leaves them.
          openimageio-tools)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}"
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

jobs=$(nproc 2>/dev/null || echo 2)
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release "$@"
cmake --build build -j"$jobs"
