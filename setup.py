"""Builds the aosr Python package with this checkout's CMake project, for `pip install .` (pyproject.toml).

One CMake build makes the extension module (aosr._aosr) and the command line (the `aosr` launcher and the
aosr-engine program it runs, src/cli/launcher/launcher.cpp); this script copies them into the wheel:

    aosr/                       the package: python/aosr/*.py, *.pyi, py.typed, _aosr*.so, libaosr_oiio.so (PNG/TIFF
                                I/O, loaded on first use) and data/ (scenes, telescope presets, calibration specs:
                                what aosr.data_path() and presets by name use)
    <prefix>/bin/aosr           the command (a venv's bin/, or ~/.local/bin with --user)
    <prefix>/libexec/aosr/aosr-engine, libaosr_oiio.so
    <prefix>/share/aosr/data/   the data folder again, for the command (the launcher sets AOSR_DATA_DIR to it)

The CMake build folder is $AOSR_CMAKE_BUILD_DIR if set (e.g. the checkout's ./build that scripts/setup.sh made:
then only what is out of date is rebuilt, nothing if it is current), else ./build-pip, configured Release without
tests, benchmarks and fuzz targets. Nothing is downloaded: the compilers and libraries are Debian's, and with
--no-build-isolation pip uses the installed setuptools and wheel.
"""
import glob
import os
import re
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = os.path.dirname(os.path.abspath(__file__))


def project_version():
    with open(os.path.join(ROOT, "CMakeLists.txt"), encoding="utf-8") as f:
        m = re.search(r"project\(aosr\s+VERSION\s+([0-9.]+)", f.read())
    if not m:
        raise RuntimeError("setup.py: no `project(aosr VERSION x.y.z)` in CMakeLists.txt")
    return m.group(1)


def cmake_build_dir():
    return os.path.abspath(os.environ.get("AOSR_CMAKE_BUILD_DIR") or os.path.join(ROOT, "build-pip"))


BUILD = cmake_build_dir()
STAGING = os.path.join(os.path.relpath(BUILD, ROOT), "setuptools")
os.makedirs(os.path.join(ROOT, STAGING), exist_ok=True)


class CMakeBuild(build_ext):
    """Runs the CMake build (configure once, then an incremental build of the module and the command line)."""

    def run(self):
        if not os.path.exists(os.path.join(BUILD, "CMakeCache.txt")):
            # The compiler scripts/setup.sh chooses: clang 14 when it is installed and CXX does not name another.
            compiler = ([] if os.environ.get("CXX") or not shutil.which("clang++-14")
                        else ["-DCMAKE_CXX_COMPILER=clang++-14"])
            self.spawn(["cmake", "-S", ROOT, "-B", BUILD, "-DCMAKE_BUILD_TYPE=Release", *compiler,
                        "-DAOSR_BUILD_TESTS=OFF", "-DAOSR_BUILD_BENCH=OFF", "-DAOSR_BUILD_FUZZ=OFF",
                        "-DAOSR_BUILD_PYTHON=ON", f"-DPython3_EXECUTABLE={sys.executable}"])
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL") or str(min(os.cpu_count() or 1, 2))
        self.spawn(["cmake", "--build", BUILD, "--target", "aosr_python", "aosr_cli", "aosr_oiio", "-j", jobs])
        built = glob.glob(os.path.join(BUILD, "python", "aosr", "_aosr*.so"))
        if len(built) != 1:
            raise RuntimeError(f"setup.py: expected one extension module in {BUILD}/python/aosr, found {built} "
                               "(is pybind11-dev installed? the CMake log says)")
        for ext in self.extensions:
            target = self.get_ext_fullpath(ext.name)
            os.makedirs(os.path.dirname(target), exist_ok=True)
            shutil.copy2(built[0], target)
            # PNG/TIFF I/O (OpenImageIO), loaded by the module on first use from its own folder
            # (src/io/oiio_plugin/oiio_plugin.hpp).
            shutil.copy2(os.path.join(BUILD, "libaosr_oiio.so"), os.path.dirname(target))
        # The package's data/ (build_py has run: build_lib holds the .py files).
        data = os.path.join(self.build_lib, "aosr", "data")
        shutil.rmtree(data, ignore_errors=True)
        shutil.copytree(os.path.join(ROOT, "data"), data)


def data_files():
    """The command line and the data folder, installed under the prefix (venv, ~/.local, /usr/local). setuptools
    wants these paths relative to setup.py's folder."""
    build = os.path.relpath(BUILD, ROOT)
    files = [("bin", [os.path.join(build, "aosr")]),
             ("libexec/aosr", [os.path.join(build, "libexec", "aosr", "aosr-engine"),
                               os.path.join(build, "libaosr_oiio.so")])]
    for dirpath, _, names in sorted(os.walk(os.path.join(ROOT, "data"))):
        rel = os.path.relpath(dirpath, ROOT)
        files.append((os.path.join("share", "aosr", rel), sorted(os.path.join(rel, n) for n in names)))
    return files


setup(
    version=project_version(),
    packages=["aosr"],
    package_dir={"aosr": "python/aosr"},
    package_data={"aosr": ["*.pyi", "py.typed"]},
    # Built by CMake (CMakeBuild); the empty source list only tells setuptools the wheel is platform-specific.
    ext_modules=[Extension("aosr._aosr", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    data_files=data_files(),
    zip_safe=False,
    # setuptools' own staging folders (and the .egg-info it keeps between runs) go into the CMake build folder,
    # not into the checkout.
    options={"build": {"build_base": STAGING}, "egg_info": {"egg_base": STAGING}},
)
