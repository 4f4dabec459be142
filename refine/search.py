"""Gradient-free search of the continuous yarn parameters with NLopt.

The search runs in a box narrowed around the start (the nets' guess): ``width`` of each
parameter's prior range on either side, clipped to the prior's box, mapped to [0, 1]^d so
that every NLopt algorithm sees a well-scaled problem.  The objective is deterministic
within one search (fixed fiber seed and render seed).  So as not to fit one seed's noise,
the best few distinct candidates of the search and the start are scored again on
``rescore_seeds`` (other fibers of the same parameters) and the winner is the one with the
lowest mean loss over all seeds; if that is the start, the search could not improve on it
and says so.

With ``sigma`` (the nets' error per parameter, :meth:`ipm.nets.ensemble.Ensemble.sigma`) the
search is a MAP estimate instead of a plain minimum: it minimises
``L(theta) / s_L + prior_weight * 0.5 * sum(((theta - theta_nets) / sigma) ** 2)``, where
``s_L`` is the seed noise of the loss at the start (the spread of ``L`` over the fiber
seeds).  A loss difference of one unit of its own seed noise then cannot pull a parameter
further than ``sqrt(2) sigma`` from the nets' guess, and the box shrinks to
``box_sigmas * sigma`` around it.  Why: the image loss alone moves parameters the nets
already get well (``R_ply``) away from them (docs/identifiability.md).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from statistics import NormalDist

import nlopt
import numpy as np

from ipm.errors import UserError
from ipm.params import PAPER_INTERVALS, YarnParams, clipped
from ipm.prior import FLYAWAY_RANGES, GAMMA_DEG

#: An objective: the loss of the yarn ``params`` rendered with fiber seed ``seed``.  One with
#: a ``for_stage(stage)`` method (:class:`ipm.refine.objective.RenderObjective`) gives each
#: :class:`Stage` of :func:`search_stages` the objective that stage is searched with.
Objective = Callable[[YarnParams, int], float]

#: The probability the intervals are meant to hold the truth with.
LEVEL = 0.8
#: How far above its lowest the objective (in seed-noise units) may lie inside an interval:
#: half the LEVEL quantile of a chi-square of one degree of freedom (the square of the normal
#: quantile at (1 + LEVEL) / 2).
PROFILE_RISE = 0.5 * NormalDist().inv_cdf((1 + LEVEL) / 2) ** 2

#: The parameters a search can move: all but the ply count ``n``, which a fit chooses among the
#: nets' most likely counts (:func:`search_ply_counts`).  An integer parameter (``m``, ``g``)
#: is searched on the real line and rounded before each render, so the loss is a staircase
#: in it that a global search (DIRECT-L) handles.
SEARCHABLE = tuple(k for k in PAPER_INTERVALS if k != "n")

#: The local search of ``SearchOptions.polish``: BOBYQA's quadratic model reaches a smooth
#: minimum in few evaluations, and it starts at POLISH_STEP of the box.
POLISH_ALGORITHM = "LN_BOBYQA"
POLISH_STEP = 0.05

#: Parameters searched on a log scale: the flyaways' amount and lengths, whose real values
#: (a few short hairs) sit in the low corner of their ranges.
LOG_SEARCHED = ("g", "l_hair", "l_loop", "d_mean", "d_std")

ALGORITHMS = ("LN_BOBYQA", "LN_SBPLX", "LN_NELDERMEAD", "LN_COBYLA", "GN_DIRECT_L")


@dataclass(frozen=True)
class SearchOptions:
    """How one stage is searched (:class:`ipm.refine.plan.FitConfig` makes them).
    params: parameters to search (:data:`SEARCHABLE`).  algorithm: an NLopt
    derivative-free algorithm (DIRECT-L, a global search of the box, by default: the
    autocorrelation has side minima in alpha_ply that trap a local search such as BOBYQA).
    budget: objective evaluations of the search (re-scoring comes on top).  time_s:
    wall-time bound of the search.  width: half-width of the box around the start, as a
    fraction of each parameter's prior range.  fiber_seed: the seed of the search's
    objective; rescore_seeds, rescore_top: the re-scoring described in the module doc.
    polish: evaluations of a local search (:data:`POLISH_ALGORITHM`) from the best point, if the
    stage has two or more parameters, at the scale of the global search's finest cells: DIRECT-L
    with 30 evaluations in three parameters only samples a grid of ninths of the box, and the
    fits of different photos landed on the same grid points (real-photos-staged@b2566ce).  In one
    parameter its cells are already a few hundredths of the box, and polishing `alpha_ply`
    followed one fiber seed's side minima of the stripe loss instead
    (real-photos-polish-every-stage@7cc1a3c against real-photos-staged@b2566ce).  keep_cover:
    a stage that moves the ply radii ``r_x``, ``r_y`` but not ``m`` scales ``m`` with them
    (:func:`same_cover`)."""

    params: tuple[str, ...] = ("alpha_ply",)
    algorithm: str = "GN_DIRECT_L"
    budget: int = 30
    time_s: float | None = None
    width: float = 0.25
    fiber_seed: int = 0
    rescore_seeds: tuple[int, ...] = (1, 2)
    rescore_top: int = 3
    prior_weight: float = 1.0
    box_sigmas: float = 3.0
    polish: int = 0
    keep_cover: bool = False

    def __post_init__(self) -> None:
        bad = [p for p in self.params if p not in SEARCHABLE]
        if bad or not self.params:
            raise UserError(f"cannot search {bad or 'no parameters'}: choose among "
                            f"{', '.join(SEARCHABLE)} (the ply count takes --ply-counts)")
        if self.algorithm not in ALGORITHMS:
            raise UserError(f"unknown algorithm {self.algorithm!r}; choose one of "
                            f"{', '.join(ALGORITHMS)}")
        most, least = len(self.params), least_budget((self.params,))
        if self.budget < least:
            raise UserError(f"budget must be at least {least} evaluations for {most} "
                            f"parameters, got {self.budget}")
        if not 0 < self.width <= 1:
            raise UserError(f"width must be in (0, 1], got {self.width}")
        if self.time_s is not None and not (np.isfinite(self.time_s) and self.time_s > 0):
            raise UserError(f"time must be a positive number of seconds, got {self.time_s}")
        if self.polish and self.polish < least:
            raise UserError(f"polish must be 0 or at least {least} evaluations for "
                            f"{most} parameters, got {self.polish}")
        if self.prior_weight < 0 or self.box_sigmas <= 0:
            raise UserError(f"prior_weight must be >= 0 and box_sigmas > 0, got "
                            f"{self.prior_weight}, {self.box_sigmas}")


def least_budget(stages: Sequence[Sequence[str]]) -> int:
    """The fewest evaluations a search of ``stages`` takes: NLopt's DIRECT-L and BOBYQA need
    ``2 k + 2`` for the largest stage's ``k`` parameters."""
    return 2 * max(len(stage) for stage in stages) + 2


def parse_stages(text: str) -> tuple[tuple[str, ...], ...]:
    """The parameters of each stage of ``a,b;c`` (``ipm fit --params``): stages separated by
    ``;``, their parameters by ``,``.

    >>> parse_stages("R_ply, r_x;alpha_ply")
    (('R_ply', 'r_x'), ('alpha_ply',))
    """
    return tuple(tuple(p.strip() for p in part.split(",") if p.strip())
                 for part in text.split(";"))


@dataclass(frozen=True)
class Stage:
    """One step of a staged search (:func:`search_stages`): ``name`` for the user;
    ``search``, how its parameters are searched, or None for the choice of the ply count
    (the ``choose`` of :func:`search_stages`); the loss it is scored by: the groups
    ``scored_by`` alone, else the whole loss but the groups ``without`` (a group of the
    whole loss keeps its weight)."""

    name: str
    search: SearchOptions | None = None
    scored_by: tuple[str, ...] | None = None
    without: tuple[str, ...] = ()

    @property
    def params(self) -> tuple[str, ...]:
        return self.search.params if self.search else ()

    def to_dict(self) -> dict:
        """What ``params.json`` and ``ipm fit --dry-run`` show of the stage."""
        out: dict = {"name": self.name, "params": list(self.params),
                     "scored_by": ("the whole loss" if self.scored_by is None else
                                   list(self.scored_by))}
        if self.without:
            out["without"] = list(self.without)
        if self.search:
            out |= {"budget": self.search.budget, "polish": self.search.polish,
                    "keep_cover": self.search.keep_cover}
        return out


@dataclass
class SearchResult:
    start: YarnParams
    best: YarnParams
    start_loss: float  # mean over all seeds
    best_loss: float
    improved: bool
    trace: list[float] = field(default_factory=list)  # objective value per evaluation
    evaluations: int = 0
    seconds: float = 0.0
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)  # LEVEL, profile


def _finite(loss: float) -> float:
    """A loss NLopt can order: a render that failed to give statistics scores worst."""
    loss = float(loss)
    return loss if np.isfinite(loss) else 1e6


def search_box(start: YarnParams, names: tuple[str, ...], width: float,
               sigma: dict[str, float] | None = None, box_sigmas: float = 3.0
               ) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) of the search around ``start``, inside the prior's box: ``width`` of each
    range on either side, or ``box_sigmas * sigma[k]`` where that is narrower; ``alpha_ply``
    searched without ``R_ply`` also within :func:`ply_pitch_range`.  A flyaway parameter
    (:data:`ipm.prior.FLYAWAY_RANGES`) is searched over its whole sampler range, down to its
    interval's low end (a cleaner yarn than the paper's), unless ``sigma`` narrows it: the
    nets do not read flyaways off renders they were not trained on
    (the Cycles pages of benchmarks/results/nets_accuracy: g, l_hair, l_loop worse than
    the mean), so a box around their guess need not hold the photo's.  (The search does
    not recover the true flyaways of such renders either: it matches their look,
    the Cycles comparisons in docs.)"""
    lo, hi = [], []
    for k in names:
        iv = PAPER_INTERVALS[k]
        half = iv.width if k in FLYAWAY_RANGES else width * iv.width
        if sigma is not None:
            half = min(half, box_sigmas * sigma[k])
        v = getattr(start, k)
        a, b = (iv.lo, FLYAWAY_RANGES[k][1]) if k in FLYAWAY_RANGES else (iv.lo, iv.hi)
        if k == "alpha_ply" and "R_ply" not in names:
            a, b = ply_pitch_range(start)
        lo.append(min(v, max(iv.lo, a, v - half)))  # the start stays inside
        hi.append(max(v, min(iv.hi, b, v + half)))
    return np.array(lo), np.array(hi)


def ply_pitch_range(p: YarnParams) -> tuple[float, float]:
    """The ply pitches the guided sampler gives a yarn of ``p``'s ply radius:
    ``2 pi R_ply tan(gamma_ply)`` for helix angles in :data:`ipm.prior.GAMMA_DEG`.  Outside
    it the stripe autocorrelation has side minima at a fraction of the true period that a
    search would otherwise fall into (docs/compare)."""
    lo, hi = (2 * np.pi * p.R_ply * np.tan(np.radians(g)) for g in GAMMA_DEG)
    return float(lo), float(hi)


def seed_noise(losses: Sequence[float]) -> float:
    """The seed noise of the loss: the spread (sample std) of its values at one point over
    the fiber seeds, at least a thousandth of their mean.  The unit in which the search adds
    the nets' prior (module doc)."""
    spread = float(np.std(losses, ddof=1)) if len(losses) > 1 else 0.0
    return max(spread, 1e-3 * abs(float(np.mean(losses))), 1e-12)


def same_cover(p: YarnParams, start: YarnParams) -> YarnParams:
    """``p`` with the fibers per ply ``m`` scaled with the ply's mean radius
    ``sqrt(r_x r_y)`` from ``start``'s (within ``m``'s interval), so that the share of a
    ply's side view its fibers cover, about ``m t / r``, stays ``start``'s: a core lit from
    behind then stays as dark as in the render of ``start``.  Why: a search that narrows the plies
    of a yarn the nets read too thick would otherwise pack their fiber count into far
    narrower plies and render an opaque black core whose ply stripes no longer show (most
    real-photo fits that missed the stripe period, real-photos-two-seeds@b73156f);
    keeping the fibers per area instead (``m`` with ``r_x r_y``) rendered see-through
    bundles whose core read too wide (real-photos-keep-fill@616f8d5).  With the cover kept the
    real-photo fits met their targets best (real-photos-default@d6136c7)."""
    scale = np.sqrt(p.r_x * p.r_y / (start.r_x * start.r_y))
    return p.replace(m=clipped("m", start.m * scale))


def same_period(p: YarnParams, n: int) -> YarnParams | None:
    """``p`` with ``n`` plies and the ply pitch scaled to keep the ply-stripe period
    ``alpha_ply / n`` the image shows; None if that pitch leaves its interval."""
    iv = PAPER_INTERVALS["alpha_ply"]
    pitch = p.alpha_ply * n / p.n
    return p.replace(n=n, alpha_ply=pitch) if iv.lo <= pitch <= iv.hi else None


def likeliest_counts(prior: dict[int, float], most: int, mass: float = 0.9
                     ) -> tuple[int, ...]:
    """The ply counts most likely under ``prior`` (the nets' probabilities), most likely
    first: at most ``most``, fewer once they hold ``mass`` of the probability."""
    order = sorted(prior, key=lambda n: -prior[n])
    keep = 1 + int(np.searchsorted(np.cumsum([prior[n] for n in order]), mass))
    return tuple(order[:max(1, min(most, keep))])


def ply_count_scores(losses: dict[int, Sequence[float]], prior: dict[int, float]
                     ) -> dict[int, float]:
    """Per ply count ``n``: the mean of its ``losses`` (one per fiber seed) in units of the
    loss's seed noise (:func:`seed_noise`, averaged over the counts), minus the log of the
    nets' probability ``prior[n]``: the negative log posterior of the count, in the units
    of the search's MAP objective (module doc).  The lowest is the count a fit keeps."""
    noise = float(np.mean([seed_noise(v) for v in losses.values()]))
    return {n: float(np.mean(v)) / noise - float(np.log(max(prior.get(n, 0.0), 1e-6)))
            for n, v in losses.items()}


def _logged(values: np.ndarray, logs: np.ndarray) -> np.ndarray:
    """``values`` with those where ``logs`` is set on a log scale (the others, which may be
    negative, are not passed to the logarithm)."""
    return np.where(logs, np.log(np.where(logs, values, 1.0)), values)


def search(objective: Objective, start: YarnParams, opts: SearchOptions = SearchOptions(),
           on_eval: Callable[[int, float, float], None] | None = None,
           sigma: dict[str, float] | None = None) -> SearchResult:
    """Minimise ``objective`` over ``opts.params`` from ``start`` (with ``sigma``: the MAP
    objective of the module doc; ``trace`` and the losses stay image losses).

    on_eval(evaluation, loss, best loss) is called after every evaluation (progress bars).
    """
    names = opts.params
    if sigma is not None:
        missing = [k for k in names if not sigma.get(k, 0) > 0]
        if missing:
            raise UserError(f"no positive prior sigma for {', '.join(missing)} (models "
                            "without validation errors: refine with --no-prior)")
    lo, hi = search_box(start, names, opts.width, sigma, opts.box_sigmas)
    logs = np.array([k in LOG_SEARCHED for k in names])
    lo, hi = _logged(lo, logs), _logged(hi, logs)
    span = np.where(hi > lo, hi - lo, 1.0)
    t0 = time.perf_counter()
    trace: list[float] = []
    seen: dict[tuple, tuple[float, YarnParams]] = {}
    seeds = (opts.fiber_seed, *opts.rescore_seeds)
    start_losses = [_finite(objective(start, s)) for s in seeds]
    noise = seed_noise(start_losses)

    def penalty(p: YarnParams) -> float:
        if sigma is None:
            return 0.0
        z = [(getattr(p, k) - getattr(start, k)) / sigma[k] for k in names]
        return opts.prior_weight * 0.5 * float(np.sum(np.square(z)))

    def in_noise_units(loss: float, p: YarnParams) -> float:
        return loss / noise + penalty(p)

    def posterior(loss: float, p: YarnParams) -> float:
        return loss if sigma is None else in_noise_units(loss, p)

    cover_kept = opts.keep_cover and bool({"r_x", "r_y"} & set(names)) and "m" not in names

    def to_params(u: np.ndarray) -> YarnParams:
        vals = lo + np.clip(u, 0, 1) * span
        vals = np.where(logs, np.exp(vals), vals)
        p = start.replace(**{k: clipped(k, v) for k, v in zip(names, vals, strict=True)})
        return same_cover(p, start) if cover_kept else p

    def f(u: np.ndarray, grad: np.ndarray) -> float:
        p = to_params(u)
        loss = _finite(objective(p, opts.fiber_seed))
        trace.append(loss)
        seen[tuple(np.round(u, 6))] = (posterior(loss, p), loss, p, in_noise_units(loss, p))
        if on_eval:
            on_eval(len(trace), loss, min(trace))
        return posterior(loss, p)

    def minimise(algorithm: str, u0: np.ndarray, budget: int, step: float) -> None:
        opt = nlopt.opt(getattr(nlopt, algorithm), len(names))
        opt.set_lower_bounds(np.zeros(len(names)))
        opt.set_upper_bounds(np.ones(len(names)))
        opt.set_min_objective(f)
        opt.set_maxeval(budget)
        if opts.time_s:  # one bound for the search and its polish together
            opt.set_maxtime(max(1e-3, opts.time_s - (time.perf_counter() - t_search)))
        opt.set_initial_step(step)
        opt.set_xtol_rel(1e-3)
        try:
            opt.optimize(u0)
        except (nlopt.RoundoffLimited, nlopt.ForcedStop):
            pass  # the evaluations so far stand; the best of them is re-scored below

    t_search = time.perf_counter()
    u0 = np.array([getattr(start, k) for k in names], dtype=float)
    u0 = (_logged(u0, logs) - lo) / span
    minimise(opts.algorithm, np.clip(u0, 0, 1), opts.budget, 0.15)
    if opts.polish and len(names) > 1:
        u_best = min(seen, key=lambda u: seen[u][0])
        minimise(POLISH_ALGORITHM, np.array(u_best), opts.polish, POLISH_STEP)

    candidates = sorted(seen.values(), key=lambda c: c[0])[: opts.rescore_top]
    scored = [(float(np.mean(start_losses)), start)]
    scored += [(float(np.mean([loss, *(_finite(objective(p, s))
                                        for s in opts.rescore_seeds)])), p)
               for _, loss, p, _ in candidates]
    best_loss, best = min(scored, key=lambda lp: posterior(*lp))
    return SearchResult(start=start, best=best, start_loss=scored[0][0], best_loss=best_loss,
                        improved=best is not start, trace=trace, evaluations=len(trace),
                        seconds=time.perf_counter() - t0,
                        intervals=profile_intervals(names, [(z, p) for *_, p, z in
                                                            seen.values()], best))


def profile_intervals(names: tuple[str, ...], evaluated: list[tuple[float, YarnParams]],
                      best: YarnParams) -> dict[str, tuple[float, float]]:
    """Per parameter, the range of its values over the ``evaluated`` (objective, params)
    within :data:`PROFILE_RISE` of the lowest objective, widened to hold ``best``."""
    low = min(z for z, _ in evaluated)
    inside = [p for z, p in evaluated if z <= low + PROFILE_RISE]
    return {k: (min(getattr(best, k), *(getattr(p, k) for p in inside)),
                max(getattr(best, k), *(getattr(p, k) for p in inside))) for k in names}


def _combined(start: YarnParams, results: list[SearchResult], best: SearchResult,
              improved: bool) -> SearchResult:
    """One result of several searches: ``start``'s loss from the first, ``best``'s
    parameters and loss, every evaluation."""
    intervals = {k: v for r in results if r.best.n == best.best.n
                 for k, v in r.intervals.items()}
    return SearchResult(start=start, best=best.best, start_loss=results[0].start_loss,
                        best_loss=best.best_loss, improved=improved,
                        trace=[x for r in results for x in r.trace],
                        evaluations=sum(r.evaluations for r in results),
                        seconds=sum(r.seconds for r in results), intervals=intervals)


def _offset(on_eval: Callable[[int, float, float], None] | None, results: list[SearchResult]
            ) -> Callable[[int, float, float], None] | None:
    """``on_eval`` counting on after the evaluations of ``results``."""
    done = sum(r.evaluations for r in results)
    return on_eval and (lambda i, loss, best: on_eval(done + i, loss, best))


def search_stages(objective: Objective, start: YarnParams, stages: Sequence[Stage],
                  on_eval: Callable[[int, float, float], None] | None = None,
                  sigma: dict[str, float] | None = None,
                  choose: Callable[[YarnParams], YarnParams] | None = None) -> SearchResult:
    """:func:`search` of each of ``stages`` in turn, each from the stage before's best (a
    staged search: the parameters the loss sees most first), with the objective's
    ``for_stage`` if it has one; a stage without a search applies ``choose`` (the ply
    count's choice, :func:`ipm.refine.measure.choose_ply_count`; none: it is skipped) to
    the best so far.  Improved if any stage moved away from its start or ``choose`` changed
    the count and, when a stage was searched with an objective of its own or the count
    changed, the objective's loss (mean over the seeds) is no higher at the end than at the
    start: a stage decides by the groups that see its parameters, and the whole loss must
    not disagree."""
    results: list[SearchResult] = []
    own: list[bool] = []  # whether a stage was searched with ``objective`` itself
    current = start
    changed = False
    searched = [stage for stage in stages if stage.search is not None]
    for stage in stages:
        if stage.search is None:
            if choose is not None:
                chosen = choose(current)
                changed, current = changed or chosen.n != current.n, chosen
            continue
        of_stage = (objective.for_stage(stage) if hasattr(objective, "for_stage")
                    else objective)
        own.append(of_stage is objective)
        results.append(search(of_stage, current, stage.search, _offset(on_eval, results),
                              sigma))
        current = results[-1].best
    seeds = (searched[0].search.fiber_seed, *searched[0].search.rescore_seeds)

    def rescored(p: YarnParams) -> float:
        return float(np.mean([_finite(objective(p, s)) for s in seeds]))

    # the losses reported at both ends are the objective's own, whatever the stages' were
    if not own[0]:
        results[0] = replace(results[0], start_loss=rescored(start))
    if not own[-1]:
        results[-1] = replace(results[-1], best_loss=rescored(current))
    improved = any(r.improved for r in results) or changed
    if not all(own) or changed:
        improved = improved and results[-1].best_loss <= results[0].start_loss
    if len(results) == 1:
        return replace(results[0], improved=improved)
    return _combined(start, results, results[-1], improved)


def search_ply_counts(objective: Objective, neural: YarnParams, counts: Sequence[int],
                      stages: Sequence[Stage],
                      on_eval: Callable[[int, float, float], None] | None,
                      sigma: dict[str, float] | None,
                      choose: Callable[[YarnParams], YarnParams] | None = None
                      ) -> SearchResult:
    """:func:`search_stages` from ``neural`` with each ply count of ``counts`` (the nets' own
    first), another count from the nets' stripe period (:func:`same_period`, the pitch as it
    is where that leaves its interval), so that its search and its prior centre on the pitch
    the image shows for that count; with several, the result with the lowest mean loss over
    the seeds wins, and it counts as an improvement only if that loss is below the nets'
    guess's.  ``on_eval`` sees the evaluations of all searches in one count.  ``choose``:
    that of :func:`search_stages`."""
    results: list[SearchResult] = []
    for n in counts:
        start = neural if n == neural.n else same_period(neural, n) or neural.replace(n=n)
        results.append(search_stages(objective, start, stages, _offset(on_eval, results),
                                     sigma, choose))
    if len(results) == 1:
        return results[0]
    best = min(results, key=lambda r: r.best_loss)
    return _combined(neural, results, best,
                     best.best != neural and best.best_loss < results[0].start_loss)
