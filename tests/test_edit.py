"""ipm edit's rules: set, scale, whole integers, and one-line errors."""

import pytest

from ipm.edit import apply_edits
from ipm.errors import ParamError
from ipm.presets import preset


def test_set_and_scale():
    p = preset("golden")
    q = apply_edits(p, ["alpha_ply=*0.5", "g=*2", "R_ply=0.3"])
    assert q.alpha_ply == pytest.approx(p.alpha_ply / 2)
    assert q.g == 2 * p.g and isinstance(q.g, int)
    assert q.R_ply == 0.3 and q.alpha == p.alpha


def test_integers_stay_whole_after_scaling():
    assert apply_edits(preset("golden"), ["m=*2"]).m == 86
    with pytest.raises(ParamError, match="m is an integer"):
        apply_edits(preset("golden"), ["m=*1.5"])


@pytest.mark.parametrize("spec, words", [
    ("twist=2", "unknown parameter 'twist'"), ("alpha_ply", "expected NAME=VALUE"),
    ("alpha_ply=*abc", "not a number"), ("alpha_ply=*100", "outside its allowed range"),
    ("g=*0.01", "outside its allowed range"), ("n=nan", "not a finite number")])
def test_bad_edits_name_the_edit(spec, words):
    with pytest.raises(ParamError, match=words) as e:
        apply_edits(preset("golden"), [spec])
    assert spec.split("=")[0] in str(e.value) and "\n" not in str(e.value)
