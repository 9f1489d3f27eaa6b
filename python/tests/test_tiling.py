"""aosr.reconstruct(..., tile=T): the tiled reconstruction (include/aosr/solvers/tiling.hpp) from Python, against
the whole-grid one and against `aosr reconstruct --tile` (the same bits)."""
import json

import numpy as np
import pytest

import aosr


def test_tiled_matches_whole_grid_and_the_cli(demo_dir, cli, tmp_path):
    whole = aosr.reconstruct(demo_dir, "tikhonov", lambda_=0.01)
    tiled = aosr.reconstruct(demo_dir, "tikhonov", lambda_=0.01, tile=32, tile_overlap=12)
    assert tiled.image.shape == whole.image.shape
    assert "tiled: 4 x 4 tiles" in tiled.summary["message"]
    peak = np.abs(whole.image).max()
    # Measured 3.4e-4 of the peak: the periodic tiles' truncation at this overlap (solvers/tiling.hpp).
    assert np.abs(tiled.image - whole.image).max() < 1e-3 * peak
    # The CLI's file holds float32 of the same image.
    out = tmp_path / "t.fits"
    p = cli("reconstruct", demo_dir, "-m", "tikhonov", "--lambda", "0.01", "--tile", "32", "--tile-overlap", "12",
            "-o", out, "--json")
    j = json.loads(p.stdout)
    assert j["tiling"]["tiles"] == [4, 4] and j["tiling"]["overlap"] == 12
    image, _ = aosr.read_fits(out)
    assert np.array_equal(image.astype(np.float32), tiled.image.astype(np.float32))
    assert j["summary"]["message"] == tiled.summary["message"]


def test_the_automatic_overlap_is_measured_for_the_linear_methods(demo_dir):
    # tikhonov and linear: the overlap from the method's response, to hold the tiled error below tile_tolerance
    # (solvers/tiling.hpp, "The overlap rule"); the summary says how it was made. A looser bound, a smaller overlap.
    import re
    overlaps = []
    for tolerance in (1e-6, 0.3):
        rec = aosr.reconstruct(demo_dir, "tikhonov", lambda_=0.01, tile=32, tile_tolerance=tolerance)
        assert "measured: tikhonov's response" in rec.summary["message"]
        overlaps.append(int(re.search(r"overlap (\d+)", rec.summary["message"]).group(1)))
    assert overlaps[1] < overlaps[0]


def test_one_regularisation_for_the_field(demo_dir):
    rec = aosr.reconstruct(demo_dir, "tv", tile=64, iterations=20)
    assert "whole field" in rec.summary["message"]
    assert rec.regularisation > 0


@pytest.mark.parametrize("kwargs,needle", [
    ({"tile": -1}, "tile = -1"),
    ({"tile_overlap": 3}, "tile_overlap"),
    ({"tile": 32, "tile_tolerance": 0.0}, "tile_tolerance"),
    ({"tile": 32, "tile_overlap": -4}, "overlap = -4"),
    ({"tile": 32, "tile_overlap": 40}, "overlap"),
])
def test_bad_tiling_raises_invalid_argument(demo_dir, kwargs, needle):
    with pytest.raises(aosr.InvalidArgument, match=needle):
        aosr.reconstruct(demo_dir, "tikhonov", **kwargs)


def test_resume_gives_the_same_bytes(demo_dir, tmp_path):
    plain = aosr.reconstruct(demo_dir, "tikhonov", tile=64)
    first = aosr.reconstruct(demo_dir, "tikhonov", tile=64, resume=str(tmp_path))
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"tile_{k}.bin" for k in range(4)]
    (tmp_path / "tile_1.bin").unlink()
    again = aosr.reconstruct(demo_dir, "tikhonov", tile=64, resume=str(tmp_path))
    assert "3 tiles resumed" in again.summary["message"]
    for rec in (first, again):
        assert np.array_equal(rec.image.view(np.uint64), plain.image.view(np.uint64))


def test_a_whole_detector_goes_by_tiles_under_the_memory_limit(demo_dir, cli, tmp_path):
    """memory_limit below the whole grid's need: tiles without a whole-grid model (FieldData), as the CLI's
    --memory-limit does; the same tiles as the whole-grid model's, the same image as the CLI's row-written file."""
    kw = dict(lambda_=0.01, tile=32, tile_overlap=12)
    held = aosr.reconstruct(demo_dir, "tikhonov", **kw)
    assert held.memory_plan is None
    small = aosr.reconstruct(demo_dir, "tikhonov", memory_limit="4M", **kw)
    plan = small.memory_plan
    assert plan is not None
    assert plan["whole_grid_bytes"] > 4 * 1024**2 and plan["memory_limit_bytes"] == 4 * 1024**2
    assert (plan["tile"], plan["tile_overlap"]) == (32, 12)
    peak = np.abs(held.image).max()
    # The window models are the kernels cut by the rule CutModel applies to whole-grid kernels (tiling.hpp).
    assert np.abs(small.image - held.image).max() < 1e-9 * peak
    # By path the frames are read by sections (each tile's window), never held; an opened Dataset holds them: the
    # same bytes either way.
    opened = aosr.reconstruct(aosr.open_dataset(demo_dir), "tikhonov", memory_limit="4M", **kw)
    assert np.array_equal(opened.image.view(np.uint64), small.image.view(np.uint64))
    assert opened.masked_pixels == small.masked_pixels
    out = tmp_path / "rows.fits"
    p = cli("reconstruct", demo_dir, "-m", "tikhonov", "--lambda", "0.01", "--tile", "32", "--tile-overlap", "12",
            "--memory-limit", "4M", "-o", out, "--json")
    assert "output_by_rows" in json.loads(p.stdout)
    image, _ = aosr.read_fits(out)
    assert np.abs(image - small.image).max() < 1e-6 * peak
    # Tiles chosen to fit when none are given; a limit that no tiling fits is a ResourceError before any work.
    auto = aosr.reconstruct(demo_dir, "tikhonov", lambda_=0.01, memory_limit=4 * 1024**2)
    assert auto.memory_plan["tile"] > 0 and auto.image.shape == held.image.shape
    assert np.isfinite(auto.image).all()
    with pytest.raises(aosr.ResourceError, match="memory"):
        aosr.reconstruct(demo_dir, "tikhonov", lambda_=0.01, memory_limit="300K")


@pytest.mark.parametrize("limit", [-1, 0, float("nan"), "lots", "12Q"])
def test_bad_memory_limit_raises_invalid_argument(demo_dir, limit):
    with pytest.raises(aosr.InvalidArgument, match="memory_limit"):
        aosr.reconstruct(demo_dir, "tikhonov", memory_limit=limit)


@pytest.mark.parametrize("phase, hook", [("plan", lambda first, last: None), ("blend", "not callable")])
def test_tile_jobs_refuse_an_await_hook_they_cannot_use(demo_dir, phase, hook):
    """The jobs' entry point (aosr.distributed.reconstruct_tiles' phases): await_tiles only as a callable, only
    with the blend, and refused by name before any work."""
    with pytest.raises(aosr.InvalidArgument, match="await_tiles"):
        aosr._aosr._tiles(demo_dir, "tikhonov", phase=phase, tile=32, await_tiles=hook)
