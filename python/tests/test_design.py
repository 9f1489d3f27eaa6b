"""aosr.design against `aosr design` (the same library study, design/design_study.hpp)."""
import json

import pytest

import aosr

ARGS = {"param": "tiptilt", "starts": 1, "iterations": 3, "realisations": 0, "validation_realisations": 0}


def test_design_matches_cli(cli, tmp_path):
    scene = aosr.data_path("scenes", "paper-sim-r2.json")
    p = cli("design", scene, "--param", "tiptilt", "--starts", 1, "--iterations", 3, "--realisations", 0,
            "--validation-realisations", 0, "--json", "-o", tmp_path / "cli.json")
    expected = json.loads(p.stdout)
    got = aosr.design(scene, output=tmp_path / "py.json", **ARGS)
    assert got["design"] == json.loads((tmp_path / "cli.json").read_text())
    assert json.loads((tmp_path / "py.json").read_text()) == got["design"]
    for k in ("objective_raster", "objective_start", "objective_final", "parameters", "termination", "message"):
        assert got[k] == expected[k], k
    assert aosr.design(aosr.load_scene(scene), **ARGS)["design"]["frames"] == got["design"]["frames"]
    # The modal content (Noll 2..36, nm RMS): a tip/tilt design lives in Z2 and Z3 only, like its raster.
    mc = got["design"]["design"]["modal_content"]
    assert mc["noll"] == list(range(2, 37)) and len(mc["frames"]) == len(got["design"]["frames"])
    rms = mc["rms_over_frames_nm"]
    assert max(rms[:2]) > 1.0 and max(rms[2:]) < 1e-6 * max(rms[:2])
    assert max(mc["raster"]["rms_over_frames_nm"][2:]) < 1e-6 * max(rms[:2])


@pytest.mark.parametrize("kwargs,needle", [({"param": "fancy"}, "param"), ({"objective": "C"}, "objective"),
                                           ({"starts": 0}, "starts")])
def test_design_errors(kwargs, needle):
    with pytest.raises(aosr.InvalidArgument, match=needle):
        aosr.design(aosr.data_path("scenes", "paper-sim-r2.json"), **kwargs)


def test_design_reports_the_gain_and_advice():
    # Issue 25: J band on the 8 m at r = 2 gains over the raster; the K-band paper scene keeps the raster.
    common = dict(starts=1, realisations=1, screens=2, validation_realisations=3, threads=1)
    j = aosr.design(aosr.data_path("scenes", "paper-sim-j-r2.json"), param="tiptilt", iterations=15, **common)
    assert j["gain"]["advice"] == "design"
    # Judged on a sky 4x finer than the HR grid; the HR grid's own sky (what objective A optimises) flatters it.
    assert j["gain"]["sky_oversampling"] == 4
    assert j["gain"]["db"] > 0.5 and j["gain"]["stderr_db"] < 0.2
    assert j["gain"]["hr_grid_sky"]["db"] > max(1.0, j["gain"]["db"] + 0.5)
    assert j["design"]["design"]["gain"] == j["gain"]
    grid = aosr.design(aosr.data_path("scenes", "paper-sim-j-r2.json"), param="tiptilt", iterations=15,
                       sky_oversampling=1, **common)
    assert grid["gain"]["hr_grid_sky"] is None
    assert grid["gain"]["db"] == pytest.approx(j["gain"]["hr_grid_sky"]["db"], abs=1e-12)
    with pytest.raises(aosr.InvalidArgument, match="sky_oversampling"):
        aosr.design(aosr.data_path("scenes", "paper-sim-r2.json"), sky_oversampling=0)
    k = aosr.design(aosr.data_path("scenes", "paper-sim-r2.json"), param="tiptilt", iterations=5, **common)
    assert k["gain"]["advice"] == "raster"
    high = aosr.design(aosr.data_path("scenes", "paper-sim-j-r2.json"), param="tiptilt", iterations=15,
                       min_gain=10.0, **common)
    assert high["gain"]["advice"] == "raster" and not high["improved"]
    with pytest.raises(aosr.InvalidArgument, match="min_gain"):
        aosr.design(aosr.data_path("scenes", "paper-sim-r2.json"), min_gain=-1.0)


def test_design_over_the_field():
    # Issue 31 item 7: a scene with a psf_field is designed over its points; the report gives each point's gain and
    # the on-axis advice, the same numbers as `aosr design --json`'s "field".
    scene = aosr.read_json(aosr.data_path("scenes", "paper-sim-j-r2.json"))
    scene["detector"]["frame_px"] = [100, 200]
    scene["psf_field"] = {"guide_star_arcsec": [-10.0, 0.0], "grid": [1, 3]}
    j = aosr.design(aosr.Scene(scene, "field.json"), param="tiptilt", starts=1, iterations=4, realisations=0, threads=1)
    f = j["field"]
    assert f["points"] == 3 and len(f["per_point"]) == 3
    far = [p["direction_arcsec"][0] for p in f["per_point"]]
    assert far == sorted(far)
    # Anisoplanatism: the raster's expected MSE grows away from the guide star; the field mean is what was judged.
    raster = [p["objective_raster"] for p in f["per_point"]]
    assert raster == sorted(raster) and f["on_axis"]["objective_raster"] < raster[0]
    assert j["gain"]["objective_raster"] == pytest.approx(sum(raster) / 3, rel=1e-12)
    assert f["advice_changes"] == (f["on_axis"]["advice"] != j["gain"]["advice"])
    assert j["design"]["design"]["field"] == f
