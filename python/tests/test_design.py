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
    assert j["gain"]["db"] > 1.0 and j["gain"]["stderr_db"] < 0.2
    assert j["design"]["design"]["gain"] == j["gain"]
    k = aosr.design(aosr.data_path("scenes", "paper-sim-r2.json"), param="tiptilt", iterations=5, **common)
    assert k["gain"]["advice"] == "raster"
    high = aosr.design(aosr.data_path("scenes", "paper-sim-j-r2.json"), param="tiptilt", iterations=15,
                       min_gain=10.0, **common)
    assert high["gain"]["advice"] == "raster" and not high["improved"]
    with pytest.raises(aosr.InvalidArgument, match="min_gain"):
        aosr.design(aosr.data_path("scenes", "paper-sim-r2.json"), min_gain=-1.0)
