"""Scenes, simulate() and datasets against `aosr simulate` (bit for bit), and their errors."""
import json
import os
import pickle

import numpy as np
import pytest

import aosr
from conftest import bits_equal


def read(path):
    return aosr.read_fits(path)[0]


def test_simulate_matches_the_cli_files(demo_scene_path, demo_dir):
    ds = aosr.simulate(aosr.load_scene(demo_scene_path))
    assert bits_equal(ds.frames, read(os.path.join(demo_dir, "frames.fits")))
    assert bits_equal(ds.weights, read(os.path.join(demo_dir, "weights.fits")))
    assert bits_equal(ds.truth, read(os.path.join(demo_dir, "truth.fits")))
    on_disk = aosr.open_dataset(demo_dir)
    for name in ("frames", "valid", "weights", "psfs", "truth", "stars"):
        assert bits_equal(getattr(ds, name), getattr(on_disk, name)), name
    assert ds.offsets == on_disk.offsets
    assert ds.masks is ds.valid and ds.shifts.shape == (4, 2)
    assert [list(x) for x in ds.shifts] == [o["shift_px"] for o in ds.offsets]
    assert (ds.r, ds.gain, ds.bias, ds.trustworthy_border_px) == (on_disk.r, on_disk.gain, on_disk.bias,
                                                                   on_disk.trustworthy_border_px)
    assert ds.has_wcs and on_disk.has_wcs and ds.hr_header() == on_disk.hr_header()
    assert "CD1_1" in ds.hr_header() and ds.hr_header()["BUNIT"] == "electron"
    # In memory and on disk reconstruct to the same bits.
    for method in ("drizzle", "tikhonov"):
        assert bits_equal(aosr.reconstruct(ds, method).image, aosr.reconstruct(on_disk, method).image)


def test_seed_and_overrides_match_cli_set(demo_scene_path, cli, tmp_path):
    out = tmp_path / "s5"
    cli("simulate", demo_scene_path, "-o", out, "--set", "seed=5", "--set", "detector.peak_noise_fraction=0.02", "--json")
    scene = aosr.load_scene(demo_scene_path, {"detector.peak_noise_fraction": 0.02})
    ds = aosr.simulate(scene, seed=5)
    assert bits_equal(ds.frames, read(out / "frames.fits"))
    assert not bits_equal(ds.frames, aosr.simulate(scene, seed=6).frames)
    assert bits_equal(ds.frames, aosr.simulate(scene, seed=5).frames)  # same seed, same bytes


def test_simulate_output_writes_the_cli_dataset(demo_scene_path, demo_dir, tmp_path):
    ds = aosr.simulate(aosr.load_scene(demo_scene_path), output=tmp_path / "py")
    for name in ("frames.fits", "valid.fits", "weights.fits", "psfs.fits", "truth.fits", "expected.fits"):
        assert bits_equal(read(tmp_path / "py" / name), read(os.path.join(demo_dir, name))), name
    assert bits_equal(aosr.open_dataset(tmp_path / "py").frames, ds.frames)


def test_scene_from_dict(demo_scene_path):
    j = aosr.read_json(demo_scene_path)
    # A dict scene resolves relative paths against the current folder: run from the scene's.
    cwd = os.getcwd()
    os.chdir(os.path.dirname(demo_scene_path))
    try:
        s = aosr.scene_from_dict(j, overrides={"r": 2})
    finally:
        os.chdir(cwd)
    assert (s.frames, s.r, s.frame_shape) == (4, 2, (128, 128))
    assert "psf" in s.plan()


def test_sky_oversampling_renders_a_finer_sky_on_the_same_outputs(demo_scene_path, cli, tmp_path):
    # The scene field is reachable from a dict and from `aosr simulate --set`; the outputs stay on the HR grid,
    # USAF's exact-area truth is the same, and the frames are not (the sky between HR samples now counts).
    j = aosr.read_json(demo_scene_path)
    j["detector"]["peak_noise_fraction"] = 0.0
    j["detector"]["frame_px"] = 32
    j["objects"] = [{"type": "usaf", "flux": {"peak_e": 1000}}]
    one = aosr.simulate(aosr.scene_from_dict(j, source=demo_scene_path))
    j["sky_oversampling"] = 2
    scene = aosr.scene_from_dict(j, source=demo_scene_path)
    assert scene.sky_oversampling == 2 and "sky_oversampling 2" in scene.plan()
    two = aosr.simulate(scene)
    assert two.truth.shape == one.truth.shape and two.psfs.shape == one.psfs.shape
    assert np.abs(two.truth - one.truth).max() <= 1e-9 * one.truth.max()
    assert np.abs(two.frames - one.frames).max() > 1e-6 * one.frames.max()
    # The same light, up to what leaves the frame's edge (the target fills it): measured 6e-6.
    assert abs(two.frames.sum() - one.frames.sum()) <= 1e-4 * one.frames.sum()
    path = tmp_path / "fine.json"
    path.write_text(json.dumps(j))
    out = cli("simulate", path, "-o", tmp_path / "fine", "--json")
    assert json.loads(out.stdout)["sky_oversampling"] == 2
    assert bits_equal(read(tmp_path / "fine" / "frames.fits"), two.frames)
    with pytest.raises(aosr.InvalidArgument, match="sky_oversampling"):
        aosr.scene_from_dict(dict(j, sky_oversampling=0), source=demo_scene_path)


def test_dataset_from_arrays_and_pickle(demo_dir):
    ds = aosr.open_dataset(demo_dir)
    mine = aosr.Dataset.from_arrays(ds.frames, ds.psfs[0], r=2, gain=ds.gain, bias=ds.bias, weights=ds.weights,
                                    truth=ds.truth, offsets=[(0.0, 0.0)] * len(ds))
    assert len(mine) == 4 and mine.psfs.shape == (4,) + ds.psfs.shape[1:]
    assert abs(mine.psfs.sum(axis=(1, 2)) - 1).max() < 1e-12
    back = pickle.loads(pickle.dumps(ds))
    assert back.hr_header() == ds.hr_header()
    for name in ("frames", "valid", "weights", "psfs", "truth"):
        assert bits_equal(getattr(back, name), getattr(ds, name))
    assert bits_equal(aosr.reconstruct(back, "tv", iterations=5).image, aosr.reconstruct(ds, "tv", iterations=5).image)


@pytest.mark.parametrize("kwargs,needle", [
    ({"r": 0}, "r = 0"),
    ({"r": 2, "psfs": np.ones((3, 8, 8))}, "psfs"),
    ({"r": 2, "psfs": np.ones((7, 7))}, "K even"),
    ({"r": 2, "valid": np.full((4, 128, 128), 0.5)}, "valid"),
    ({"r": 2, "truth": np.ones((10, 10))}, "truth"),
])
def test_dataset_from_arrays_errors(demo_dir, kwargs, needle):
    ds = aosr.open_dataset(demo_dir)
    args = {"psfs": ds.psfs}
    args.update(kwargs)
    psfs = args.pop("psfs")
    with pytest.raises(aosr.InvalidArgument, match=needle):
        aosr.Dataset.from_arrays(ds.frames, psfs, **args)


def test_scene_errors_carry_the_cli_message(demo_scene_path, cli, tmp_path):
    p = cli("simulate", demo_scene_path, "--set", "r=99", "--plan", check=False)
    assert p.returncode != 0
    with pytest.raises(aosr.InvalidArgument) as e:
        aosr.load_scene(demo_scene_path, {"r": 99})
    assert str(e.value) in p.stderr + p.stdout
    with pytest.raises(aosr.IoError) as e:
        aosr.load_scene(tmp_path / "missing.json")
    assert isinstance(e.value, OSError) and "missing.json" in str(e.value)
    with pytest.raises(aosr.IoError):
        aosr.open_dataset(tmp_path)
    with pytest.raises(aosr.InvalidArgument, match="override"):
        aosr.load_scene(demo_scene_path, {"objects.x.flux": 1})


def test_dm_gain_is_a_closed_loop_scene_option(demo_scene_path):
    # ao.dm_gain (a DM stroke calibration error of the simulated hardware) reaches Python through the scene, as
    # `aosr simulate --set ao.dm_gain=1.1` does; out of range it is the parser's InvalidArgument naming the field.
    path = os.path.join(os.path.dirname(demo_scene_path), "paper-sim-r2.json")
    s = aosr.load_scene(path, {"ao.dm_gain": 1.1})
    assert "ao-loop" in s.plan()
    with pytest.raises(aosr.InvalidArgument, match=r"ao\.dm_gain = 3; allowed: a number in \[0\.5, 2\]"):
        aosr.load_scene(path, {"ao.dm_gain": 3})


def test_offset_calibration_and_antithetic_are_closed_loop_scene_options(demo_scene_path):
    # ao.offset_calibration and ao.antithetic (include/aosr/scene/scene_spec.hpp) reach Python through the scene,
    # as `aosr simulate --set ao.antithetic=false` does: the plan runs the loop twice by default (the antithetic
    # pair) and once without it; a bad value is the parser's InvalidArgument naming the field.
    path = os.path.join(os.path.dirname(demo_scene_path), "paper-sim-r2.json")
    assert "antithetic pair" in aosr.load_scene(path).plan()
    assert "antithetic pair" not in aosr.load_scene(path, {"ao.antithetic": False}).plan()
    assert "ao-loop" in aosr.load_scene(path, {"ao.offset_calibration": "flat"}).plan()
    with pytest.raises(aosr.InvalidArgument, match=r"ao\.offset_calibration = \"probe\"; allowed: one of on-sky, flat"):
        aosr.load_scene(path, {"ao.offset_calibration": "probe"})
