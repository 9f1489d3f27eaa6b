#!/usr/bin/env bash
# Installs aosr's build dependencies from Debian 12 packages (only those missing), then configures ./build
# (Release) and builds what the main job and `import aosr` need: the libraries, the `aosr` command and the Python
# module. With --tests it also builds the test suites, the fuzz targets and the benchmarks (target aosr_dev), as
# the README's command 2 does. Idempotent: a second run installs nothing and rebuilds only what changed.
# Usage: scripts/setup.sh [--tests] [extra cmake -D options]
# (-DAOSR_BUILD_EVERYTHING=ON makes the default target build everything, for a developer's plain `cmake --build`.)
set -euo pipefail
cd "$(dirname "$0")/.."
targets=(all)
if [ "${1:-}" = "--tests" ]; then
  targets+=(aosr_dev)
  shift
fi

# Command 1 (the libraries, the `aosr` command, the Python module and its pip install): only what those need, so
# that a first set-up installs no more than it uses (bench/results/build.md, "A clean clone").
packages=(cmake g++ make pkg-config
          # The compiler of a new build folder: clang 14 compiles aosr in about three quarters of GCC 12's CPU time
          # with the same flags, and the binaries run as fast (bench/results/build.md, "Stop 60"). CXX=g++ (or any
          # -DCMAKE_CXX_COMPILER=) chooses another; an existing build folder keeps the compiler it has.
          clang-14
          # ninja schedules the build with less overhead than make, mold links in a fraction of GNU ld's time, and
          # ccache skips files compiled before with the same flags (cmake/BuildSpeed.cmake, bench/results/build.md)
          ninja-build mold ccache
          libeigen3-dev libceres-dev libfftw3-dev libopenimageio-dev libcfitsio-dev nlohmann-json3-dev libcli11-dev
          # OpenCV's three modules that aosr links, not libopencv-dev and its every module (Qt, VTK, GDAL, MPI:
          # 118 packages more; cmake/OpenCVModules.cmake finds the modules without OpenCV's CMake config).
          libopencv-core-dev libopencv-imgproc-dev libopencv-videoio-dev
          # CMake configures the test targets (built only with --tests) and needs GoogleTest's config for that.
          libgtest-dev libgmock-dev
          # The Python package (python/, `import aosr`): pybind11 bindings built for Debian's /usr/bin/python3,
          # numpy, and `pip install .` (pyproject.toml, setup.py) with Debian's pip, setuptools and wheel.
          pybind11-dev python3-dev python3-numpy python3-pip python3-setuptools python3-wheel)
if ((${#targets[@]} > 1)); then
  # --tests (command 2) adds what the tests and the optional parts use: astropy reads aosr's FITS WCS in the
  # checks (tests/cli/wcs_astropy_check.py), Dask's distributed scheduler runs aosr.distributed, pytest the Python
  # tests, python3-venv the pip-install test's virtualenv, OpenCV's superres module the BTV-L1 comparison of
  # bench/reconstruct_bench.
  packages+=(python3-astropy python3-dask python3-distributed python3-pytest python3-venv libopencv-superres-dev)
fi
scripts/install_packages.sh "${packages[@]}"

jobs=$(nproc 2>/dev/null || echo 2)
generator=()
# Ninja for a new build folder (an existing one keeps the generator it was configured with).
if [ ! -f build/CMakeCache.txt ] && command -v ninja > /dev/null; then generator=(-G Ninja); fi
compiler=()
if [ ! -f build/CMakeCache.txt ] && [ -z "${CXX:-}" ] && [[ " $* " != *" -DCMAKE_CXX_COMPILER="* ]] &&
   command -v clang++-14 > /dev/null; then
  compiler=(-DCMAKE_CXX_COMPILER=clang++-14)
fi
cmake -S . -B build "${generator[@]}" "${compiler[@]}" -DCMAKE_BUILD_TYPE=Release "$@"
cmake --build build -j"$jobs" --target "${targets[@]}"

# `import aosr` and the `aosr` command for /usr/bin/python3's user: the package pip-installed into the user site
# (~/.local; README.md, "Python"), from this build folder (nothing is recompiled or downloaded). Debian 12 marks
# /usr/bin/python3 externally managed (PEP 668), so pip wants --break-system-packages even for a --user install,
# which writes only below ~/.local. AOSR_SETUP_PIP=0 skips this step. An aosr.pth that an earlier version of this
# script wrote (it pointed the user site at build/python) is removed: one route, not two that shadow each other.
site=$(/usr/bin/python3 -m site --user-site)
if [ -f "$site/aosr.pth" ]; then
  rm -f "$site/aosr.pth"
  echo "setup: removed $site/aosr.pth (replaced by pip install --user)"
fi
if [ "${AOSR_SETUP_PIP:-1}" != 0 ] && [ -d build/python/aosr ]; then
  AOSR_CMAKE_BUILD_DIR="$PWD/build" PIP_DISABLE_PIP_VERSION_CHECK=1 /usr/bin/python3 -m pip install -q --user \
    --no-build-isolation --no-index --break-system-packages .
  echo "setup: /usr/bin/python3 imports aosr from $site (pip install --user); the command: $(/usr/bin/python3 -m site --user-base)/bin/aosr"
fi
