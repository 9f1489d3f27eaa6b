"""Progress, cancellation and Ctrl-C of every long call (simulate, design, calibrate, tikhonov), aosr.methods()
from the library, and aosr.calibrate refusing to overwrite an input as `aosr calibrate` does."""
import json
import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import aosr

# A small calibration set (2 modes x 2 levels): seconds to fit, as in test_io_core.py.
SMALL_SET = {"telescope": "paper-bench", "calibration": {
    "pixel_lambda_over_d": 0.3115, "window_px": [32, 32], "modes": [4, 5], "gains": [0.9, 1.1],
    "amplitudes_nm": [40, 80], "references_per_mode": 1, "static_nm": {"4": 10}, "seed": 3}}


@pytest.fixture(scope="module")
def small_set(tmp_path_factory):
    d = tmp_path_factory.mktemp("calset")
    spec = d / "small.json"
    spec.write_text(json.dumps(SMALL_SET))
    aosr.synthesize_calibration(spec, output=d / "set")
    return d / "set"


def test_methods_come_from_the_library(demo_dir):
    methods = aosr.methods()
    assert methods[0] == "shift-add" and {"drizzle", "tikhonov", "linear", "tv", "map"} <= set(methods)
    # The list the library parses against: its error names exactly these.
    with pytest.raises(aosr.InvalidArgument) as e:
        aosr.reconstruct(demo_dir, "no-such-method")
    allowed = str(e.value).split("allowed: ")[1].split(" | ")
    assert [a.strip() for a in allowed] == methods


def test_simulate_progress_and_cancel(demo_scene_path):
    scene = aosr.load_scene(demo_scene_path)
    seen = []
    full = aosr.simulate(scene, progress=lambda p: seen.append(p) or True)
    assert {p["stage"] for p in seen} == {"simulate"}
    assert seen[-1]["iteration"] == seen[-1]["total"] > 4           # object, PSFs, convolution, pixels, detector
    assert np.array_equal(full.frames, aosr.simulate(scene).frames)  # a callback changes nothing
    assert aosr.simulate(scene, progress=lambda p: False) is None   # stops after the object

    def interrupt(p):
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        aosr.simulate(scene, progress=interrupt)


def test_tikhonov_progress_and_cancel(demo_dir):
    ds = aosr.open_dataset(demo_dir)
    seen = []
    # The CG path (taken for weighted or masked data and padded boundaries; forced here): one report per PCG
    # iteration (stage "tikhonov-cg").
    cg = {"tikhonov_method": "conjugate-gradient", "tikhonov_precondition": False}
    full = aosr.reconstruct(ds, "tikhonov", progress=lambda p: seen.append(p) or True, **cg)
    assert {p["stage"] for p in seen} == {"tikhonov-cg"} and seen[-1]["value_name"] == "residual"
    assert np.array_equal(full.image, aosr.reconstruct(ds, "tikhonov", **cg).image)   # a callback changes nothing
    cancelled = aosr.reconstruct(ds, "tikhonov", progress=lambda p: False, **cg)   # after the first PCG iteration
    assert cancelled.summary["termination"] == "cancelled" and np.isfinite(cancelled.image).all()
    assert cancelled.summary["iterations"] < full.summary["iterations"]
    # The demo's uniform weights: the direct Fourier solve, reported as one step.
    seen.clear()
    aosr.reconstruct(ds, "tikhonov", progress=lambda p: seen.append(p) or True)
    assert [(p["stage"], p["iteration"]) for p in seen] == [("tikhonov", 0), ("tikhonov", 1)]

    def interrupt(p):
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):   # posterior draws on the padded grid, each a PCG solve
        aosr.reconstruct(ds, "tikhonov", std=True, boundary="padded", lambda_=0.01, progress=interrupt)


def test_design_progress_and_cancel(tmp_path):
    scene = aosr.data_path("scenes", "paper-sim-r2.json")
    args = {"param": "tiptilt", "starts": 2, "iterations": 4, "realisations": 0, "validation_realisations": 0}
    seen = []
    full = aosr.design(scene, progress=lambda p: seen.append(p) or True, **args)
    assert {p["stage"] for p in seen} == {"design"} and seen[-1]["total"] == 8
    assert full["design"] == aosr.design(scene, **args)["design"]
    cut = aosr.design(scene, output=tmp_path / "d.json", progress=lambda p: p["iteration"] < 1, **args)
    assert cut["termination"] == "cancelled" and cut["output"] is None
    assert not (tmp_path / "d.json").exists()

    def interrupt(p):
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        aosr.design(scene, progress=interrupt, **args)


def test_calibrate_progress_and_cancel(small_set, tmp_path):
    seen = []
    full = aosr.calibrate(small_set, threads=1, static_max_noll=4, progress=lambda p: seen.append(p) or True)
    assert [(p["stage"], p["iteration"], p["total"]) for p in seen][-1] == ("calibrate", 2, 2)
    assert full == aosr.calibrate(small_set, threads=1, static_max_noll=4)
    assert aosr.calibrate(small_set, threads=1, output=tmp_path / "cal", progress=lambda p: False) is None
    assert not (tmp_path / "cal" / "calibration.json").exists()

    def interrupt(p):
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        aosr.calibrate(small_set, threads=2, progress=interrupt)


def test_calibrate_refuses_to_overwrite_an_input(small_set, tmp_path, cli):
    # A set whose manifest is named calibration.json: writing the calibration beside it would overwrite it.
    d = tmp_path / "set"
    d.mkdir()
    for name in os.listdir(small_set):
        src = small_set / name
        if src.is_dir():
            (d / name).symlink_to(src)
    manifest = (small_set / "calibration-set.json").read_text()
    (d / "calibration.json").write_text(manifest)
    with pytest.raises(aosr.InvalidArgument, match="never overwrites an input"):
        aosr.calibrate(d / "calibration.json", output=d)
    assert (d / "calibration.json").read_text() == manifest
    p = cli("calibrate", d / "calibration.json", "-o", d, check=False)   # the CLI refuses the same
    assert p.returncode == 1 and "never overwrites an input" in p.stderr
    # synthesize_calibration: the manifest written must not be the spec read.
    spec = tmp_path / "calibration-set.json"
    spec.write_text(json.dumps(SMALL_SET))
    with pytest.raises(aosr.InvalidArgument, match="never overwrites an input"):
        aosr.synthesize_calibration(spec, output=tmp_path)


def test_ctrl_c_reaches_every_long_call(demo_dir):
    """A real SIGINT during simulate, design, calibrate and Tikhonov (CG path with posterior draws): each raises
    KeyboardInterrupt within seconds (uninterrupted, each would run for minutes) and the library stays usable."""
    script = textwrap.dedent(f"""
        import sys, time, aosr
        ds = aosr.open_dataset({demo_dir!r})
        # 1 s of loop per sub-exposure (seconds of wall each): the run is checked after every sub-exposure.
        closed_loop = aosr.load_scene(aosr.data_path("scenes", "paper-sim-r2.json"), {{"ao.time_per_frame_s": 1.0}})
        bench_set = aosr.synthesize_calibration("paper-bench")   # 10 modes: checked after every mode
        calls = [
            ("simulate", lambda: aosr.simulate(closed_loop)),
            ("design", lambda: aosr.design(aosr.data_path("scenes", "paper-sim-r2.json"), param="zernike",
                                           starts=64, iterations=100000, realisations=0,
                                           validation_realisations=0)),
            ("calibrate", lambda: aosr.calibrate(bench_set, threads=1)),
            ("tikhonov", lambda: aosr.reconstruct(ds, "tikhonov", std=True, boundary="padded", lambda_=0.01,
                                                  tikhonov_std_samples=1000000)),
        ]
        for name, call in calls:
            print("start", name, flush=True)
            t = time.time()
            try:
                call()
                print("finished", name, flush=True)
            except KeyboardInterrupt:
                print("interrupted", name, "%.2f" % (time.time() - t), flush=True)
        print("ok", aosr.reconstruct(ds, "shift-add").summary["termination"], flush=True)
    """)
    p = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True, env=os.environ)
    try:
        for name in ("simulate", "design", "calibrate", "tikhonov"):
            assert p.stdout.readline().split() == ["start", name]
            # Long enough for the call to be inside the library with the GIL released.
            import time
            time.sleep(1.5)
            p.send_signal(signal.SIGINT)
            words = p.stdout.readline().split()
            assert words[:2] == ["interrupted", name], words
            assert float(words[2]) < 60, words   # each would run for minutes (a loaded machine is slow)
        assert p.stdout.readline().split() == ["ok", "converged"]
        assert p.wait(timeout=60) == 0
    finally:
        p.kill()
