"""Shared fixtures of the aosr Python tests (run by ctest as python_bindings / python_distributed, which set
PYTHONPATH to <build>/python and AOSR_CLI / AOSR_REFERENCE to the C++ executables the results are compared with)."""
import json
import os
import shutil
import subprocess

import pytest

import aosr

# python/tests/pip_install_test.sh runs these tests against a pip-installed package: make sure that is the one.
if os.environ.get("AOSR_EXPECT_INSTALLED_UNDER"):
    assert aosr.__file__.startswith(os.environ["AOSR_EXPECT_INSTALLED_UNDER"]), aosr.__file__

SOURCE_DIR = os.environ.get("AOSR_SOURCE_DIR", os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..")))


def _executable(var, fallback):
    path = os.environ.get(var) or os.path.join(SOURCE_DIR, "build", fallback)
    if not os.path.exists(path):
        pytest.skip(f"{var} not set and {path} missing")
    return path


@pytest.fixture(scope="session")
def cli():
    """Runs `aosr ARGS...`; returns (returncode, stdout, stderr)."""
    exe = _executable("AOSR_CLI", "aosr")

    def run(*args, check=True):
        p = subprocess.run([exe, *map(str, args)], capture_output=True, text=True)
        if check and p.returncode != 0:
            raise AssertionError(f"aosr {' '.join(map(str, args))} failed:\n{p.stdout}\n{p.stderr}")
        return p
    return run


@pytest.fixture(scope="session")
def reference():
    """Runs the C++ reference (python/tests/aosr_py_reference.cpp) and returns its JSON line."""
    exe = _executable("AOSR_REFERENCE", "python/aosr_py_reference")

    def run(*args):
        p = subprocess.run([exe, *map(str, args)], capture_output=True, text=True)
        assert p.returncode == 0, p.stderr
        return json.loads(p.stdout)
    return run


@pytest.fixture(scope="session")
def demo_scene_path():
    return os.path.join(SOURCE_DIR, "data", "scenes", "demo.json")


@pytest.fixture(scope="session")
def demo_dir(tmp_path_factory, cli, demo_scene_path):
    """The demo scene simulated by the CLI (frames 128x128, N = 4, r = 2)."""
    out = tmp_path_factory.mktemp("demo") / "sim"
    cli("simulate", demo_scene_path, "-o", out, "--json")
    return str(out)


def bits_equal(a, b):
    """True when two float64 arrays hold the same bits (NaN payloads and signed zeros included)."""
    import numpy as np
    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))
