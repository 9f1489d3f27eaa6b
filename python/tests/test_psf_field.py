"""A PSF that varies over the field from Python (issue 31): a scene's psf_field simulates the field's PSFs
(Dataset.psf_field), and aosr.reconstruct(..., psf_field=) uses them by tiles or as one space-variant operator,
with the same bits as `aosr reconstruct --psf-field`; aosr.write_figure draws line plots without matplotlib."""
import json

import numpy as np
import pytest

import aosr


def field_scene(frame_px=48, guide_star=(-45.0, 0.0)):
    return {"name": "py-field", "telescope": "paper-8m", "frames": 4, "r": 2, "seed": 5,
            "ao": {"mode": "analytic"}, "offsets": {"type": "raster"},
            "psf_field": {"guide_star_arcsec": list(guide_star), "grid": 2},
            "detector": {"frame_px": frame_px, "noise": "peak-fraction", "peak_noise_fraction": 0.0005,
                         "saturation": False},
            "objects": [{"type": "stars", "count": 25, "flux_range_e": [2e4, 2e5], "margin_px": 5.0}]}


@pytest.fixture(scope="module")
def field_dataset():
    return aosr.simulate(aosr.Scene(field_scene()))


def test_dataset_carries_the_field(field_dataset):
    f = field_dataset.psf_field
    assert f["grid"] == (2, 2)
    assert f["psfs"].shape == (4, 4) + field_dataset.psfs.shape[1:]
    assert np.allclose(f["psfs"].sum(axis=(2, 3)), 1.0)
    assert f["nodes_hr_px"][3] == (95.0, 95.0)
    assert f["guide_star_arcsec"] == (-45.0, 0.0)
    assert f["nominal_psfs"] is None
    # Far from the guide star every node's PSF is broader than the guide star's own (dataset.psfs).
    assert f["psfs"][:, 0].max(axis=(1, 2)).max() < field_dataset.psfs[0].max()


def test_field_models_beat_the_guide_stars_psf(field_dataset):
    truth = field_dataset.truth
    scores = {}
    for pf in ("none", "tiles", "operator"):
        rec = aosr.reconstruct(field_dataset, "tikhonov", psf_field=pf)
        assert rec.psf_field == pf
        assert np.isfinite(rec.image).all()
        scores[pf] = aosr.compare_images_aligned(truth, rec.image, crop=16)["aligned"]["psnr_db"]
    assert aosr.reconstruct(field_dataset, "tikhonov").psf_field == "tiles"  # auto
    assert scores["tiles"] > scores["none"] + 1.0, scores
    assert abs(scores["tiles"] - scores["operator"]) < 0.5, scores


def test_the_memory_plan_names_the_window_a_field_model_uses():
    # Under a memory limit a field model's λ is chosen on the memory plan's window, at most 256 camera px
    # (psf_field_model.hpp, kFieldRegularisationWindow); the plan reports the window used. The whole grid
    # (36 MB) does not fit in 14 MiB, and neither do the field's own tiles (80 camera px, half the node spacing):
    # the tiles are the memory plan's (FitDatasetTilingToMemory).
    ds = aosr.simulate(aosr.Scene(field_scene(frame_px=160)))
    rec = aosr.reconstruct(ds, "tikhonov", memory_limit="14M")
    plan = rec.memory_plan
    assert plan["whole_grid_bytes"] > 14 * 2**20
    assert 16 <= plan["tile"] < 80, plan
    w = plan["regularisation_window"]
    assert 0 < w < 160
    assert f"central {w} x {w} camera px" in rec.summary["message"], rec.summary["message"]
    assert f"tiles of <= {plan['tile']} camera px" in rec.summary["message"], rec.summary["message"]
    # Where not even the smallest tile fits, the limit is refused by name (the field's tiles used to run past it).
    with pytest.raises(aosr.ResourceError, match="more than the limit of 2 MiB"):
        aosr.reconstruct(ds, "tikhonov", memory_limit="2M")


def test_same_bits_as_the_cli(field_dataset, cli, tmp_path):
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(field_scene()))
    cli("simulate", scene, "-o", tmp_path / "data")
    out = tmp_path / "t.fits"
    p = cli("reconstruct", tmp_path / "data", "-m", "tikhonov", "--psf-field", "operator", "-o", out, "--json")
    assert json.loads(p.stdout)["psf_field"]["model"] == "operator"
    rec = aosr.reconstruct(tmp_path / "data", "tikhonov", psf_field="operator")
    image, header = aosr.read_fits(out)
    assert header["PSFFIELD"] == "operator 2x2"
    assert np.array_equal(image.astype(np.float32), rec.image.astype(np.float32))


def test_bad_requests(field_dataset, demo_dir):
    with pytest.raises(ValueError, match="auto | none | tiles | operator"):
        aosr.reconstruct(field_dataset, "tikhonov", psf_field="grid")
    with pytest.raises(ValueError, match="a method that models the PSF"):
        aosr.reconstruct(field_dataset, "drizzle", psf_field="tiles")
    with pytest.raises(ValueError, match="per-frequency design"):
        aosr.reconstruct(field_dataset, "linear", psf_field="operator")
    with pytest.raises(ValueError, match="a dataset with a psf_field"):
        aosr.reconstruct(demo_dir, "tikhonov", psf_field="tiles")


def test_write_figure(tmp_path):
    path = tmp_path / "f.png"
    aosr.write_figure(path, [{"title": "t", "x": {"label": "x"}, "y": {"label": "y", "log": True},
                              "series": [{"label": "a", "x": [1, 2, 3], "y": [1, 10, 100]}]}], columns=1)
    assert path.stat().st_size > 1000
    with pytest.raises(ValueError, match="panels\\[0\\].colour"):
        aosr.write_figure(path, [{"colour": "red"}])
    with pytest.raises(ValueError, match="log"):
        aosr.write_figure(path, [{"y": {"log": True}, "series": [{"x": [1], "y": [-1]}]}])
    aosr.write_figure(path, [{"series": [{"x": [1, 2], "y": [3, 4], "point_labels": ["a", ""]}]}])
    with pytest.raises(ValueError, match="point_labels"):
        aosr.write_figure(path, [{"series": [{"x": [1, 2], "y": [3, 4], "point_labels": ["a"]}]}])
