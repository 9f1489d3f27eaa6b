"""aosr.tradeoff: the accuracy/time sweep of `aosr tradeoff` (include/aosr/solvers/tradeoff.hpp) from Python; the
same rows as the CLI's JSON, seconds aside."""
import json

import pytest

import aosr

KEYS = ("method", "knob", "iterations", "termination", "psnr_db", "ssim", "misfit", "change", "regularisation")


def test_tradeoff_gives_the_cli_rows(cli, demo_dir, tmp_path):
    common = dict(methods=["drizzle", "tikhonov", "linear"], lambda_factors=[0.1], target_factors=[1.5])
    t = aosr.tradeoff(demo_dir, **common)
    assert t["methods"] == common["methods"] and t["has_truth"] and not t["cancelled"]
    assert [r["method"] for r in t["rows"]] == ["drizzle", "tikhonov", "tikhonov", "linear", "linear"]
    gcv = [r for r in t["rows"] if r["method"] == "tikhonov" and r["lambda_factor"] == 1.0][0]
    assert gcv["psnr_db"] > 20 and "GCV" in gcv["knob"]
    assert [r for r in t["rows"] if r["method"] == "linear"][0]["scored_through"] == "its effective PSF"
    p = cli("tradeoff", demo_dir, "-o", tmp_path / "t", "--methods", "drizzle,tikhonov,linear",
            "--lambda-factors", "0.1", "--target-factors", "1.5", "--json")
    rows = json.loads(p.stdout)["rows"]
    assert len(rows) == len(t["rows"])
    for a, b in zip(rows, t["rows"]):
        for k in KEYS:
            assert a[k] == pytest.approx(b[k], rel=1e-12, abs=0) if isinstance(a[k], float) else a[k] == b[k], k


def test_tradeoff_refuses_bad_options_by_name(demo_dir):
    with pytest.raises(aosr.InvalidArgument, match="methods"):
        aosr.tradeoff(demo_dir, methods=["wiener"])
    with pytest.raises(aosr.InvalidArgument, match="lambda_factors"):
        aosr.tradeoff(demo_dir, lambda_factors=[1.0])
    with pytest.raises(aosr.InvalidArgument, match="iterations"):
        aosr.tradeoff(demo_dir, iterations=[0])
    # A cancelled sweep stops after the run it cancelled.
    t = aosr.tradeoff(demo_dir, methods=["tv", "map"], iterations=[50], progress=lambda p: False)
    assert t["cancelled"] and len(t["rows"]) == 1 and t["rows"][0]["termination"] == "cancelled"
