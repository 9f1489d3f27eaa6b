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
          openimageio-tools
          # the WCS check of tests/cli/wcs_astropy_check.py reads aosr's FITS files with astropy (wcslib)
          python3-astropy python3-numpy)
# The Python package (python/, `import aosr`): pybind11 bindings built for Debian's /usr/bin/python3, numpy and
# astropy for users and tests, Dask's distributed scheduler for aosr.distributed, pytest for the python tests.
packages+=(pybind11-dev python3-dev python3-numpy python3-astropy python3-dask python3-distributed python3-pytest)
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

# `import aosr` for /usr/bin/python3: a .pth file in its user site-packages naming build/python, where the build
# assembles the extension module and the package's .py files (python/CMakeLists.txt). Rewritten on every run:
# the checkout set up last is the one Python imports.
if [ -d build/python/aosr ]; then
  site=$(/usr/bin/python3 -m site --user-site)
  mkdir -p "$site"
  echo "$PWD/build/python" > "$site/aosr.pth"
  echo "setup: /usr/bin/python3 imports aosr from $PWD/build/python (via $site/aosr.pth)"
fi
