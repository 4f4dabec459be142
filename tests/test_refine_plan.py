"""The fit as named stages (ipm.refine.plan) and the capture setups' one home (ipm.setups):
no renders."""

import inspect
import re
from pathlib import Path

import pytest

from ipm.errors import UserError
from ipm.refine.plan import FitConfig, plan
from ipm.refine.search import parse_stages
from ipm.setups import NAMES, SETUPS, setup_of

ROOT = Path(__file__).resolve().parents[1]


def names(config, setup, probability=0.9, outside=False):
    return [s.name for s in plan(config, setup, probability, outside).stages]


def test_a_fit_chooses_the_ply_count_when_its_search_moves_the_pitch():
    """Where the setup's loss tells the count, with the nets' probabilities, a ply-count
    stage comes before the first stage that moves alpha_ply; with --nets-ply-count, without
    probabilities, without a pitch stage or in a setup without such groups, none."""
    behind, front = (next(s.name for s in SETUPS.values() if s.light_behind is b)
                     for b in (True, False))
    assert names(FitConfig(), behind) == ["ply count", "ply twist"]
    assert names(FitConfig(), front) == ["ply twist"]
    assert names(FitConfig(nets_ply_count=True), behind) == ["ply twist"]
    assert names(FitConfig(), behind, None) == ["ply twist"]
    staged = FitConfig(params="R_ply,r_x,r_y;alpha_ply")
    assert names(staged, behind) == ["thickness", "ply count", "ply twist"]
    assert names(FitConfig(params="R_ply,r_x,r_y"), behind) == ["thickness"]
    count = plan(staged, behind, 0.9).stages[1]
    assert count.search is None and count.scored_by == setup_of(behind).count_groups


def test_the_gates_choose_other_stages_up_front():
    """Outside the nets' range: the setup's outside stages with a polish, the cover kept,
    one seed per evaluation and no prior; an unsure count: the stages without alpha_ply."""
    for setup in SETUPS.values():
        if setup.outside_stages is None:
            assert not FitConfig().gates_outside(setup.name)
            continue
        assert FitConfig().gates_outside(setup.name)
        assert FitConfig(params=setup.stages).gates_outside(setup.name)
        assert not FitConfig(prior=False).gates_outside(setup.name)
        assert not FitConfig(params="R_ply").gates_outside(setup.name)
        outside = plan(FitConfig(budget=8), setup.name, None, outside=True)
        assert tuple(s.params for s in outside.stages) == parse_stages(setup.outside_stages)
        assert outside.gate and not outside.prior and outside.seeds_per_eval == 1
        thickness, flyaways, twist = (s.search for s in outside.stages)
        assert thickness.keep_cover and thickness.polish > 0 and flyaways.polish > 0
        assert thickness.budget >= 2 * 4 + 2  # the least a four-parameter stage takes
        assert [s.scored_by for s in outside.stages] == [None, ("flyaways",),
                                                         setup.pitch_groups]
        assert outside.stages[0].without == ("contour",)
    front = next(s.name for s in SETUPS.values() if not s.count_groups)
    unsure = plan(FitConfig(), front, 0.3)
    assert unsure.gate == "unsure ply count" and unsure.stages == ()
    assert names(FitConfig(params="R_ply;alpha_ply"), front, 0.3) == ["thickness"]
    assert names(FitConfig(sure_count=0.0), front, 0.3) == ["ply twist"]
    assert plan(FitConfig(), front, 0.6).gate is None


@pytest.mark.parametrize("kw, match", [(dict(params="n"), "cannot search"),
                                       (dict(params="alpha_ply;"), "cannot search"),
                                       (dict(algorithm="LN_FOO"), "unknown algorithm"),
                                       (dict(params="R_ply,r_x,r_y", budget=6),
                                        "at least 8 evaluations for 3"),
                                       (dict(polish=3), "polish must be"),
                                       (dict(scale=2.0), "scales must be")])
def test_a_bad_config_is_one_line(kw, match):
    with pytest.raises(UserError, match=match):
        FitConfig(**kw)


def test_the_commands_take_their_fit_options_from_the_config():
    from ipm.refine import commands

    options = [f for f, v in FitConfig.__dataclass_fields__.items() if "help" in v.metadata]
    assert len(options) > 10
    for command in (commands.fit, commands.compare):
        parameters = inspect.signature(command).parameters
        assert set(options) <= set(parameters) and "config" not in parameters


def test_only_the_setups_module_names_a_setup():
    """No setup name in the library's code, docstrings or help but in ipm/setups.py; each
    setup's shipped nets are where its record says."""
    from ipm.nets.ensemble import SHIPPED_FOR

    word = re.compile("|".join(NAMES))
    found = [f"{path.relative_to(ROOT)}:{i}" for folder in ("ipm", "render", "refine", "nets")
             for path in sorted((ROOT / folder).glob("*.py")) if path.name != "setups.py"
             for i, line in enumerate(path.read_text().splitlines(), 1) if word.search(line)]
    assert not found, found
    for name, folder in SHIPPED_FOR.items():
        assert folder.name == setup_of(name).models and (folder / "ensemble.json").is_file()
