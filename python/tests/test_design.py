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


@pytest.mark.parametrize("kwargs,needle", [({"param": "fancy"}, "param"), ({"objective": "C"}, "objective"),
                                           ({"starts": 0}, "starts")])
def test_design_errors(kwargs, needle):
    with pytest.raises(aosr.InvalidArgument, match=needle):
        aosr.design(aosr.data_path("scenes", "paper-sim-r2.json"), **kwargs)
