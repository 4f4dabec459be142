"""``ipm fit``: the nets' guess, refined by render-and-compare (the part beyond the paper).

Steps: exposure check of the photo; the neural ensemble's parameters; the fiber colour (the
paper does not infer appearance) matched to the photo's core; then, with ``refine``, the
stages of :func:`ipm.refine.plan.plan` (the gates choose them before the search): NLopt
searches (:mod:`ipm.refine.search`) of the continuous raw-yarn parameters on the statistics
loss (:mod:`ipm.refine.objective`) at a low resolution, and the choice of the ply count.
The losses reported for both results are means over the search seed and the re-scoring
seeds, so they compare.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace

import numpy as np
from scipy.stats import norm

from ipm.params import PAPER_INTERVALS, RAW_CONTINUOUS, YarnParams
from ipm.photo import Photo, on_scene_card
from ipm.refine.capture import search_card
from ipm.refine.measure import (
    MIN_CORE_CONTRAST,
    choose_ply_count,
    core_contrast,
    exposure_warning,
    match_colour,
    match_size,
    photo_tilt,
    search_view,
    width_ratio,
)
from ipm.refine.objective import Detail, Readings, RenderObjective, search_weights
from ipm.refine.plan import FitConfig, Plan, plan, within_gate
from ipm.refine.search import LEVEL, SearchResult, likeliest_counts, search_ply_counts
from ipm.setups import DEFAULT_SETUP, setup_of


def nets_interval(name: str, value: float, sigma: float) -> tuple[float, float]:
    """The :data:`LEVEL` interval of parameter ``name`` around ``value`` for a Gaussian
    error of ``sigma`` (the nets' validation error), within the parameter's interval."""
    half = float(norm.ppf(0.5 + LEVEL / 2)) * sigma
    iv = PAPER_INTERVALS[name]
    return max(iv.lo, value - half), min(iv.hi, value + half)


def search_interval(name: str, value: float, profile: tuple[float, float],
                    neural_value: float, sigma: float | None) -> tuple[float, float]:
    """The :data:`LEVEL` interval of a searched parameter: the search's profile interval
    widened to hold the refined ``value``, and with the nets' ``sigma`` its hull with their
    interval around ``neural_value`` (:func:`nets_interval`).  Why the hull: the profile
    measures only the loss's seed noise, not how far the scene's renders are from the
    photo, and alone it held the truth far less often than its level (``docs/compare``,
    the Cycles comparisons in ``docs``); the hull holds it about as often as the nets'
    intervals do (``benchmarks/results/interval_coverage.md``)."""
    lo, hi = min(value, profile[0]), max(value, profile[1])
    if sigma is None:
        return lo, hi
    nets = nets_interval(name, neural_value, sigma)
    return min(lo, nets[0]), max(hi, nets[1])


@dataclass
class FitResult:
    neural: YarnParams
    refined: YarnParams
    loss_neural: float
    loss_refined: float
    improved: bool
    warnings: list[str] = field(default_factory=list)
    search: SearchResult | None = None
    seconds: float = 0.0
    tilt_deg: float = 0.0
    sigma: dict[str, float] | None = None
    count_scores: dict[int, float] = field(default_factory=dict)  # choose_ply_count's
    config: FitConfig | None = None
    plan: Plan | None = None  # the stages the fit ran

    def intervals(self) -> dict[str, tuple[float, float, str]]:
        """A :data:`LEVEL` interval per continuous raw-yarn parameter of the refined result,
        and where it comes from: for the parameters it searched, the search's profile
        (:func:`ipm.refine.search.profile_intervals`) joined with the nets' interval
        (:func:`search_interval`); the nets' validation error as a Gaussian around the value
        for the others (none without ``sigma``)."""
        out: dict[str, tuple[float, float, str]] = {}
        searched = self.search.intervals if self.search else {}
        sigma = self.sigma or {}
        for k in RAW_CONTINUOUS:
            v = getattr(self.refined, k)
            if k in searched:
                source = "search profile" + (" and nets' validation error" if k in sigma else "")
                out[k] = (*search_interval(k, v, searched[k], getattr(self.neural, k),
                                           sigma.get(k)), source)
            elif self.sigma and k in self.sigma:
                out[k] = (*nets_interval(k, v, self.sigma[k]), "nets' validation error")
        return out
    def to_dict(self, pixel_size_mm: float, setup: str = DEFAULT_SETUP) -> dict:
        config = self.config or FitConfig()
        return {
            "neural": self.neural.to_dict(), "refined": self.refined.to_dict(),
            "loss": {"neural": self.loss_neural, "refined": self.loss_refined},
            "improved": self.improved, "warnings": self.warnings,
            "intervals": {"level": LEVEL, **{k: list(v) for k, v in self.intervals().items()}},
            "evaluations": self.search.evaluations if self.search else 0,
            **({"ply_count_scores": {str(n): round(v, 3) for n, v in self.count_scores.items()}}
               if self.count_scores else {}),
            "plan": self.plan.to_dict() if self.plan else None,
            "settings": {**asdict(config), "pixel_size_mm": pixel_size_mm, "setup": setup,
                         "tilt_deg": round(self.tilt_deg, 3), "prior_sigma": self.sigma},
        }


def fit(photo: Photo, neural: YarnParams, renderer, config: FitConfig | None = None,
        refine: bool = True, on_eval: Callable[[int, float, float], None] | None = None,
        sigma: dict[str, float] | None = None, readings: Readings | None = None,
        detail: tuple[Readings, float] | None = None,
        count_prior: dict[int, float] | None = None, dry_run: bool = False) -> FitResult:
    """Fit ``photo`` starting from the nets' parameters ``neural``; ``sigma``, the nets'
    error per parameter (:meth:`ipm.nets.ensemble.Ensemble.sigma`), makes the search a MAP
    estimate around them (:mod:`ipm.refine.search`) where the plan keeps the prior.
    ``readings``: the nets' readings (:meth:`ipm.nets.ensemble.Ensemble.readings`), added
    to the loss at weight ``config.learned`` when that is above 0.  ``detail``: the detail
    nets' readings and pitch (:meth:`ipm.nets.ensemble.Ensemble.detail_readings`; None for
    a photo too coarse for them), compared on a window at weight ``config.detail``
    (``config``: :class:`FitConfig` if None).
    ``count_prior``: the nets' probability of each ply count
    (:meth:`ipm.nets.ensemble.Ensemble.ply_count_probabilities`): the plan's ply-count
    stage chooses among them, and with ``config.ply_counts`` above 1 the search runs from
    there with each of the likeliest counts too and keeps the lowest loss
    (:func:`search_ply_counts`).  ``dry_run``: stop once the plan is made (``plan`` of the
    result; nothing searched, no losses).  The refined result differs from the nets' only
    if its loss is lower."""
    t0 = time.perf_counter()
    config = config or FitConfig()
    setup = photo.setup
    warnings = [w for w in (exposure_warning(photo.image),) if w]
    scale, frame = search_view(photo, config.scale)
    small = photo.at_pitch(scale)
    card = search_card(small, setup)
    view = on_scene_card(small, setup)  # the yarn stands out of any card as out of the scene's
    seen = core_contrast(view) >= MIN_CORE_CONTRAST
    tilt = photo_tilt(view) if seen else 0.0
    learned = config.learned > 0 and readings is not None
    window = (Detail.of_photo(photo, *detail, weight=config.detail, spp=config.spp)
              if config.detail > 0 and detail is not None and seen else None)
    if config.detail > 0 and detail is None:
        warnings.append(f"no detail nets read photos of {photo.pixel_size_mm:g} mm per pixel "
                        "(the shipped ones need 0.0125 mm or finer); the loss has no detail "
                        "window")

    def objective_of(p: Plan) -> RenderObjective:
        return RenderObjective(renderer, small, scale, config.spp,
                               weights=search_weights(p.searched),
                               seeds_per_eval=p.seeds_per_eval, tilt_deg=tilt,
                               readings=readings if learned else None,
                               readings_weight=config.learned, frame=frame, detail=window,
                               card=card)

    count_prior = count_prior or {}
    probability = count_prior.get(neural.n, 0.0) if count_prior else None
    outside = False
    if not seen:
        warnings.append("no yarn found in the photo (its core does not stand out from the "
                        "background); the search is skipped and the neural result kept")
        refine = False
    elif refine and config.gates_outside(setup):
        # the nets' yarn as they read it, before its colour is matched to the photo: the
        # match changes how dark, and so how wide, a core lit from behind renders
        ratio = width_ratio(objective_of(plan(config, setup, probability)), neural, small)
        outside = not within_gate(ratio)
        if outside:
            warnings.append(f"the nets' yarn renders {ratio:.2g} times as wide as the photo's "
                            "core: the yarn is outside the nets' range, so its thickness "
                            "(the fibers per ply following the plies' width), "
                            "flyaways and ply twist are searched in turn without their "
                            f"prior (stages '{setup_of(setup).outside_stages}')")
    chosen = plan(config, setup, probability, outside)
    if refine and chosen.gate == "unsure ply count":
        warnings.append(f"the nets give their ply count {neural.n} a probability of only "
                        f"{probability:.2f}: a ply pitch fitted with a wrong count is a "
                        "wrong pitch, so alpha_ply keeps the nets' value")
    if not refine:
        chosen = replace(chosen, stages=())
    if dry_run:
        return FitResult(neural, neural, float("nan"), float("nan"), False, warnings,
                         tilt_deg=tilt, config=config, plan=chosen)
    objective = objective_of(chosen)
    sigma = sigma if chosen.prior else None
    if seen:
        neural = match_colour(objective, neural, small)
    if not chosen.stages:
        loss = _mean_loss(objective, neural, config)
        return FitResult(neural, neural, loss, loss, False, warnings,
                         seconds=time.perf_counter() - t0, tilt_deg=tilt, sigma=sigma,
                         config=config, plan=chosen)
    start = (match_colour(objective, match_size(objective, neural, small), small)
             if config.match_size else neural)
    scores: dict[int, float] = {}

    def with_chosen_count(p: YarnParams) -> YarnParams:
        ratio = width_ratio(objective, p, small)
        if not within_gate(ratio):
            warnings.append(f"the yarn renders {ratio:.2g} times as wide as the photo's "
                            "core, so its ply count is kept: the count's choice reads "
                            "the core's outline (a search that fits the thickness first, "
                            "--params 'R_ply,r_x,r_y;alpha_ply', chooses it after)")
            return p
        new, found = choose_ply_count(objective, p, count_prior,
                                      (config.fiber_seed, *config.rescore_seeds),
                                      setup_of(setup).count_groups)
        scores.update(found)
        return new

    stages = chosen.stages
    if stages[0].search is None:  # the ply count first: chosen once, before the counts
        start, stages = with_chosen_count(start), stages[1:]
    counts = list(dict.fromkeys([start.n, *likeliest_counts(count_prior, config.ply_counts)]))
    result = search_ply_counts(objective, start, counts[:config.ply_counts], stages, on_eval,
                               sigma, with_chosen_count)
    best, best_loss = ((result.best, result.best_loss) if result.improved
                       else (start, result.start_loss))
    loss_neural, improved = result.start_loss, result.improved
    if start is not neural:  # another start counts only if its loss is lower too
        loss_neural = _mean_loss(objective, neural, config)
        improved = best_loss < loss_neural
    refined = match_colour(objective, best, small) if improved else neural
    if not improved:
        warnings.append("the search found no parameters with a lower loss than the nets' "
                        "over the re-scoring seeds" + (" (loss plus the nets' prior)"
                                                       if sigma else "")
                        + "; the neural result is kept")
    return FitResult(neural, refined, loss_neural, best_loss if improved else loss_neural,
                     improved, warnings, result, time.perf_counter() - t0, tilt, sigma,
                     scores, config, chosen)


def search_objective(photo: Photo, renderer, config: FitConfig
                     ) -> tuple[RenderObjective, np.ndarray]:
    """``(objective, small)``: the objective a fit searches ``photo`` with (its view at the
    search's pitch, :func:`search_view`; its tilt; ``config``'s samples and seeds per
    evaluation), and the photo at that pitch; for the benchmarks that score what a fit
    sees without searching."""
    scale, frame = search_view(photo, config.scale)
    small = photo.at_pitch(scale)
    return RenderObjective(renderer, small, scale, config.spp,
                           seeds_per_eval=config.seeds_per_eval,
                           tilt_deg=photo_tilt(on_scene_card(small, photo.setup)), frame=frame,
                           card=search_card(small, photo.setup)), small


def _mean_loss(objective: RenderObjective, p: YarnParams, config: FitConfig) -> float:
    return float(np.mean([objective(p, s) for s in (config.fiber_seed, *config.rescore_seeds)]))
