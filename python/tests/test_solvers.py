"""aosr.reconstruct against the same library call in C++ (bit for bit), its options table, progress, Ctrl-C,
zero copy and the GIL."""
import json
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest

import aosr
from conftest import bits_equal

# Every method; tv and map capped so that the suite stays quick (the same cap on both sides).
METHODS = [("shift-add", None), ("shift-add-median", None), ("drizzle", None), ("tikhonov", None),
           ("linear", None), ("tv", 15), ("map", 15)]


@pytest.mark.parametrize("method,iterations", METHODS)
def test_reconstruct_matches_cpp_bit_for_bit(method, iterations, demo_dir, reference, tmp_path):
    out = tmp_path / f"{method}.fits"
    args = ["reconstruct", demo_dir, method, out] + (["--iterations", iterations] if iterations else [])
    ref = reference(*args)
    expected, _ = aosr.read_fits(out)
    options = {"iterations": iterations} if iterations else {}
    rec = aosr.reconstruct(demo_dir, method, **options)
    assert bits_equal(rec.image, expected)
    assert rec.regularisation == ref["regularisation"]
    assert rec.summary["iterations"] == ref["iterations"]
    assert rec.summary["termination"] == ref["termination"]
    if os.path.exists(str(out) + ".aux.fits"):
        aux, _ = aosr.read_fits(str(out) + ".aux.fits")
        assert bits_equal(rec.aux, aux)
    # The same through an opened dataset object.
    assert bits_equal(aosr.reconstruct(aosr.open_dataset(demo_dir), method, **options).image, expected)


def test_cli_summary_agrees(demo_dir, cli, tmp_path):
    import json
    p = cli("reconstruct", demo_dir, "-m", "tikhonov", "-o", tmp_path / "t.fits", "--json")
    j = json.loads(p.stdout)
    rec = aosr.reconstruct(demo_dir, "tikhonov")
    assert rec.regularisation == j["regularisation"]
    assert rec.weights_source == j["weights"]
    assert rec.summary["message"] == j["summary"]["message"]
    m = aosr.evaluate(rec.image, dataset=demo_dir)
    assert m["psnr_db"] == j["against_truth"]["psnr_db"]
    assert m["ssim"] == j["against_truth"]["ssim"]


def test_options_table(demo_dir):
    ds = aosr.open_dataset(demo_dir)
    a = aosr.reconstruct(ds, "tv", tv_max_iterations=5, tv_relative_tolerance=1e-6)
    b = aosr.reconstruct(ds, "tv", tv={"max_iterations": 5, "relative_tolerance": 1e-6})
    assert bits_equal(a.image, b.image) and a.summary["iterations"] == 5
    fixed = aosr.reconstruct(ds, "tikhonov", lambda_=0.5)
    assert fixed.regularisation == 0.5
    assert aosr.reconstruct(ds, "tikhonov", **{"lambda": 0.5}).regularisation == 0.5
    assert aosr.reconstruct(ds, "tv", mu=2.0, iterations=3).regularisation == 2.0
    std = aosr.reconstruct(ds, "tikhonov", std=True, weights="mask")
    assert std.aux_name == "posterior-std" and std.aux.shape == std.image.shape
    sampled = aosr.reconstruct(ds, "tikhonov", std=True, tikhonov_std_samples=4)  # weighted: posterior draws
    assert sampled.aux_name == "posterior-std" and np.isfinite(sampled.aux).all()
    # Values added to the library's enums are accepted through its own Parse functions.
    wiener = aosr.reconstruct(ds, "tikhonov", prior="fitted", lambda_rule="wiener", weights="mask")
    assert wiener.summary["termination"] == "converged"
    assert aosr.reconstruct_options()["tikhonov_lambda_rule"]["default"] == "gcv"
    help_ = aosr.reconstruct_options()
    assert help_["tv_max_iterations"]["default"] == 1000
    assert help_["noise_sigma"]["default"] == 1.0  # the CLI's default
    assert "linear_leakage" in help_
    # The rank counts are made on request (tikhonov_count_unconstrained, the CLI's --count-unconstrained).
    counted = aosr.reconstruct(ds, "tikhonov", lambda_=0.5, tikhonov_count_unconstrained=True)
    assert "HR frequencies unconstrained by the data" in counted.summary["message"]
    assert "unconstrained" not in fixed.summary["message"]
    assert bits_equal(counted.image, fixed.image)
    assert help_["tikhonov_count_unconstrained"]["default"] is False


@pytest.mark.parametrize("kwargs,needle", [
    ({"bogus": 1}, "bogus"),
    ({"tv_max_iterations": 2.5}, "tv_max_iterations"),
    ({"tv_positivity": 1}, "True or False"),
    ({"prior": "smooth"}, "smooth"),
    ({"map_prior": "tv"}, "charbonnier-tv"),
    ({"tv": {"nope": 1}}, "nope"),
])
def test_bad_options_raise_invalid_argument(demo_dir, kwargs, needle):
    with pytest.raises(aosr.InvalidArgument, match=needle) as e:
        aosr.reconstruct(demo_dir, "tv", **kwargs)
    assert isinstance(e.value, ValueError)


def test_progress_callback_and_cancel(demo_dir):
    ds = aosr.open_dataset(demo_dir)
    seen = []
    full = aosr.reconstruct(ds, "tv", iterations=8, progress=lambda p: seen.append(p) or True)
    assert {"pilot", "tv"} <= {p["stage"] for p in seen}
    assert bits_equal(full.image, aosr.reconstruct(ds, "tv", iterations=8).image)  # a callback changes nothing
    cancelled = aosr.reconstruct(ds, "tv", iterations=1000, progress=lambda p: p["stage"] != "tv")
    assert cancelled.summary["termination"] == "cancelled"
    assert np.isfinite(cancelled.image).all()

    def boom(p):
        raise RuntimeError("from the callback")
    with pytest.raises(RuntimeError, match="from the callback"):
        aosr.reconstruct(ds, "map", iterations=50, progress=boom)


def test_ctrl_c_interrupts_a_long_solve(demo_dir):
    """A real SIGINT during a long TV solve: KeyboardInterrupt within a second or two, process still sane."""
    script = textwrap.dedent(f"""
        import sys, time, aosr
        ds = aosr.open_dataset({demo_dir!r})
        print("ready", flush=True)
        t = time.time()
        try:
            aosr.reconstruct(ds, "tv", iterations=1000000, tv_relative_tolerance=1e-15, tv_absolute_tolerance=0.0)
        except KeyboardInterrupt:
            print("interrupted after %.2f s" % (time.time() - t), flush=True)
            rec = aosr.reconstruct(ds, "shift-add")   # the library is still usable
            print("ok", rec.summary["termination"], flush=True)
            sys.exit(0)
        print("not interrupted", flush=True)
        sys.exit(1)
    """)
    p = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True, env=os.environ)
    assert p.stdout.readline().strip() == "ready"
    time.sleep(1.0)
    p.send_signal(signal.SIGINT)
    out, _ = p.communicate(timeout=60)
    assert p.returncode == 0, out
    assert "interrupted after" in out and "ok converged" in out
    seconds = float(out.split("interrupted after ")[1].split()[0])
    assert seconds < 10


def test_zero_copy_out_and_read_only_views(demo_dir):
    ds = aosr.open_dataset(demo_dir)
    rec = aosr.reconstruct(ds, "tikhonov")
    a, b = rec.image, rec.image
    assert np.shares_memory(a, b)                  # two views of the one C++ image
    assert a.flags.c_contiguous and a.dtype == np.float64 and a.flags.writeable
    a[0, 0] += 1.0
    assert b[0, 0] == a[0, 0]
    assert np.shares_memory(ds.truth, ds.truth) and not ds.truth.flags.writeable
    assert ds.frames is ds.frames and not ds.frames.flags.writeable   # stacks: one cached copy
    del rec
    assert np.isfinite(a).all()                    # the view keeps the C++ result alive
    p = aosr.psf("paper-8m", mode="diffraction", size=32)["psf"]
    assert p.base is not None and p.flags.owndata is False  # moved out of C++, not copied


def test_inputs_are_copied_once_and_never_modified(demo_dir):
    ds = aosr.open_dataset(demo_dir)
    frames = np.array(ds.frames)
    mine = aosr.Dataset.from_arrays(frames, ds.psfs, r=ds.r, gain=ds.gain, bias=ds.bias, valid=ds.valid,
                                    weights=ds.weights, truth=ds.truth)
    assert not np.shares_memory(mine.frames, frames)
    before = frames.copy()
    aosr.reconstruct(mine, "tikhonov")
    assert bits_equal(frames, before)
    # Any dtype/layout is accepted (converted), with the same result as float64 C order.
    fortran = [np.asfortranarray(f) for f in frames]
    again = aosr.Dataset.from_arrays(fortran, ds.psfs.astype(np.float64), r=ds.r, gain=ds.gain, bias=ds.bias,
                                     valid=ds.valid.astype(np.int32), weights=ds.weights)
    assert bits_equal(aosr.reconstruct(again, "tikhonov").image, aosr.reconstruct(mine, "tikhonov").image)


def test_gil_released_during_solve(demo_dir):
    ds = aosr.open_dataset(demo_dir)
    ticks = 0
    done = threading.Event()

    def solve():
        aosr.reconstruct(ds, "tv", iterations=60)
        done.set()
    t = threading.Thread(target=solve)
    t.start()
    while not done.is_set():
        ticks += 1
        time.sleep(0.001)
    t.join()
    assert ticks > 10   # the main thread ran while the solve did


def test_reconstruct_rejects_a_bad_dataset_argument():
    with pytest.raises(aosr.InvalidArgument, match="aosr.Dataset or a dataset folder"):
        aosr.reconstruct(42, "tikhonov")
    with pytest.raises(aosr.IoError) as e:
        aosr.reconstruct("/nonexistent/folder", "tikhonov")
    assert isinstance(e.value, OSError) and "/nonexistent/folder" in str(e.value)


def test_default_weights_are_source_independent_for_linear_methods(demo_dir, cli, tmp_path):
    """Issue 24: weights='auto' means background (sky + read noise) inverse variances for the linear methods, the
    dataset's for tv/map; 'poisson' names the source-dependent ones and warns next to a linear method."""
    import json
    import warnings
    ds = aosr.open_dataset(demo_dir)
    for method in ("linear", "drizzle", "tikhonov"):
        rec = aosr.reconstruct(ds, method)
        assert rec.weights_source == "background variances from the detector model (e-^-2)", method
        j = json.loads(cli("reconstruct", demo_dir, "-m", method, "-o", tmp_path / f"{method}.fits", "--json").stdout)
        assert j["weights"] == rec.weights_source
    assert aosr.reconstruct(ds, "tv", iterations=3).weights_source == "dataset inverse variances (e-^-2)"
    assert aosr.reconstruct(ds, "linear", weights="background").weights_source.startswith("background variances")
    with pytest.warns(UserWarning, match="bias bright sources low"):
        rec = aosr.reconstruct(ds, "drizzle", weights="poisson")
    assert rec.weights_source == "dataset inverse variances (e-^-2)"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        aosr.reconstruct(ds, "drizzle")  # no warning by default
    # A simulation in memory carries the same detector model as a dataset on disk.
    mem = aosr.simulate(aosr.load_scene(aosr.data_path("scenes", "demo.json")), seed=1)
    assert aosr.reconstruct(mem, "linear").weights_source == "background variances from the detector model (e-^-2)"


def test_diffraction_target_psf(demo_dir, cli, tmp_path):
    """target_psf='diffraction' (the CLI's --target-psf diffraction): the telescope's Airy pattern at the dataset's
    wavelength on the HR grid: the demo's camera pixel is lambda/D and r = 2, so the pattern is point-sampled at
    lambda/(2D), where psf_metrics' FWHM reads 0.903 lambda/D = 1.81 HR px (1.02 lambda/D at lambda/(8D))."""
    import json
    rec = aosr.reconstruct(demo_dir, "linear", target_psf="diffraction")
    assert abs(rec.linear["target_fwhm_hr_px"] - 1.81) < 0.02
    j = json.loads(cli("reconstruct", demo_dir, "-m", "linear", "--target-psf", "diffraction", "-o",
                       tmp_path / "d.fits", "--json").stdout)
    assert j["linear"]["target_fwhm_hr_px"] == rec.linear["target_fwhm_hr_px"]
    assert aosr.reconstruct_options()["linear_target_psf"]["default"] == "auto"


def test_reconstruct_offsets_estimate_matches_the_cli(demo_dir, cli, tmp_path):
    """offsets='estimate': the registration of `aosr reconstruct --offsets estimate`, per frame commanded and
    estimated offsets in camera px, the same numbers as the CLI's JSON."""
    rec = aosr.reconstruct(demo_dir, "tikhonov", offsets="estimate")
    reg = rec.registration
    assert reg is not None and len(reg["frames"]) == 4 and reg["rounds"] >= 1
    assert "estimated from the frames" in rec.offsets_source
    out = json.loads(cli("reconstruct", demo_dir, "-m", "tikhonov", "--offsets", "estimate", "--json",
                         "-o", tmp_path / "t.fits").stdout)
    for f, g in zip(reg["frames"], out["registration"]["frames"]):
        assert f["commanded_camera_px"] == pytest.approx(tuple(g["commanded_camera_px"]), abs=1e-12)
        assert f["estimated_camera_px"] == pytest.approx(tuple(g["estimated_camera_px"]), abs=1e-12)
        # the demo's DM applies what it is commanded: the estimate stays near it
        assert f["estimated_camera_px"] == pytest.approx(f["commanded_camera_px"], abs=0.02)
    assert aosr.reconstruct(demo_dir, "tikhonov").registration is None
    with pytest.raises(aosr.InvalidArgument, match="mean . frame0"):
        aosr.reconstruct(demo_dir, "tikhonov", offsets="estimate", registration_anchor="x")
    with pytest.raises(aosr.InvalidArgument, match="search_range_camera_px"):
        aosr.reconstruct(demo_dir, "tikhonov", offsets="estimate", registration_range=0)


def _small_star_field(tmp_path):
    """crowded-stars on a 48² frame with 40 stars (seconds): a dataset folder."""
    scene = aosr.read_json(aosr.data_path("scenes", "crowded-stars.json"))
    scene["detector"]["frame_px"] = 48
    scene["objects"][0]["count"] = 40
    out = tmp_path / "stars"
    aosr.simulate(aosr.scene_from_dict(scene), output=out)
    return out


def test_stars_psf_refuses_a_structured_background(cli, tmp_path):
    """Issue 31 item 4: stars over a structured background (a dead-leaves texture as a nebula) do not fit as point
    sources; the estimate is refused with chi2 and the stars kept, from Python and the CLI, unless the check is
    turned off; the same stars on their flat sky pass (chi2 near the stars ~1.1)."""
    scene = aosr.read_json(aosr.data_path("scenes", "crowded-stars.json"))
    scene["detector"]["frame_px"] = 64
    scene["objects"][0]["count"] = 100
    flat = aosr.stars_psf(aosr.simulate(aosr.scene_from_dict(scene)))
    assert flat["chi2_near_stars"] < 2 and flat["rejected"] >= 0
    scene["objects"].append({"type": "dead-leaves", "radius_range_px": [1, 16], "flux": {"peak_e": 400}})
    out = tmp_path / "nebula"
    aosr.simulate(aosr.scene_from_dict(scene), output=out)
    with pytest.raises(aosr.InvalidArgument, match="stars kept.*max_chi2_near_stars"):
        aosr.stars_psf(out)
    loose = aosr.stars_psf(out, max_chi2_near_stars=0, background_mesh_px=16)
    assert loose["chi2_near_stars"] > 5 and loose["background_mesh_px"] == 16
    p = cli("reconstruct", out, "-m", "tikhonov", "--model-psfs", "stars", "-o", tmp_path / "t.fits", check=False)
    assert p.returncode != 0 and "max_chi2_near_stars" in p.stdout + p.stderr


def test_stars_psf_matches_the_cli(cli, tmp_path):
    """aosr.stars_psf and model_psfs='stars': the PSFs `aosr reconstruct --model-psfs stars` estimates (the same
    bits), the stars it used and its chi2, and the error naming what an empty field lacks."""
    ds = _small_star_field(tmp_path)
    est = aosr.stars_psf(ds)
    assert est["psf"].shape == (64, 64) and est["psfs"].shape[0] == 4
    assert est["psf"].sum() == pytest.approx(1.0, abs=1e-12)
    assert est["stars_used"] >= 10 and est["stars"].shape == (est["stars_used"], 3)
    assert 0.5 < est["chi2_per_dof"] < 2 and est["chi2_near_stars"] > 0
    assert est["cg_converged"] and est["cg_iterations_total"] >= est["cg_iterations_last"] > 0
    capped = aosr.stars_psf(ds, cg_iterations=3)  # a capped h solve is reported, not hidden
    assert not capped["cg_converged"] and "NOT converged" in capped["report"]
    truth = aosr.open_dataset(ds).psfs
    k = est["psfs"].shape[1]
    c = truth.shape[1] // 2
    crop = truth[:, c - k // 2:c + k // 2, c - k // 2:c + k // 2]
    rms = np.sqrt(((est["psfs"] - crop) ** 2).mean()) / crop.max()
    assert rms < 0.02  # the target on a crowded field

    out = json.loads(cli("reconstruct", ds, "-m", "tikhonov", "--model-psfs", "stars", "--stars-psf-out",
                         tmp_path / "p.fits", "--json", "-o", tmp_path / "t.fits").stdout)
    assert out["stars_psf"]["stars_used"] == est["stars_used"]
    assert out["stars_psf"]["chi2_per_dof"] == pytest.approx(est["chi2_per_dof"], rel=1e-12)
    assert bits_equal(np.asarray(aosr.read_fits(tmp_path / "p.fits")[0]), est["psfs"])

    rec = aosr.reconstruct(ds, "tikhonov", model_psfs="stars")
    assert rec.model_psfs_replaced and rec.stars_psf["stars_used"] == est["stars_used"]
    assert bits_equal(rec.stars_psf["psfs"], est["psfs"])
    assert aosr.reconstruct(ds, "tikhonov").stars_psf is None
    assert aosr.stars_psf(ds, rounds=2)["rounds"] == 2

    rng = np.random.default_rng(3)
    empty = aosr.Dataset.from_arrays(100 + rng.normal(0, 3, (4, 32, 32)), np.ones((1, 8, 8)), r=2)
    with pytest.raises(aosr.InvalidArgument, match="no point source above 5 sigma"):
        aosr.stars_psf(empty)
    with pytest.raises(aosr.InvalidArgument, match="no point source above"):
        aosr.reconstruct(empty, "tikhonov", model_psfs="stars")
    with pytest.raises(aosr.InvalidArgument, match="stars option"):
        aosr.stars_psf(ds, threshold=3)
    with pytest.raises(aosr.InvalidArgument, match="'nominal' . 'stars'"):
        aosr.reconstruct(ds, "tikhonov", model_psfs="star")


def test_bicubic_conserves_flux_and_checks_r():
    frame = np.random.default_rng(3).random((12, 10))
    up = aosr.bicubic(frame, 3)
    assert up.shape == (36, 30)
    assert up.sum() == pytest.approx(frame.sum(), rel=0.02)  # flux per HR pixel: sums agree up to the borders
    with pytest.raises(aosr.InvalidArgument, match="r"):
        aosr.bicubic(frame, 0)


def test_stars_psf_over_a_field_grid(cli, tmp_path):
    """Issue 31 item 4: stars PSFs fitted at the nodes of a grid over the field (grid=(ny, nx); the CLI's
    --stars-grid) are a field model: the reconstruction goes by tiles with them, the CLI and Python give the
    same nodes, the FITS output carries them, and a grid too fine for the stars is refused naming the node."""
    scene = aosr.read_json(aosr.data_path("scenes", "crowded-stars.json"))
    scene["detector"]["frame_px"] = 64
    scene["objects"][0]["count"] = 100
    ds = tmp_path / "stars"
    aosr.simulate(aosr.scene_from_dict(scene), output=ds)
    with pytest.raises(aosr.InvalidArgument, match="16384 unknowns for 16384 frame pixels"):
        aosr.stars_psf(ds, grid=(2, 2))  # K = 64 by default: too many unknowns for 4 frames of 64^2
    est = aosr.stars_psf(ds, grid=(2, 2), psf_size_hr_px=32)
    assert est["grid"] == (2, 2) and est["node_psfs"].shape == (4, 32, 32) and len(est["field_psfs"]) == 4
    assert est["field_psfs"][0].shape[0] == 4 and len(est["grid_nodes_hr_px"]) == 4
    assert sum(est["node_stars"]) == pytest.approx(est["stars_used"], rel=1e-12)
    np.testing.assert_allclose(est["psf"], est["node_psfs"].mean(axis=0), atol=1e-12)
    assert "2 x 2 grid" in est["report"] and aosr.stars_psf(ds)["grid"] == (1, 1)
    # The scene's PSF is the same everywhere: every node is that PSF, to the noise of ~25 faint stars a node
    # (2-3.5 % RMS of the peak; the single PSF of all of them 1 %). A weaker prior (grid_variation) lets them
    # wander further.
    truth = aosr.open_dataset(ds).psfs
    k = est["psfs"].shape[1]
    c = truth.shape[1] // 2
    crop = truth[0, c - k // 2:c + k // 2, c - k // 2:c + k // 2]
    rms = lambda a: np.sqrt(((a - crop) ** 2).mean()) / crop.max()
    assert max(rms(est["field_psfs"][g][0]) for g in range(4)) < 0.05
    loose = aosr.stars_psf(ds, grid=(2, 2), psf_size_hr_px=32, grid_variation=3.0)
    assert max(rms(loose["field_psfs"][g][0]) for g in range(4)) > max(rms(est["field_psfs"][g][0]) for g in range(4))

    stars = {"grid": (2, 2), "psf_size_hr_px": 32}
    rec = aosr.reconstruct(ds, "tikhonov", model_psfs="stars", stars=stars)
    assert rec.psf_field == "tiles" and rec.stars_psf["grid"] == (2, 2)
    assert bits_equal(rec.stars_psf["node_psfs"], est["node_psfs"])
    assert aosr.reconstruct(ds, "tikhonov", model_psfs="stars", stars=stars, psf_field="none").psf_field == "none"
    out = json.loads(cli("reconstruct", ds, "-m", "tikhonov", "--model-psfs", "stars", "--stars-grid", "2x2",
                         "--stars-psf-size", "32",
                         "--stars-psf-out", tmp_path / "p.fits", "--json", "-o", tmp_path / "t.fits").stdout)
    assert out["stars_psf"]["grid"]["ny"] == 2 and out["psf_field"]["model"] == "tiles"
    assert out["stars_psf"]["grid"]["node_stars"] == pytest.approx(est["node_stars"], rel=1e-12)
    from astropy.io import fits
    with fits.open(tmp_path / "p.fits") as f:
        assert f["FIELD"].header["FLDNY"] == 2 and f["FIELD"].data.shape == (16,) + est["field_psfs"][0].shape[1:]
        assert bits_equal(f["FIELD"].data[4 * 3:4 * 4], est["field_psfs"][3])
        assert bits_equal(f[0].data, est["psfs"])
    np.testing.assert_allclose(aosr.read_fits(tmp_path / "t.fits")[0], rec.image, rtol=1e-6, atol=1e-6 * abs(rec.image).max())

    # The nodes' prior (grid_degree, --stars-grid-degree): a quadratic surface by default, the mean with 0; the CLI
    # and Python give the same nodes, and the FITS FIELD extension records it.
    assert est["grid_degree"] == 2 and est["grid_roughness"] == 0.005
    # (2 x 3 nodes: the quadratic's 5 terms leave one for the roughness; 2 x 2 would span all four nodes.)
    flat = aosr.stars_psf(ds, grid=(2, 3), psf_size_hr_px=16, min_stars=2, grid_degree=0)
    curved = aosr.stars_psf(ds, grid=(2, 3), psf_size_hr_px=16, min_stars=2)
    assert "degree-2 surface" in curved["report"] and "surface" not in flat["report"]
    assert not np.array_equal(flat["node_psfs"], curved["node_psfs"])
    out = json.loads(cli("reconstruct", ds, "-m", "tikhonov", "--model-psfs", "stars", "--stars-grid", "2x3",
                         "--stars-psf-size", "16", "--stars-min", "2", "--stars-grid-degree", "0", "--stars-psf-out", tmp_path / "f.fits",
                         "--json", "-o", tmp_path / "f3.fits").stdout)
    assert out["stars_psf"]["grid"]["degree"] == 0
    assert out["stars_psf"]["grid"]["node_stars"] == pytest.approx(flat["node_stars"], rel=1e-12)
    with fits.open(tmp_path / "f.fits") as f:
        assert f["FIELD"].header["FLDDEG"] == 0
        assert bits_equal(f["FIELD"].data[4 * 5:4 * 6], flat["field_psfs"][5])
    with pytest.raises(aosr.InvalidArgument, match="grid_degree = 5"):
        aosr.stars_psf(ds, grid=(3, 3), psf_size_hr_px=16, grid_degree=5)
    p = cli("reconstruct", ds, "-m", "tikhonov", "--model-psfs", "stars", "--stars-grid", "3x3", "--stars-grid-degree",
            "5", "-o", tmp_path / "u.fits", check=False)
    assert p.returncode != 0 and "stars-grid-degree" in p.stdout + p.stderr

    with pytest.raises(aosr.InvalidArgument, match="node .* coarser grid"):
        aosr.stars_psf(ds, grid=(4, 4), psf_size_hr_px=16, min_stars=10)
    p = cli("reconstruct", ds, "-m", "tikhonov", "--model-psfs", "stars", "--stars-grid", "4x4", "--stars-psf-size", "16",
            "--stars-min", "10", "-o",
            tmp_path / "u.fits", check=False)
    assert p.returncode != 0 and "coarser grid" in p.stdout + p.stderr
    p = cli("reconstruct", ds, "-m", "tikhonov", "--stars-grid", "2x2", "-o", tmp_path / "u.fits", check=False)
    assert p.returncode != 0 and "only with --model-psfs stars" in p.stdout + p.stderr
    p = cli("reconstruct", ds, "-m", "tikhonov", "--model-psfs", "stars", "--stars-grid", "2by2", "-o",
            tmp_path / "u.fits", check=False)
    assert p.returncode != 0 and "NYxNX" in p.stdout + p.stderr
    with pytest.raises(aosr.InvalidArgument, match="stars grid"):
        aosr.stars_psf(ds, grid=(2, 2, 2))
