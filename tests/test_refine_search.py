"""The NLopt search machinery on an analytic objective (no renderer needed)."""

from dataclasses import replace

import numpy as np
import pytest

from ipm.errors import UserError
from ipm.params import PAPER_INTERVALS
from ipm.presets import preset
from ipm.prior import FLYAWAY_RANGES
from ipm.refine.search import (
    ALGORITHMS,
    SearchOptions,
    Stage,
    likeliest_counts,
    ply_count_scores,
    same_period,
    search,
    search_box,
    search_ply_counts,
    search_stages,
)

TRUTH = preset("golden")
NAMES = ("alpha", "alpha_ply", "R_ply")
#: The ply count's choice, as a stage.
COUNT = Stage("ply count")


def staged(*stages, **kw):
    """A stage searching each tuple of ``stages`` (``SearchOptions(**kw)``); COUNT as is."""
    return [s if isinstance(s, Stage) else Stage("s", SearchOptions(params=s, **kw))
            for s in stages]


def quadratic(p, seed):
    """Distance to TRUTH in units of the prior range, plus seed noise of 1e-4."""
    d = [(getattr(p, k) - getattr(TRUTH, k)) / PAPER_INTERVALS[k].width
         for k in NAMES]
    return float(np.sum(np.square(d))) + 1e-4 * (seed % 3)


@pytest.mark.parametrize("algorithm", ["LN_BOBYQA", "LN_SBPLX", "LN_NELDERMEAD", "GN_DIRECT_L"])
def test_finds_the_minimum_from_a_perturbed_start(algorithm):
    start = TRUTH.replace(alpha=TRUTH.alpha - 1.5, alpha_ply=TRUTH.alpha_ply + 2.0,
                          R_ply=TRUTH.R_ply + 0.1)
    evals = []
    res = search(quadratic, start, SearchOptions(params=NAMES, algorithm=algorithm, budget=150),
                 on_eval=lambda i, loss, best: evals.append((i, loss, best)))
    assert res.improved and res.best_loss < res.start_loss
    for k in NAMES:
        iv = PAPER_INTERVALS[k]
        assert abs(getattr(res.best, k) - getattr(TRUTH, k)) < 0.01 * iv.width, k
    assert len(evals) == res.evaluations <= 150 and evals[-1][2] == min(res.trace)
    # the other fields are kept
    assert res.best.replace(**{k: getattr(start, k) for k in NAMES}) == start


def test_stays_in_the_box_and_the_prior():
    start = TRUTH.replace(R_ply=PAPER_INTERVALS["R_ply"].lo)
    lo, hi = search_box(start, NAMES, 0.1)
    assert lo[2] == PAPER_INTERVALS["R_ply"].lo and np.all(hi > lo)
    seen = []
    search(lambda p, s: seen.append(p) or quadratic(p, s), start,
           SearchOptions(params=NAMES, budget=40, width=0.1))
    vals = np.array([[getattr(p, k) for k in NAMES] for p in seen])
    assert np.all(vals >= lo - 1e-9) and np.all(vals <= hi + 1e-9)


def test_an_integer_parameter_is_searched_at_whole_values():
    """The fibers per ply ``m``: every render gets a whole ``m``, and a staircase loss with
    its lowest step at the truth is found from a start 15 fibers off."""
    seen = []

    def loss(p, seed):
        seen.append(p.m)
        return abs(p.m - TRUTH.m) + 1e-4 * (seed % 3)

    res = search(loss, TRUTH.replace(m=TRUTH.m + 15), SearchOptions(params=("m",), budget=30))
    assert all(isinstance(m, int) for m in seen) and len(set(seen)) > 3
    assert res.improved and res.best.m == TRUTH.m


def test_keeps_the_start_when_nothing_is_better():
    res = search(quadratic, TRUTH, SearchOptions(params=NAMES, budget=30))
    assert not res.improved and res.best is TRUTH


def test_deterministic():
    start = TRUTH.replace(alpha=-4.0)
    a = search(quadratic, start, SearchOptions(params=NAMES, budget=30))
    b = search(quadratic, start, SearchOptions(params=NAMES, budget=30))
    assert a.trace == b.trace and a.best == b.best


@pytest.mark.parametrize("kw, match", [(dict(params=("n",)), "cannot search"),
                                       (dict(algorithm="LN_FOO"), "unknown algorithm"),
                                       (dict(budget=3), "budget must be"),
                                       (dict(width=0.0), "width"),
                                       (dict(time_s=0.0), "time must be"),
                                       (dict(time_s=-1.0), "time must be"),
                                       (dict(time_s=float("nan")), "time must be")])
def test_bad_options(kw, match):
    with pytest.raises(UserError, match=match):
        SearchOptions(**kw)


def test_all_listed_algorithms_exist():
    import nlopt

    for a in ALGORITHMS:
        nlopt.opt(getattr(nlopt, a), 2)


def test_prior_keeps_the_search_near_the_start_when_the_loss_is_noise():
    """A loss whose pull toward TRUTH is small against its seed noise moves the MAP search
    far less than the plain search; the box is box_sigmas * sigma around the start."""
    start = TRUTH.replace(alpha=TRUTH.alpha - 1.5, alpha_ply=TRUTH.alpha_ply + 2.0,
                          R_ply=TRUTH.R_ply + 0.1)
    sigma = {"alpha": 0.5, "alpha_ply": 0.5, "R_ply": 0.02}

    def weak(p, seed):
        return 1e-3 * quadratic(p, 0) + 1e-3 * (seed % 3)

    plain = search(weak, start, SearchOptions(params=NAMES, budget=60))
    seen = []
    prior = search(lambda p, s: seen.append(p) or weak(p, s), start,
                   SearchOptions(params=NAMES, budget=60), sigma=sigma)
    moved = {k: abs(getattr(prior.best, k) - getattr(start, k)) / sigma[k] for k in NAMES}
    assert max(moved.values()) < 1.0
    assert abs(plain.best.R_ply - TRUTH.R_ply) < abs(prior.best.R_ply - TRUTH.R_ply)
    vals = np.array([[getattr(p, k) - getattr(start, k) for k in NAMES] for p in seen])
    assert np.all(np.abs(vals) <= 3.0 * np.array([sigma[k] for k in NAMES]) + 1e-9)
    assert prior.best_loss <= prior.start_loss


def test_prior_follows_a_loss_that_is_sure():
    """With a loss far above its seed noise the prior barely matters: the MAP search still
    finds TRUTH when it lies inside the box."""
    start = TRUTH.replace(alpha=TRUTH.alpha - 0.4, R_ply=TRUTH.R_ply + 0.02)
    sigma = {"alpha": 0.5, "alpha_ply": 0.5, "R_ply": 0.02}
    res = search(lambda p, s: 100 * quadratic(p, 0) + 1e-6 * (s % 3), start,
                 SearchOptions(params=NAMES, budget=120), sigma=sigma)
    assert res.improved
    assert abs(res.best.alpha - TRUTH.alpha) < 0.1 and abs(res.best.R_ply - TRUTH.R_ply) < 0.005


def test_prior_needs_every_sigma():
    with pytest.raises(UserError, match="prior sigma for R_ply"):
        search(quadratic, TRUTH, SearchOptions(params=NAMES), sigma={"alpha": 1, "alpha_ply": 1})


def test_ply_counts_each_searched_and_the_lowest_loss_kept():
    """The loss sees the stripe period alpha_ply / n: with the nets' n wrong, the search
    with the right n among the candidates finds the truth and wins; the nets' n alone fits
    the period with a wrong alpha_ply."""
    def period(p, seed):
        return ((p.alpha_ply / p.n - TRUTH.alpha_ply / TRUTH.n) / 0.1) ** 2 + 1e-4 * (seed % 3) \
            + (0.0 if p.n == TRUTH.n else 0.05)

    start = TRUTH.replace(n=TRUTH.n + 1, alpha_ply=TRUTH.alpha_ply + 1.0)
    opts = staged(("alpha_ply",), budget=30)
    seen = []
    res = search_ply_counts(period, start, [start.n, TRUTH.n, 6], opts,
                            lambda i, loss, best: seen.append(i), None)
    assert res.improved and res.best.n == TRUTH.n and res.start is start
    assert abs(res.best.alpha_ply - TRUTH.alpha_ply) < 0.05
    assert seen == list(range(1, res.evaluations + 1))  # one count over the searches
    alone = search_ply_counts(period, start, [start.n], opts, None, None)
    assert alone.best.n == start.n and abs(alone.best.alpha_ply - TRUTH.alpha_ply) > 1.0
    # when no count beats the nets' guess, the guess stays
    kept = search_ply_counts(period, TRUTH, [TRUTH.n, 2], opts, None, None)
    assert not kept.improved or kept.best.n == TRUTH.n


def test_another_ply_count_is_searched_from_the_nets_stripe_period():
    """The nets read the stripe period right and the count one too high: the right count,
    started at the pitch that keeps the period (not the nets' pitch, 3 sigma of the prior
    away), finds the truth inside a MAP box the nets' pitch would not reach and wins by the
    loss's other groups (a penalty of the wrong count here)."""
    def period(p, seed):
        return ((p.alpha_ply / p.n - TRUTH.alpha_ply / TRUTH.n) / 0.1) ** 2 + 1e-4 * (seed % 3) \
            + (0.0 if p.n == TRUTH.n else 0.05)

    n = TRUTH.n + 1
    start = TRUTH.replace(n=n, alpha_ply=TRUTH.alpha_ply * n / TRUTH.n)
    assert start.alpha_ply - TRUTH.alpha_ply > 3 * 0.5
    sigma = {"alpha_ply": 0.5}
    res = search_ply_counts(period, start, [n, TRUTH.n], staged(("alpha_ply",), budget=30),
                            None, sigma)
    assert res.best.n == TRUTH.n and abs(res.best.alpha_ply - TRUTH.alpha_ply) < 0.05


def test_a_ply_count_scores_its_loss_in_seed_noise_units_less_the_log_prior():
    """Two counts whose losses spread by 0.1414 over two seeds (std of 1.0 and 1.2, of 0.5
    and 0.7): 1.1 / 0.1414 - ln 0.9 = 7.88 against 0.6 / 0.1414 - ln 0.1 = 6.55, so the
    lower loss wins against a nets' 0.9; against a nets' 0.9999 (-ln 1e-4 = 9.21) it loses."""
    losses = {2: [1.0, 1.2], 3: [0.5, 0.7]}
    scores = ply_count_scores(losses, {2: 0.9, 3: 0.1})
    assert scores[2] == pytest.approx(7.883, abs=2e-3)
    assert scores[3] == pytest.approx(6.545, abs=2e-3)
    sure = ply_count_scores(losses, {2: 0.9999, 3: 1e-4})
    assert min(sure, key=sure.get) == 2


def test_another_ply_count_keeps_the_stripe_period_within_the_pitch_interval():
    start = TRUTH.replace(n=2, alpha_ply=4.0)
    three = same_period(start, 3)
    assert three.n == 3 and three.alpha_ply == pytest.approx(6.0)
    assert three.replace(n=2, alpha_ply=4.0) == start  # nothing else changes
    hi = PAPER_INTERVALS["alpha_ply"].hi
    assert same_period(TRUTH.replace(n=2, alpha_ply=0.6 * hi), 4) is None


def test_the_likeliest_counts_stop_at_the_mass_or_the_number_asked():
    prior = {2: 0.1, 3: 0.6, 4: 0.25, 5: 0.05}
    assert likeliest_counts(prior, most=4, mass=1.0) == (3, 4, 2, 5)
    assert likeliest_counts(prior, most=2) == (3, 4)
    assert likeliest_counts(prior, most=4, mass=0.8) == (3, 4)  # 0.85 >= 0.8 after two
    assert likeliest_counts(prior, most=4, mass=0.0) == (3,)
    assert likeliest_counts({}, most=3) == ()


def test_a_staged_search_chooses_the_count_before_its_pitch_stage_and_the_whole_loss_judges():
    """The count is chosen once, at its stage, from the thickness stage's best (R_ply at the
    truth), and kept when the loss agrees; a count the loss scores 10 higher is not an
    improvement."""
    def loss(p, seed):
        return quadratic(p, seed) + (10.0 if p.n == 6 else 0.0) \
            + (0.0 if p.n in (TRUTH.n, 6) else 1.0)

    opts = staged(("R_ply",), COUNT, ("alpha_ply",), budget=20)
    start = TRUTH.replace(n=TRUTH.n + 1, R_ply=TRUTH.R_ply * 1.2)
    seen = []

    def right(p):
        seen.append(p)
        return p.replace(n=TRUTH.n)

    res = search_stages(loss, start, opts, None, None, right)
    assert len(seen) == 1 and abs(seen[0].R_ply - TRUTH.R_ply) < 0.02 * TRUTH.R_ply
    assert seen[0].n == start.n and res.improved and res.best.n == TRUTH.n
    wrong = search_stages(loss, TRUTH.replace(R_ply=TRUTH.R_ply * 1.2), opts, None, None,
                          lambda p: p.replace(n=6))
    assert wrong.best.n == 6 and not wrong.improved
    never = search_stages(loss, start, staged(("alpha_ply",), ("R_ply",), budget=20), None,
                          None, lambda p: p.replace(n=6))
    assert never.best.n == start.n  # no ply-count stage: no choice


def test_staged_search_starts_each_stage_from_the_one_before():
    """alpha_ply, then alpha from alpha_ply's best: both reach the truth, the evaluations
    count on across the stages, and a stage with an empty parameter list is refused."""
    start = TRUTH.replace(alpha=TRUTH.alpha - 1.5, alpha_ply=TRUTH.alpha_ply + 2.0)
    seen = []
    opts = staged(("alpha_ply",), ("alpha",), budget=30)
    res = search_stages(quadratic, start, opts, lambda i, loss, best: seen.append(i))
    assert res.improved and res.start is start and res.best_loss < res.start_loss
    for k in ("alpha", "alpha_ply"):
        assert abs(getattr(res.best, k) - getattr(TRUTH, k)) < 0.01 * PAPER_INTERVALS[k].width
    assert seen == list(range(1, res.evaluations + 1)) and res.evaluations > 30
    one = search_stages(quadratic, start, staged(("alpha_ply",), budget=30))
    assert one.best.alpha == start.alpha  # a single stage leaves alpha alone
    with pytest.raises(UserError):
        SearchOptions(params=())


def test_flyaways_are_searched_over_their_whole_range_on_a_log_scale():
    """A clean yarn (40 flyaways per 10 mm, hairs of 0.4 mm) from the nets' guess of a
    hairy one (167, 3.4 mm): the box holds the whole sampler range whatever ``width``, and
    30 evaluations of DIRECT-L, searching on a log scale, land within 10 % of both; the
    same budget on the box's linear scale samples none of its points below 0.9 mm."""
    truth = TRUTH.replace(g=40, l_hair=0.4)
    start = TRUTH.replace(g=167, l_hair=3.4)
    names = ("g", "l_hair")
    lo, hi = search_box(start, names, 0.1)
    assert lo.tolist() == [PAPER_INTERVALS["g"].lo, PAPER_INTERVALS["l_hair"].lo]
    assert hi.tolist() == [FLYAWAY_RANGES["g"][1], FLYAWAY_RANGES["l_hair"][1]]

    def log_distance(p, seed):
        return sum(np.log(getattr(p, k) / getattr(truth, k)) ** 2 for k in names)

    res = search(log_distance, start, SearchOptions(params=names, budget=30))
    assert abs(res.best.g - 40) <= 4 and abs(res.best.l_hair - 0.4) < 0.04
    linear = (lo[1] + (hi[1] - lo[1]) * np.array([1, 3, 5]) / 6).min()  # DIRECT's sixths
    assert linear > 0.9


def test_a_stage_is_searched_with_the_objectives_own_objective_for_it():
    """An objective with ``for_stage``: the flyaway stage is searched with the objective
    it gives (here the hairs' loss alone), and the losses reported at both ends are the
    objective's own."""
    truth = TRUTH.replace(g=60)

    class Staged:
        def __call__(self, p, seed):
            return quadratic(p, seed) + ((p.g - truth.g) / 100) ** 2 + 1.0

        def for_stage(self, stage):
            return (lambda p, seed: ((p.g - truth.g) / 100) ** 2) if "g" in stage.params else self

    start = TRUTH.replace(g=150, alpha_ply=TRUTH.alpha_ply + 2.0)
    objective = Staged()
    res = search_stages(objective, start, staged(("g",), ("alpha_ply",), budget=30))
    assert abs(res.best.g - 60) <= 3 and abs(res.best.alpha_ply - TRUTH.alpha_ply) < 0.3
    assert res.start_loss == pytest.approx(np.mean([objective(start, s) for s in (0, 1, 2)]))
    assert res.best_loss > 1.0  # the objective's own, not the stage's
    flyaways_last = search_stages(objective, start, staged(("alpha_ply",), ("g",), budget=30))
    assert flyaways_last.best_loss == pytest.approx(
        np.mean([objective(flyaways_last.best, s) for s in (0, 1, 2)]))


def test_a_stage_whose_best_the_whole_objective_scores_worse_is_not_an_improvement():
    """The stage's own objective has its minimum 2 mm above the start's alpha_ply, the
    objective itself at the start: the stage moves, but the search does not count it an
    improvement (the fit then keeps the start)."""
    start = TRUTH

    class Disagreeing:
        def __call__(self, p, seed):
            return quadratic(p, seed)

        def for_stage(self, stage):
            return lambda p, seed: (p.alpha_ply - start.alpha_ply - 2.0) ** 2

    res = search_stages(Disagreeing(), start, staged(("alpha_ply",), budget=30))
    assert abs(res.best.alpha_ply - start.alpha_ply - 2.0) < 0.3
    assert res.best_loss > res.start_loss and not res.improved


def test_profile_interval_is_where_the_objective_stays_near_its_lowest():
    """On a quadratic objective in noise units, z = ((x - x0) / s)^2 / 2, the points within
    PROFILE_RISE of the lowest span x0 +- s * sqrt(2 PROFILE_RISE) = x0 +- 1.28 s: the
    Gaussian 80% interval; the best value is always inside."""
    from ipm.refine.search import LEVEL, PROFILE_RISE, profile_intervals

    x0, s = TRUTH.alpha_ply, 0.5
    xs = np.linspace(x0 - 3, x0 + 3, 601)
    evaluated = [(0.5 * ((x - x0) / s) ** 2, TRUTH.replace(alpha_ply=float(x))) for x in xs]
    lo, hi = profile_intervals(("alpha_ply",), evaluated, TRUTH)["alpha_ply"]
    z = np.sqrt(2 * PROFILE_RISE)
    assert LEVEL == 0.8 and z == pytest.approx(1.2816, abs=1e-3)
    assert lo == pytest.approx(x0 - z * s, abs=0.011) and hi == pytest.approx(x0 + z * s,
                                                                              abs=0.011)
    far = TRUTH.replace(alpha_ply=x0 + 2.9)
    assert profile_intervals(("alpha_ply",), evaluated, far)["alpha_ply"][1] == far.alpha_ply


def test_search_reports_an_interval_per_searched_parameter():
    start = TRUTH.replace(alpha_ply=TRUTH.alpha_ply + 1.0)
    res = search(quadratic, start, SearchOptions(params=("alpha_ply",), budget=30),
                 sigma={"alpha_ply": 1.0})
    lo, hi = res.intervals["alpha_ply"]
    assert lo <= res.best.alpha_ply <= hi and set(res.intervals) == {"alpha_ply"}


def test_the_ply_pitch_search_stays_in_the_samplers_helix_angles():
    """alpha_ply searched alone stays within 2 pi R_ply tan(50..80 degrees), where the
    stripe autocorrelation's side minima at a fraction of the period cannot trap it."""
    from ipm.refine.search import ply_pitch_range

    lo, hi = search_box(TRUTH, ("alpha_ply",), 1.0)
    a, b = ply_pitch_range(TRUTH)
    assert a == pytest.approx(2 * np.pi * TRUTH.R_ply * np.tan(np.radians(50)))
    assert lo[0] == pytest.approx(a) and hi[0] == pytest.approx(b)
    both = search_box(TRUTH, ("alpha_ply", "R_ply"), 1.0)[0]
    assert both[0] == PAPER_INTERVALS["alpha_ply"].lo  # with R_ply searched too: the prior box
    outside = TRUTH.replace(alpha_ply=0.9 * a)
    lo, hi = search_box(outside, ("alpha_ply",), 0.1)
    assert lo[0] <= outside.alpha_ply <= hi[0]  # a start outside it stays in the box


def test_polish_reaches_a_minimum_between_the_global_searchs_grid_points():
    """DIRECT-L with 30 evaluations in three parameters samples a coarse grid; a local
    polish of 20 more from its best gets much closer to a minimum off that grid."""
    start = TRUTH.replace(alpha=TRUTH.alpha - 1.3, alpha_ply=TRUTH.alpha_ply + 1.7,
                          R_ply=TRUTH.R_ply + 0.07)

    def error(opts):
        res = search(quadratic, start, opts)
        return res, max(abs(getattr(res.best, k) - getattr(TRUTH, k)) / PAPER_INTERVALS[k].width
                        for k in NAMES)

    coarse, e_coarse = error(SearchOptions(params=NAMES, budget=30))
    polished, e_polished = error(SearchOptions(params=NAMES, budget=30, polish=20))
    assert coarse.evaluations <= 30 < polished.evaluations <= 50
    assert e_polished < 0.5 * e_coarse
    one = search(quadratic, start, SearchOptions(params=("alpha_ply",), budget=30, polish=20))
    assert one.evaluations <= 30  # one parameter: DIRECT-L's cells are fine already
    with pytest.raises(UserError, match="polish"):
        SearchOptions(params=NAMES, polish=3)


def side_cover(params, seeds=(1, 2, 3)):
    """The share of a side view of ply 0 its core fibers cover, measured on the generated
    fibers: at nine cross-sections along the yarn, each fiber's point nearest the section
    casts a shadow ``2 t_x`` wide on the x axis, and the union of the shadows is taken over
    the span they reach."""
    from ipm.generator import generate

    shares = []
    for seed in seeds:
        fibers = generate(params, seed, length=2.0)
        ply = [fibers.fiber(int(f)) for f in np.flatnonzero((fibers.kind == 0)
                                                              & (fibers.ply == 0))]
        for z in np.linspace(-0.8, 0.8, 9):
            x = np.sort([pts[np.argmin(np.abs(pts[:, 2] - z)), 0] for pts in ply])
            lo, hi = x - params.t_x, x + params.t_x
            reach = np.maximum.accumulate(np.concatenate([[-np.inf], hi[:-1]]))
            shares.append(np.clip(hi - np.maximum(lo, reach), 0, None).sum()
                          / (hi.max() - lo.min()))
    return float(np.mean(shares))


def test_a_search_that_narrows_the_plies_keeps_their_cover_with_keep_cover():
    """With ``keep_cover`` a stage of the ply radii scales the fibers per ply with the
    plies' width, so a side view of a ply stays about as covered as the start's; without,
    the same fibers packed into plies half as wide cover far more of it (a backlit core
    turns opaque)."""
    start = TRUTH.replace(m=40, t_x=0.006, t_y=0.006, r_x=0.3, r_y=0.25)
    small = {"r_x": 0.5 * start.r_x, "r_y": 0.5 * start.r_y}

    def loss(p, seed):  # lowest at plies half as wide
        return sum((getattr(p, k) - v) ** 2 for k, v in small.items()) + 1e-6 * (seed % 3)

    opts = SearchOptions(params=("r_x", "r_y"), budget=40, width=0.5)
    kept = search(loss, start, replace(opts, keep_cover=True)).best
    packed = search(loss, start, opts).best
    assert kept.r_x < 0.6 * start.r_x and packed.r_x < 0.6 * start.r_x
    assert packed.m == start.m and 0.4 * start.m < kept.m < 0.65 * start.m
    depth = {k: -np.log(1 - side_cover(p)) for k, p in (("start", start), ("kept", kept),
                                                         ("packed", packed))}
    assert depth["packed"] > 1.6 * depth["start"], depth
    assert abs(np.log(depth["kept"] / depth["start"])) < 0.3, depth
