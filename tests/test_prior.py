import numpy as np
import pytest

from ipm.params import PAPER_INTERVALS
from ipm.prior import GuidedPrior


def test_draws_stay_inside_the_value_intervals():
    draws = GuidedPrior().sample_many(2000, seed=11)
    for k, iv in PAPER_INTERVALS.items():
        v = np.array([getattr(p, k) for p in draws])
        assert v.min() >= iv.lo and v.max() <= iv.hi, k
    assert {p.n for p in draws} == {2, 3, 4, 5, 6}


def test_raw_yarn_relations_of_the_sampler():
    for p in GuidedPrior().sample_many(300, seed=3):
        r_frac = p.r_y / p.r_x
        lo = {2: 0.67, 3: 0.72}.get(p.n, 0.85)
        hi = {2: 0.9, 3: 0.91}.get(p.n, 0.95)
        assert lo - 1e-12 <= r_frac <= hi + 1e-12
        assert p.t_y <= p.t_x <= 2.5 * p.t_y
        area_ply = p.m * p.t_x * p.t_y / (p.r_x * p.r_y)
        assert 0.035 - 1e-9 <= area_ply <= 0.215 + 1e-9
        # alpha and alpha_ply twist in opposite directions, helix angles in [50, 80] degrees
        gamma = np.degrees(np.arctan(-p.alpha / (2 * np.pi * p.r_x)))
        gamma_ply = np.degrees(np.arctan(p.alpha_ply / (2 * np.pi * p.R_ply)))
        assert 50 - 1e-6 <= gamma <= 80 + 1e-6 and 50 - 1e-6 <= gamma_ply <= 80 + 1e-6


def test_seeded():
    a, b = GuidedPrior().sample_many(5, seed=1), GuidedPrior().sample_many(5, seed=1)
    assert a == b and a != GuidedPrior().sample_many(5, seed=2)


def test_flyaways_drawn_in_the_real_yarns_ranges_unless_asked_for_the_paper_intervals():
    from ipm.presets import PRESET_NAMES, preset
    from ipm.prior import FLYAWAY_RANGES

    real = GuidedPrior().sample_many(400, seed=7)
    paper = GuidedPrior(flyaways="paper").sample_many(400, seed=7)
    for k, (lo, hi) in FLYAWAY_RANGES.items():
        v = [getattr(p, k) for p in real]
        assert lo <= min(v) and max(v) <= hi, k
        # every one of the paper's real yarns lies inside the box
        assert all(lo <= getattr(preset(name), k) <= hi for name in PRESET_NAMES), k
    # the paper's whole intervals reach the 35 mm loops and 14 mm hairs the box leaves out
    assert max(p.l_loop for p in paper) > 25 and max(p.l_hair for p in paper) > 10
    assert max(p.l_loop for p in real) < 17 and max(p.l_hair for p in real) < 6.3


def test_fine_yarns_are_thin_dense_spun_yarns_inside_the_intervals():
    """``yarns="fine"``: every draw inside the paper's intervals, its envelope 0.15-0.6 mm,
    2-4 plies, denser than the knitting yarns (fibers' area in a ply); the paper's sampler
    is the default and unknown kinds are one line."""
    from ipm.errors import UserError

    fine = GuidedPrior(yarns="fine").sample_many(200, seed=5)
    knitting = GuidedPrior().sample_many(200, seed=5)
    for p in fine:
        for k, iv in PAPER_INTERVALS.items():
            assert iv.lo <= getattr(p, k) <= iv.hi, k
        assert 0.15 <= 2 * (p.R_ply + max(p.r_x, p.r_y)) <= 0.6
        assert 2 <= p.n <= 4

    def density(p):
        return p.m * np.pi * p.t_x * p.t_y / (np.pi * p.r_x * p.r_y)

    assert np.median([density(p) for p in fine]) > 2 * np.median([density(p) for p in knitting])
    assert GuidedPrior(yarns="knitting").sample_many(5, 1) == GuidedPrior().sample_many(5, 1)
    with pytest.raises(UserError, match="unknown kind of yarns 'wool'"):
        GuidedPrior(yarns="wool")
