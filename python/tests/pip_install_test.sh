#!/usr/bin/env bash
# `pip install .` of this checkout, the way README.md ("Python") tells users to do it, checked end to end:
#   1. into a fresh virtualenv made with /usr/bin/python3 -m venv --system-site-packages;
#   2. into a user site (pip install --user --break-system-packages; PYTHONUSERBASE points at a temporary folder
#      so the real ~/.local is not touched);
# each with --no-build-isolation --no-index (Debian's setuptools, wheel and numpy; nothing is downloaded), reusing
# the CMake build folder BUILD (AOSR_CMAKE_BUILD_DIR: an up-to-date build is not recompiled, but the wheel is
# really built and installed by pip). Then, from a temporary folder outside the checkout, with the installed
# package only (no PYTHONPATH, no user site for the venv): the README's Python example and the `aosr` command
# (--version and a real command) for both, and the I/O and scene python tests against that command in the venv.
# Usage: python/tests/pip_install_test.sh SOURCE_DIR BUILD_DIR [pytest args...]   (ctest: python_pip_install)
set -euo pipefail
# Skipped (77) without Debian's python3-pip, python3-venv, python3-setuptools or python3-wheel (scripts/setup.sh
# installs them).
{ /usr/bin/python3 -c "import setuptools, wheel, ensurepip" && /usr/bin/python3 -m pip --version; } >/dev/null 2>&1 || {
  echo "pip_install_test: skipped: python3-pip, python3-venv, python3-setuptools or python3-wheel missing"; exit 77; }
src=$(cd "$1" && pwd)
build=$(cd "$2" && pwd)
shift 2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export PIP_DISABLE_PIP_VERSION_CHECK=1 PIP_NO_CACHE_DIR=1 PIP_ROOT_USER_ACTION=ignore PYTHONDONTWRITEBYTECODE=1 AOSR_CMAKE_BUILD_DIR="$build"
unset PYTHONPATH AOSR_DATA_DIR AOSR_CLI

# The README's Python example, as written there (the ```python block of the "Python" section).
example="$tmp/readme_example.py"
awk '/^## Python/{p=1} p&&/^```python/{c=1;next} c&&/^```/{exit} c{print}' "$src/README.md" > "$example"
grep -q "aosr.reconstruct" "$example" || { echo "pip_install_test: no Python example found in README.md" >&2; exit 1; }

check() {  # check PYTHON AOSR_COMMAND WHERE [pytest args]: the installed package and command, outside the checkout
  local py=$1 cmd=$2 where=$3
  shift 3
  mkdir -p "$tmp/run-$where" && cd "$tmp/run-$where"
  "$py" -c "import aosr, os, sys; f = aosr.__file__; print('aosr', aosr.__version__, 'from', f)
assert f.startswith('$tmp'), 'imported from outside the install: ' + f
assert os.path.exists(aosr.data_path('telescopes', 'paper-8m.json')), aosr.data_path()
assert aosr.data_path().startswith('$tmp'), aosr.data_path()"
  "$cmd" --version
  "$cmd" psf paper-8m --mode diffraction --size 32 --json > psf.json   # a preset by name: the installed data
  # PNG output through the installed OpenImageIO plugin (libexec/aosr/libaosr_oiio.so), not the build tree's.
  LD_DEBUG=files "$cmd" demo -o demo > /dev/null 2> ld.log
  test -s demo/montage.png
  grep -q "file=$tmp/[^ ]*/libaosr_oiio.so" ld.log || { echo "pip_install_test: plugin not loaded from $tmp" >&2; exit 1; }
  "$py" "$example" | tee example.out
  grep -q "^tv: converged after .* PSNR .* dB, SSIM" example.out
  # The venv also runs the I/O and scene tests (data files, presets, the command, FITS and WCS through the
  # installed package); the solver tests are the same compiled code python_bindings already runs.
  [ "$where" = venv ] || return 0
  AOSR_CLI="$cmd" AOSR_REFERENCE="$build/python/aosr_py_reference" AOSR_SOURCE_DIR="$src" \
    AOSR_EXPECT_INSTALLED_UNDER="$tmp" "$py" -m pytest -q -p no:cacheprovider "$@" \
    "$src/python/tests/test_io_core.py" "$src/python/tests/test_scene.py"
}

echo "== pip install into a fresh virtualenv (--system-site-packages)"
/usr/bin/python3 -m venv --system-site-packages "$tmp/venv"
(cd "$src" && "$tmp/venv/bin/python" -m pip install -q --no-build-isolation --no-index .)
PYTHONNOUSERSITE=1 check "$tmp/venv/bin/python" "$tmp/venv/bin/aosr" venv "$@"

echo "== pip install --user (PYTHONUSERBASE=$tmp/user)"
export PYTHONUSERBASE="$tmp/user"
# Debian 12 marks /usr/bin/python3 externally managed (PEP 668): pip refuses --user installs without
# --break-system-packages, although a user install writes only below PYTHONUSERBASE (~/.local), never /usr.
(cd "$src" && /usr/bin/python3 -m pip install -q --user --no-build-isolation --no-index --break-system-packages .)
check /usr/bin/python3 "$tmp/user/bin/aosr" user "$@"
echo "pip_install_test: ok"
