"""Scores across the field: aosr.compare_images_rings (core/metrics.hpp CompareImagesInRings) and
aosr.evaluate(rings=...) against `aosr evaluate --rings --json`; aligned scores never below raw."""
import json

import numpy as np
import pytest

import aosr


def _smooth(shape, seed):
    """A band-limited periodic image (sinusoids up to a quarter of the sampling rate)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:shape[0], 0:shape[1]]
    return 2.0 + sum(rng.uniform(0.1, 1) / (1 + i) * np.cos(2 * np.pi * (rng.integers(-shape[0] // 4, shape[0] // 4 + 1) * y / shape[0]
                                                                        + rng.integers(-shape[1] // 4, shape[1] // 4 + 1) * x / shape[1])
                                                           + rng.uniform(0, 2 * np.pi)) for i in range(40))


def test_noise_only_in_the_outer_ring_shows_only_there():
    truth = _smooth((128, 128), 1)
    y, x = np.mgrid[0:128, 0:128]
    rho = np.hypot(y - 63.5, x - 63.5)
    r3 = 0.75 * np.hypot(63.5, 63.5)
    noise = np.where(rho >= r3, np.random.default_rng(2).normal(0, 0.05, truth.shape), 0.0)
    m = aosr.compare_images_rings(truth, truth + noise, rings=4)
    assert m["centre"] == (63.5, 63.5) and m["peak"] == truth.max() - truth.min()
    rings = m["rings"]
    assert len(rings) == 4 and abs(rings[3]["inner_px"] - r3) < 1e-9
    assert sum(r["pixels"] for r in rings) == 128 * 128
    assert sum(r["ssim_positions"] for r in rings) == 118 * 118
    for r in rings[:3]:
        assert np.isinf(r["psnr_db"]) and np.isinf(r["aligned"]["psnr_db"])
        assert r["offset_px"] == {"dy": 0.0, "dx": 0.0}
    outer = rho >= r3
    expected = 10 * np.log10(m["peak"] ** 2 / np.mean(noise[outer] ** 2))
    assert rings[3]["pixels"] == int(outer.sum())
    assert abs(rings[3]["psnr_db"] - expected) < 1e-9
    assert rings[3]["aligned"]["psnr_db"] >= rings[3]["psnr_db"]
    assert rings[3]["ssim"] < 0.999 and abs(rings[0]["ssim"] - 1) < 1e-12  # outer ring measured 0.9952


def test_each_ring_is_aligned_on_its_own_and_never_below_raw():
    truth = _smooth((128, 128), 3)
    moved = aosr.fourier_shift(truth, 0.3, -0.2)
    y, x = np.mgrid[0:128, 0:128]
    w = np.hypot(63.5, 63.5) / 4
    t = np.clip((np.hypot(y - 63.5, x - 63.5) - 1.5 * w) / (0.5 * w), 0, 1)
    estimate = (1 - t) * truth + t * moved
    m = aosr.compare_images_rings(truth, estimate, rings=4)
    for r in m["rings"][2:]:
        assert r["offset_applied"]
        assert abs(r["offset_px"]["dy"] - 0.3) < 0.01 and abs(r["offset_px"]["dx"] + 0.2) < 0.01
        assert r["aligned"]["psnr_db"] > r["psnr_db"] + 10
    for r in m["rings"]:
        assert r["aligned"]["psnr_db"] >= r["psnr_db"] and r["aligned"]["ssim"] >= r["ssim"]
    # A centre in a corner (x, y) = (0, 0): quarter discs.
    c = aosr.compare_images_rings(truth, estimate, rings=2, centre=(0, 0))
    assert c["centre"] == (0.0, 0.0) and abs(c["rings"][1]["outer_px"] - np.hypot(127, 127)) < 1e-9


def test_ring_errors_name_the_argument():
    a = _smooth((64, 64), 5)
    with pytest.raises(aosr.InvalidArgument, match="rings = 0"):
        aosr.compare_images_rings(a, a, rings=0)
    with pytest.raises(aosr.InvalidArgument, match=r"rings = 9.*1 \.\. 4"):
        aosr.compare_images_rings(a, a, rings=9)
    with pytest.raises(aosr.InvalidArgument, match="centre"):
        aosr.compare_images_rings(a, a, rings=2, centre=(70, 3))
    with pytest.raises(aosr.InvalidArgument, match="centre"):
        aosr.compare_images_rings(a, a, rings=2, centre=(1, 2, 3))
    with pytest.raises(aosr.InvalidArgument, match="estimate shape"):
        aosr.compare_images_rings(a, a[:, :63], rings=2)
    with pytest.raises(aosr.InvalidArgument, match="rings = -1"):
        aosr.evaluate(a, truth=a, rings=-1)
    with pytest.raises(aosr.InvalidArgument, match="ring_centre"):
        aosr.evaluate(a, truth=a, ring_centre=(3, 4))


def test_evaluate_rings_match_the_cli(demo_dir, cli, tmp_path):
    rec = aosr.reconstruct(demo_dir, "tikhonov")
    aosr.write_fits(tmp_path / "e.fits", rec.image, dtype="float64")
    j = json.loads(cli("evaluate", "--manifest", demo_dir, "--estimate", tmp_path / "e.fits", "--rings", 3,
                       "--ring-centre", "100,60", "--json").stdout)
    m = aosr.evaluate(tmp_path / "e.fits", dataset=demo_dir, rings=3, ring_centre=(100, 60))
    assert m["rings"] == j["rings"]
    assert m["rings"]["centre_hr_px"] == {"x": 100.0, "y": 60.0} and m["rings"]["count"] == 3
    for r in m["rings"]["rings"]:
        assert r["aligned"]["psnr_db"] >= r["psnr_db"] and r["aligned"]["ssim"] >= r["ssim"]
        assert r["inner_arcsec"] < r["outer_arcsec"]  # the dataset knows its pixel scale
    assert m["aligned"]["psnr_db"] >= m["psnr_db"] and m["aligned"]["ssim"] >= m["ssim"]
    assert "rings" not in aosr.evaluate(tmp_path / "e.fits", dataset=demo_dir)
