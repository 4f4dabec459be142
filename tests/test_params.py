import json

import numpy as np
import pytest

from ipm.errors import ParamError, UserError
from ipm.params import PAPER_INTERVALS, PARAM_ORDER, YarnParams
from ipm.presets import PRESET_NAMES, preset


def test_json_keys_are_the_paper_symbols():
    d = json.loads(preset("golden").to_json())
    assert set("n m t_x t_y alpha r_x r_y alpha_ply R_ply j j_xy j_z g p beta l_hair s l_loop "
               "d_mean d_std".split()) <= set(d)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_presets_roundtrip_json_and_vector(name):
    p = preset(name)
    assert YarnParams.from_json(p.to_json()) == p
    v = p.to_vector()
    assert v.shape == (len(PARAM_ORDER),) and np.all((v >= 0) & (v <= 1))
    back = YarnParams.from_vector(v, base=p)
    for k in PARAM_ORDER:
        assert getattr(back, k) == pytest.approx(getattr(p, k), rel=1e-12, abs=1e-12)


def test_golden_preset_matches_the_supplemental_tables():
    p = preset("golden")
    assert (p.n, p.alpha_ply, p.R_ply, p.alpha, p.r_x, p.r_y, p.m) == \
        (3, 6.474, 0.289, -2.392, 0.241, 0.195, 43)
    assert (p.g, p.p, p.l_hair, p.beta, p.s, p.l_loop, p.d_mean, p.d_std, p.j_xy, p.j) == \
        (123, 0.50, 2.26, 0.77, 0.44, 4.48, 4.44, 2.08, 0.014, 0.19)
    assert p.thickness == "thick" and preset("red").thickness == "thin"


def test_out_of_range_names_field_value_and_range():
    with pytest.raises(ParamError, match=r"R_ply = 3\.0 is outside its allowed range \[0\.053, "
                                         r"1\.486\] mm"):
        preset("golden").replace(R_ply=3.0)


@pytest.mark.parametrize("bad, match", [({"n": 2.5}, "n: expected an integer"),
                                        ({"alpha": "x"}, "alpha: expected a number"),
                                        ({"g": True}, "g: expected an integer"),
                                        ({"p": float("nan")}, "p = nan is outside")])
def test_wrong_types_are_named(bad, match):
    d = preset("rose").to_dict() | bad
    with pytest.raises(ParamError, match=match):
        YarnParams.from_dict(d)


def test_missing_field_is_named():
    d = preset("rose").to_dict()
    del d["l_loop"]
    with pytest.raises(ParamError, match="missing parameter.*l_loop"):
        YarnParams.from_dict(d)


def test_fourth_level_needs_its_helix():
    with pytest.raises(ParamError, match="n_yarn > 1"):
        preset("rose").replace(n_yarn=2)


def test_vector_clips_and_rounds():
    p = YarnParams.from_vector(np.full(len(PARAM_ORDER), 1.7))
    assert p.n == 6 and p.R_ply == PAPER_INTERVALS["R_ply"].hi


def test_a_yarn_is_loaded_from_what_any_command_writes(tmp_path):
    """Flat (`ipm sample`), a render's sidecar (under `params`) and a fit's params.json
    (`refined`, else `neural`): each command that takes a yarn takes all three."""
    neural, refined = preset("golden"), preset("golden").replace(alpha_ply=5.0)
    files = {"flat.json": refined.to_dict(),
             "sidecar.json": {"params": refined.to_dict(), "spp": 16},
             "fit.json": {"neural": neural.to_dict(), "refined": refined.to_dict()},
             "neural-only.json": {"neural": refined.to_dict(), "loss": {"neural": 0.1}}}
    for name, content in files.items():
        (tmp_path / name).write_text(json.dumps(content))
        assert YarnParams.load(tmp_path / name) == refined, name
    with pytest.raises(UserError, match="no such file"):
        YarnParams.load(tmp_path / "missing.json")
