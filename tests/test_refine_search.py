"""The NLopt search machinery on an analytic objective (no renderer needed)."""

import numpy as np
import pytest

from ipm.errors import UserError
from ipm.params import PAPER_INTERVALS
from ipm.presets import preset
from ipm.refine.search import ALGORITHMS, SearchOptions, search, search_box

TRUTH = preset("golden")
NAMES = ("alpha", "alpha_ply", "R_ply")


def quadratic(p, seed):
    """Distance to TRUTH in units of the prior range, plus seed noise of 1e-4."""
    d = [(getattr(p, k) - getattr(TRUTH, k)) / (PAPER_INTERVALS[k].hi - PAPER_INTERVALS[k].lo)
         for k in NAMES]
    return float(np.sum(np.square(d))) + 1e-4 * (seed % 3)


@pytest.mark.parametrize("algorithm", ["LN_BOBYQA", "LN_SBPLX", "LN_NELDERMEAD"])
def test_finds_the_minimum_from_a_perturbed_start(algorithm):
    start = TRUTH.replace(alpha=TRUTH.alpha - 1.5, alpha_ply=TRUTH.alpha_ply + 2.0,
                          R_ply=TRUTH.R_ply + 0.1)
    evals = []
    res = search(quadratic, start, SearchOptions(params=NAMES, algorithm=algorithm, budget=150),
                 on_eval=lambda i, loss, best: evals.append((i, loss, best)))
    assert res.improved and res.best_loss < res.start_loss
    for k in NAMES:
        iv = PAPER_INTERVALS[k]
        assert abs(getattr(res.best, k) - getattr(TRUTH, k)) < 0.01 * (iv.hi - iv.lo), k
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
                                       (dict(width=0.0), "width")])
def test_bad_options(kw, match):
    with pytest.raises(UserError, match=match):
        SearchOptions(**kw)


def test_all_listed_algorithms_exist():
    import nlopt

    for a in ALGORITHMS:
        nlopt.opt(getattr(nlopt, a), 2)
