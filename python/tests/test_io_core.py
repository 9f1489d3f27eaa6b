"""FITS headers as dicts (astropy reads them), errors as exceptions, evaluate/psf/calibrate against the CLI."""
import json
import os

import numpy as np
import pytest

import aosr
from conftest import bits_equal


def test_fits_round_trip_and_astropy(tmp_path):
    fits = pytest.importorskip("astropy.io.fits")
    data = np.arange(12.0).reshape(3, 4) / 7
    header = {"OBJECT": "M31", "EXPTIME": 1.5, "NFRAMES": 4, "FLAG": True, "HIERARCH LONGKEYWORD": "x"}
    aosr.write_fits(tmp_path / "a.fits", data, header, comments={"EXPTIME": "[s]"}, dtype="float64")
    back, h, c = aosr.read_fits(tmp_path / "a.fits", with_comments=True)
    assert bits_equal(back, data) and h == header and c["EXPTIME"] == "[s]"
    with fits.open(tmp_path / "a.fits") as f:
        assert bits_equal(f[0].data, data)
        assert f[0].header["EXPTIME"] == 1.5 and f[0].header["LONGKEYWORD"] == "x"
    assert fits.Header(h)["OBJECT"] == "M31"
    # An astropy header is accepted too; its structural keywords are the writer's.
    aosr.write_fits(tmp_path / "b.fits", np.ones((2, 3, 4)), fits.getheader(tmp_path / "a.fits"))
    cube, h2 = aosr.read_fits(tmp_path / "b.fits")
    assert cube.shape == (2, 3, 4) and h2["OBJECT"] == "M31"


def test_errors_map_to_exceptions(tmp_path):
    assert issubclass(aosr.InvalidArgument, ValueError) and issubclass(aosr.InvalidArgument, aosr.Error)
    assert issubclass(aosr.IoError, OSError) and issubclass(aosr.ResourceError, MemoryError)
    with pytest.raises(aosr.IoError) as e:
        aosr.read_fits(tmp_path / "nope.fits")
    assert e.value.path == str(tmp_path / "nope.fits") and str(e.value).startswith(str(tmp_path / "nope.fits"))
    with pytest.raises(aosr.InvalidArgument, match="dtype"):
        aosr.write_fits(tmp_path / "x.fits", np.ones((2, 2)), dtype="int8")
    with pytest.raises(aosr.InvalidArgument, match="2-D"):
        aosr.compare_images(np.ones(3), np.ones(3))
    with pytest.raises(aosr.InvalidArgument, match="threads"):
        aosr.set_threads(-1)
    with pytest.raises(aosr.ResourceError):
        aosr.set_memory_limit("1M")
        try:
            aosr.simulate(aosr.load_scene(aosr.data_path("scenes", "paper-sim-r4.json")))
        finally:
            aosr.set_memory_limit("1T")


def test_fft_planner_settings_and_shipped_wisdom(demo_dir):
    # The shipped FFTW wisdom is read by this FFTW (else every transform silently takes FFTW_ESTIMATE's slower
    # plans); 'heuristic' plans without it and gives the same image to rounding; a bad name is refused.
    assert aosr.allocator_tuned() in (True, False)
    try:
        a = aosr.reconstruct(demo_dir, "tikhonov").image
        assert aosr.fft_wisdom_loaded()
        aosr.set_fft_planner("heuristic")
        b = aosr.reconstruct(demo_dir, "tikhonov").image
        assert np.max(np.abs(a - b)) <= 1e-9 * np.max(np.abs(a))
        with pytest.raises(aosr.InvalidArgument, match="heuristic"):
            aosr.set_fft_planner("fastest")
    finally:
        aosr.set_fft_planner("estimate")


def test_allocator_tuning_defers_to_the_environment_unless_overridden():
    # Dask's nanny starts workers with MALLOC_TRIM_THRESHOLD_=65536: the import leaves it alone, aosr.distributed's
    # tasks override it (tune_allocator(override_environment=True)); AOSR_MALLOC_TUNING=0 is never overridden.
    import subprocess
    import sys
    code = ("import aosr; a = aosr.allocator_tuned(); b = aosr.tune_allocator(); "
            "c = aosr.tune_allocator(override_environment=True); print(a, b, c)")
    env = dict(os.environ, MALLOC_TRIM_THRESHOLD_="65536", PYTHONPATH=os.pathsep.join(sys.path))
    env.pop("AOSR_MALLOC_TUNING", None)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False", "True"]
    env["AOSR_MALLOC_TUNING"] = "0"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False", "False"]


def test_evaluate_matches_cli(demo_dir, cli, tmp_path):
    rec = aosr.reconstruct(demo_dir, "drizzle")
    aosr.write_fits(tmp_path / "e.fits", rec.image, dtype="float64")
    j = json.loads(cli("evaluate", "--manifest", demo_dir, "--estimate", tmp_path / "e.fits", "--json").stdout)
    m = aosr.evaluate(tmp_path / "e.fits", dataset=demo_dir)
    for k in ("psnr_db", "ssim", "rmse", "crop_px", "aligned", "offset_hr_px", "offset_mas"):
        assert m[k] == j[k], k
    assert m["offset_mas"] is not None  # the dataset knows its pixel scale
    truth = os.path.join(demo_dir, "truth.fits")
    j = json.loads(cli("evaluate", "--truth", truth, "--estimate", tmp_path / "e.fits", "--crop", 8, "--json").stdout)
    m = aosr.evaluate(rec.image, truth=truth, crop=8)
    assert (m["psnr_db"], m["ssim"]) == (j["psnr_db"], j["ssim"])
    c = aosr.compare_images(aosr.read_fits(truth)[0], rec.image, crop=8)
    assert c["psnr_db"] == j["psnr_db"]
    with pytest.raises(aosr.InvalidArgument, match="exactly one"):
        aosr.evaluate(rec.image)


def test_evaluate_subtracts_a_linear_outputs_sky(tmp_path):
    # truth + c: a file whose METHOD is linear is scored without its sky by default (as `aosr evaluate`), an array
    # only when asked; 'sky_subtracted' says what was removed.
    y, x = np.mgrid[0:32, 0:40]
    truth = 60 + 50 * np.sin(0.3 * y) * np.cos(0.2 * x)
    aosr.write_fits(tmp_path / "t.fits", truth, dtype="float64")
    aosr.write_fits(tmp_path / "e.fits", truth + 7.25, header={"METHOD": "linear"}, dtype="float64")
    m = aosr.evaluate(tmp_path / "e.fits", truth=tmp_path / "t.fits")
    assert abs(m["sky_subtracted"] - 7.25) < 1e-9 and m["rmse"] < 1e-9
    m = aosr.evaluate(truth + 7.25, truth=truth)
    assert m["sky_subtracted"] is None and abs(m["rmse"] - 7.25) < 1e-9
    m = aosr.evaluate(truth + 7.25, truth=truth, subtract_sky=True)
    assert abs(m["sky_subtracted"] - 7.25) < 1e-9
    m = aosr.evaluate(tmp_path / "e.fits", truth=truth, subtract_sky=False)
    assert m["sky_subtracted"] is None and abs(m["rmse"] - 7.25) < 1e-9


def test_aligned_scores_recover_a_known_shift():
    # A band-limited periodic image moved by a known sub-pixel offset: recovered to 0.01 px, aligned PSNR high.
    rng = np.random.default_rng(4)
    y, x = np.mgrid[0:64, 0:64]
    truth = 2.0 + sum(rng.uniform(0.1, 1) * np.cos(2 * np.pi * (rng.integers(-12, 13) * y + rng.integers(-12, 13) * x) / 64
                                                    + rng.uniform(0, 2 * np.pi)) for _ in range(30))
    moved = aosr.fourier_shift(truth, 0.4137, -0.2562)
    m = aosr.compare_images_aligned(truth, moved, crop=4)
    assert abs(m["offset_px"]["dy"] - 0.4137) < 0.01 and abs(m["offset_px"]["dx"] + 0.2562) < 0.01
    assert m["aligned"]["psnr_db"] > 50 > m["psnr_db"]
    assert m["psnr_db"] == aosr.compare_images(truth, moved, crop=4)["psnr_db"]
    same = aosr.compare_images_aligned(truth, truth)
    assert same["offset_px"] == {"dy": 0.0, "dx": 0.0}
    e = aosr.evaluate(moved, truth=truth, crop=4)
    assert e["offset_hr_px"] == m["offset_px"] and e["offset_mas"] is None


def test_psf_matches_cli(cli, tmp_path):
    out = tmp_path / "p.fits"
    j = json.loads(cli("psf", "paper-8m", "--size", 64, "--offset", "4=100", "-o", out, "--json").stdout)
    p = aosr.psf("paper-8m", size=64, offsets={4: 100})
    assert bits_equal(p["psf"], aosr.read_fits(out)[0])
    assert p["core_centroid_lambda_over_d"] == j["core_centroid_lambda_over_d"]
    assert abs(p["core_centroid_lambda_over_d"]["x"]) < 1e-6  # defocus moves no core
    for k in ("mode", "strehl", "fwhm_px", "window_sum", "residual_rms_nm", "encircled_energy"):
        assert p[k] == j[k], k
    with pytest.raises(aosr.InvalidArgument, match="size"):
        aosr.psf("paper-bench", size=4000)
    with pytest.raises(aosr.InvalidArgument, match="sensor"):
        aosr.psf("paper-8m", sensor="magic")


def test_psf_off_axis_matches_cli(cli):
    # Anisoplanatism (issue 31): the PSF 20" from the guide star, as `aosr psf --field-angle 20` (same bytes).
    # lambda/(8D) pixels: at lambda/(2D) the half-maximum region's moments are quantised (psf_cli_test.cpp).
    j = json.loads(cli("psf", "paper-8m", "--size", 128, "--pixel-lod", 0.125, "--field-angle", 20, "--json").stdout)
    p = aosr.psf("paper-8m", size=128, pixel_lod=0.125, field_angle=20)
    for k in ("strehl", "fwhm_px", "elongation", "major_axis_angle_deg", "isoplanatic_angle_arcsec",
              "field_direction_arcsec", "fwhm_major_lambda_over_d", "fwhm_minor_lambda_over_d"):
        assert p[k] == j[k], k
    on = aosr.psf("paper-8m", size=64)
    assert on["field_angle_arcsec"] == 0 and on["strehl"] > p["strehl"]
    assert p["elongation"] > 1.015 and abs(p["major_axis_angle_deg"]) < 10  # measured 1.032 at -5.1 deg
    q = aosr.psf("paper-8m", size=128, pixel_lod=0.125, field_direction=(0, 20))
    assert q["elongation"] > 1.015 and abs(abs(q["major_axis_angle_deg"]) - 90) < 10
    with pytest.raises(aosr.InvalidArgument, match="field_direction"):
        aosr.psf("paper-8m", field_direction=(1, 2, 3))
    with pytest.raises(aosr.InvalidArgument, match="not together"):
        aosr.psf("paper-8m", field_angle=3, field_direction=(1, 2))
    with pytest.raises(aosr.InvalidArgument, match="field_direction"):
        aosr.psf("paper-8m", field_angle=float("nan"))


def test_closed_loop_psf_antithetic_pair(cli):
    kw = dict(mode="closed-loop", sensor="ideal", size=32, exposure=0.1, settling=0.05)
    pair = aosr.psf("paper-8m", **kw)
    one = aosr.psf("paper-8m", antithetic=False, **kw)
    assert pair["closed_loop"]["antithetic"] and not one["closed_loop"]["antithetic"]
    c = pair["core_centroid_lambda_over_d"]
    assert abs(c["y"]) < 1e-9 and abs(c["x"]) < 1e-9  # the stretch's random tilt cancels in the pair
    assert max(abs(v) for v in one["core_centroid_lambda_over_d"].values()) > 1e-4
    j = json.loads(cli("psf", "paper-8m", "--mode", "closed-loop", "--sensor", "ideal", "--size", 32,
                       "--exposure", 0.1, "--settling", 0.05, "--json").stdout)
    assert j["core_centroid_lambda_over_d"] == c and j["strehl"] == pair["strehl"]
    j1 = json.loads(cli("psf", "paper-8m", "--mode", "closed-loop", "--sensor", "ideal", "--size", 32,
                        "--exposure", 0.1, "--settling", 0.05, "--no-antithetic", "--json").stdout)
    assert not j1["closed_loop"]["antithetic"]
    assert j1["core_centroid_lambda_over_d"] == one["core_centroid_lambda_over_d"]


def test_calibrate_matches_cli(cli, tmp_path):
    spec = tmp_path / "small.json"
    spec.write_text(json.dumps({"telescope": "paper-bench", "calibration": {
        "pixel_lambda_over_d": 0.3115, "window_px": [32, 32], "modes": [4, 5], "gains": [0.9, 1.1],
        "amplitudes_nm": [40, 80], "references_per_mode": 1, "static_nm": {"4": 10}, "seed": 3}}))
    cli("calibrate", "--synthesize", spec, "-o", tmp_path / "set")
    cli("calibrate", tmp_path / "set", "-o", tmp_path / "cal", "--threads", 2, "--static-max-noll", 4)
    expected = json.loads((tmp_path / "cal" / "calibration.json").read_text())
    s = aosr.synthesize_calibration(spec)
    assert bits_equal(s.frames, aosr.CalibrationSet.load(tmp_path / "set").frames)
    got = aosr.calibrate(tmp_path / "set", threads=2, static_max_noll=4)
    assert got["modes"] == expected["modes"]
    in_memory = aosr.calibrate(s, threads=1, static_max_noll=4)
    assert [m["gain"] for m in in_memory["modes"]] == [m["gain"] for m in expected["modes"]]


def test_stubs_and_docstrings_cover_the_module():
    import ast
    from aosr import _aosr
    stub = ast.parse(open(os.path.join(os.path.dirname(aosr.__file__), "_aosr.pyi")).read())
    declared = {n.name for n in stub.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
    public = {n for n in dir(_aosr) if not n.startswith("_")}
    assert public - declared == set()
    for name in ("reconstruct", "simulate", "evaluate", "psf", "design", "calibrate", "open_dataset", "read_fits"):
        assert len(getattr(aosr, name).__doc__) > 200, name
    assert "super-resolves" in aosr.reconstruct.__doc__.lower()
    assert os.path.exists(os.path.join(os.path.dirname(aosr.__file__), "py.typed"))


def test_evaluate_stars_match_cli(cli, tmp_path):
    """The star-field part (photometry and centroids of the brightest stars), same library call as the CLI."""
    data = tmp_path / "cs"
    cli("simulate", aosr.data_path("scenes", "crowded-stars.json"), "-o", data, "--json")
    rec = aosr.reconstruct(data, "tikhonov")
    aosr.write_fits(tmp_path / "t.fits", rec.image, dtype="float64")
    j = json.loads(cli("evaluate", "--manifest", data, "--estimate", tmp_path / "t.fits", "--stars", 10, "--json").stdout)
    m = aosr.evaluate(rec.image, dataset=data, stars=10)
    assert m["stars"]["measured"] > 0
    for k in ("measured", "skipped_at_edge", "median_abs_flux_error", "rms_position_error_hr_px", "brightest"):
        assert m["stars"][k] == j["stars"][k], k
