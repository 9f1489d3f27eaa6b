"""aosr.mtf: the slanted-edge MTF (core/slanted_edge.hpp) from Python, against the analytic Gaussian MTF, and its
refusals as aosr.InvalidArgument."""
import math

import numpy as np
import pytest

import aosr


def gaussian_edge(rows, cols, angle_deg, sigma):
    """Φ(d/σ) at each pixel centre, d the signed distance to an edge through the centre (point-sampled Gaussian)."""
    t = math.radians(angle_deg)
    y, x = np.mgrid[0:rows, 0:cols].astype(float)
    d = (x - (cols - 1) / 2) * math.cos(t) - (y - (rows - 1) / 2) * math.sin(t)
    erf = np.vectorize(math.erf)
    return 0.5 * (1 + erf(d / (sigma * math.sqrt(2))))


def test_mtf_matches_the_gaussian_and_reports_its_figures():
    sigma = 1.0
    img = np.zeros((140, 120))
    img[10:130, 20:80] = gaussian_edge(120, 60, 5.0, sigma)
    m = aosr.mtf(img, roi=(20, 10, 60, 120), r=2, pixel_lambda_over_d=0.4, frequencies=[0.1])
    f = m["frequency"]
    assert f[0] == 0 and m["mtf"][0] == pytest.approx(1.0)
    ref = np.exp(-2 * math.pi ** 2 * sigma ** 2 * f ** 2)
    assert np.max(np.abs(m["mtf"] - ref)[f <= 0.5]) < 0.02
    assert m["mtf50"] == pytest.approx(math.sqrt(math.log(2) / (2 * math.pi ** 2)) / sigma, rel=0.01)
    assert m["nyquist"]["frequency"] == 0.25 and m["cutoff"]["frequency"] == 0.4
    assert m["at"][0][0] == 0.1
    assert m["edge"]["orientation"] == "vertical" and m["edge"]["angle_deg"] == pytest.approx(5.0, abs=0.05)
    assert m["esf"].shape == m["lsf"].shape == m["esf_distance"].shape
    # The same edge turned by 90 degrees is read along the columns, with the same curve.
    t = aosr.mtf(img.T, roi=(10, 20, 120, 60))
    assert t["edge"]["orientation"] == "horizontal"
    assert np.allclose(t["mtf"], aosr.mtf(img, roi=(20, 10, 60, 120))["mtf"], atol=1e-12)


def test_mtf_refuses_unusable_edges():
    img = gaussian_edge(100, 50, 5.0, 1.5)
    with pytest.raises(aosr.InvalidArgument, match="clipped"):
        aosr.mtf(np.minimum(img, 0.7))
    # At this noise the edge is not even found (the outer quarters no longer differ): refused as "no edge".
    with pytest.raises(aosr.InvalidArgument, match="too noisy|no edge"):
        aosr.mtf(img + np.random.default_rng(1).normal(0, 0.3, img.shape))
    with pytest.raises(aosr.InvalidArgument, match="too short"):
        aosr.mtf(img[:10])
    with pytest.raises(aosr.InvalidArgument, match="roi"):
        aosr.mtf(img, roi=(0, 0, 10))
    with pytest.raises(aosr.InvalidArgument, match="window"):
        aosr.mtf(img, window="box")


def test_mtf_finds_the_edges_of_a_turned_chart():
    # No roi: the whole image if it holds one edge, else the longest straight edge found (core/edge_search.hpp).
    # The turned USAF chart's truth (data/scenes/usaf-tilted.json) is read on a bar's edge: the pixel box's MTF50.
    j = aosr.read_json(aosr.data_path("scenes", "usaf-tilted.json"))
    j["detector"]["peak_noise_fraction"] = 0.0
    truth = aosr.simulate(aosr.scene_from_dict(j, source="usaf-tilted.json")).truth
    m = aosr.mtf(truth)
    assert m["roi_source"] == "found automatically" and len(m["roi"]) == 4
    assert abs(m["edge"]["angle_deg"]) == pytest.approx(5.0, abs=0.2)
    assert m["mtf50"] == pytest.approx(0.605, abs=0.012)
    assert aosr.mtf(truth, roi=m["roi"])["mtf50"] == m["mtf50"]
    one = gaussian_edge(100, 50, 5.0, 1.0)
    assert aosr.mtf(one)["roi_source"] == "whole image"
    j["objects"][0]["rotation_deg"] = 0.0
    flat = aosr.simulate(aosr.scene_from_dict(j, source="usaf-flat.json")).truth
    with pytest.raises(aosr.InvalidArgument, match="within 1 deg of an axis"):
        aosr.mtf(flat)


def test_slanted_edge_scene_and_usaf_resolving_power(demo_scene_path):
    # A scene's slanted-edge object: its truth is the pixel box's edge (MTF50 0.605 cycles/px at 5 degrees).
    j = aosr.read_json(demo_scene_path)
    j["detector"]["peak_noise_fraction"] = 0.0
    j["detector"]["frame_px"] = 48
    j["objects"] = [{"type": "slanted-edge", "angle_deg": 5.0, "low": 0.0, "high": 1.0}]
    edge = aosr.simulate(aosr.scene_from_dict(j, source=demo_scene_path))
    assert aosr.mtf(edge.truth)["mtf50"] == pytest.approx(0.605, abs=0.006)
    # The USAF truth resolves its representable elements with transfer 1; a flat image none.
    j["objects"] = [{"type": "usaf", "flux": {"peak_e": 1000}}]
    j["detector"]["frame_px"] = 64
    scene = aosr.scene_from_dict(j, source=demo_scene_path)
    truth = aosr.simulate(scene).truth
    p = aosr.usaf_resolving_power(truth, scene)
    assert p["finest"] is not None and p["threshold"] == 0.153
    assert all(e["transfer"] == pytest.approx(1.0) for e in p["elements"] if e["bar_width_hr_px"] >= 1.0)
    assert aosr.usaf_resolving_power(np.ones_like(truth), scene)["finest"] is None
    with pytest.raises(aosr.InvalidArgument, match="HR frame"):
        aosr.usaf_resolving_power(truth[:10], scene)


def test_compare_mtf_exact_transfer_of_the_linear_methods(demo_scene_path, tmp_path):
    # A noise-free edge dataset: Tikhonov's and the linear output's edges match their exact transfer
    # (solvers/linear_transfer.hpp) within issue 33's 0.03 up to the HR Nyquist; TV is marked signal-dependent.
    j = aosr.read_json(demo_scene_path)
    j["detector"] = {"frame_px": 128, "noise": "none"}
    j["objects"] = [{"type": "slanted-edge", "angle_deg": 5.0, "low": 0.1, "high": 1.0}]
    ds = aosr.simulate(aosr.scene_from_dict(j, source=demo_scene_path))
    # Noise-free frames: GCV would run to the smallest λ (no noise to balance); a fixed λ instead.
    opts = {"tikhonov": {"lambda_": 1e-3}, "tv": {"iterations": 20}}
    recs = [aosr.reconstruct(ds, m, **opts.get(m, {})) for m in ("tikhonov", "linear", "tv")]
    out = aosr.compare_mtf(recs + [("truth", ds.truth)], ds, roi=(64, 32, 128, 192), r=2, smooth_tails=False,
                           plot=str(tmp_path / "mtf.png"), table=str(tmp_path / "mtf.csv"))
    assert [o["label"] for o in out] == ["tikhonov", "linear", "tv", "truth"]
    for o in out[:2]:
        assert o["exact_status"] == "exact"
        assert o["frequency"][-1] == pytest.approx(0.5)
        assert np.max(np.abs(o["mtf"] - o["exact"]["mtf"])) < 0.03
    assert out[0]["exact"]["alias"].shape == out[0]["exact"]["mtf"].shape
    assert out[2]["exact_status"] == "signal-dependent" and out[2]["exact"] is None
    assert out[3]["exact_status"] == "measured only"
    assert (tmp_path / "mtf.png").exists()
    assert (tmp_path / "mtf.csv").read_text().startswith("frequency_cycles_per_px,tikhonov edge,")
    # Without the dataset Tikhonov's curve is unavailable; a wrong exact model would be far off.
    assert aosr.compare_mtf(recs[:1], roi=(64, 32, 128, 192))[0]["exact_status"].startswith("unavailable")
    wrong = aosr.compare_mtf(recs[:1], ds, roi=(64, 32, 128, 192), smooth_tails=False, prior="identity")[0]
    assert np.max(np.abs(wrong["mtf"] - wrong["exact"]["mtf"])) > 0.03
    with pytest.raises(aosr.InvalidArgument, match="images\\[0\\]"):
        aosr.compare_mtf([3.0])
    with pytest.raises(aosr.InvalidArgument, match="prior"):
        aosr.compare_mtf(recs[:1], ds, prior="fitted")
    with pytest.raises(aosr.InvalidArgument, match="no image has a usable edge"):
        aosr.compare_mtf([("flat", np.ones((64, 64)))])
