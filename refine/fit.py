"""``ipm fit``: the nets' guess, refined by render-and-compare (the part beyond the paper).

Steps: exposure check of the photo; the neural ensemble's parameters; the fiber colour (the
paper does not infer appearance) matched to the photo's core; then, with ``refine``, the
NLopt search (:mod:`ipm.refine.search`) of the continuous raw-yarn parameters on the
statistics loss (:mod:`ipm.refine.objective`) at a low resolution.  The losses reported for
both results are means over the search seed and the re-scoring seeds, so they compare.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace

import numpy as np
from scipy.stats import norm

from ipm.errors import UserError
from ipm.frame import PIXEL_SIZE_MM
from ipm.params import PAPER_INTERVALS, RAW_CONTINUOUS, YarnParams, clipped
from ipm.photo import Photo, srgb_to_linear
from ipm.refine.capture import LIGHT_BACKGROUND, in_capture, matched_blur, matched_level
from ipm.refine.objective import (
    COUNT_GROUPS,
    THICKNESS,
    Detail,
    Readings,
    RenderObjective,
    centre_crop,
    search_weights,
    to_tensor,
)
from ipm.refine.search import (
    DEFAULT_LEARNED,
    DEFAULT_PLY_COUNTS,
    LEVEL,
    SURE_COUNT,
    SearchOptions,
    SearchResult,
    least_budget,
    likeliest_counts,
    ply_count_scores,
    same_period,
    search_ply_counts,
    search_stages_of,
)
from ipm.refine.stats import centre_rows, core_width, yarn_centre, yarn_tilt
from ipm.render.photometric import Photometric
from ipm.render.scene import Frame, frame_size, pixel_size_mm

#: A photo with more than this fraction of pixels at either end of the range is strongly
#: under- or over-exposed, where the paper's nets do not hold.
CLIPPED_WARN = 0.02
#: The core must differ from the background by this much (sRGB) for a yarn to be seen.
MIN_CORE_CONTRAST = 0.03
#: A yarn whose render's core is not within this factor of the photo's width is not one the
#: nets can read: a fit searches its thickness first (``FitOptions.outside``), and chooses
#: its ply count (:func:`choose_ply_count`) only once within it, since the choice reads the
#: core's outline at that thickness (on the real photos, whose yarns the nets' render far
#: wider, it misread the count: docs/real-photos-count; the widths of each set of photos:
#: benchmarks/results/count_width.md).
COUNT_WIDTH_FACTOR = 1.5
#: The search of a yarn outside the nets' range (``outside`` of :class:`FitOptions`): its
#: thickness, then its flyaways, then the ply twist, each stage from the best of the one
#: before, a local polish of each stage of several parameters, and no prior from the nets,
#: whose reading of such a yarn is off their training data; the fibers per ply follow the
#: plies' width (``keep_cover``, :func:`ipm.refine.search.same_cover`).  The recipe that
#: fitted the 24 real backlit photos (docs/real-photos-default), whose yarns are thinner
#: than any the nets know.
OUTSIDE_PARAMS = "R_ply,r_x,r_y;g,l_hair,l_loop,d_mean;alpha_ply"
OUTSIDE_POLISH = 16
#: Fiber seeds per evaluation of that search: one, at half the renders of two.  Its stages
#: re-score their best candidates on more seeds, and on the real photos one seed met the
#: targets as two did, within the spread between runs (docs/real-photos-one-seed against
#: docs/real-photos-two-seeds and docs/real-photos-fast; benchmarks/README.md).
OUTSIDE_SEEDS_PER_EVAL = 1
#: The setups whose photos' core width tells a yarn outside the nets' range.  Not frontlit:
#: there the core's half-contrast width follows the light, and ipm's own held-out renders,
#: whose thickness the nets read well, reached the gate too (count_width.md).
OUTSIDE_SETUPS = ("backlit",)


@dataclass(frozen=True)
class FitOptions:
    """scale, spp: resolution and samples of the renders inside the search.  seeds_per_eval:
    fiber seeds averaged per evaluation.  search: the NLopt options.  ply_counts: how many
    of the nets' most likely ply counts the search tries (each a search of its own: the
    ply-stripe period the loss sees is ``alpha_ply / n``, so a wrong ``n`` makes the right
    period a wrong ``alpha_ply``).  display_scale, display_spp: the renders written for the
    user.  learned: the weight of the nets' readings in the loss (``readings`` of
    :func:`fit`; 0: the hand-made statistics alone).  detail: the weight of the detail nets'
    readings of a window at their pitch, rendered per evaluation besides the search's view
    (``detail`` of :func:`fit`, :class:`ipm.refine.objective.Detail`; 0: none).
    match_size: start the search from the nets' yarn scaled to the photo's core width
    (:func:`match_size`) instead of from the nets' yarn itself.  choose_count: in a setup
    with :data:`ipm.refine.objective.COUNT_GROUPS`, start from the ply count those groups
    and the nets' probabilities choose (:func:`choose_ply_count`) instead of the nets':
    before the search when its first stage moves ``alpha_ply``, else before the first
    stage that does, from the stages before's best.  Why not always first: the choice
    sees the thickness it starts from, and on the real photos, thinner than any yarn the
    nets know, at the nets' thickness it chose 4 plies for most of the 2-ply yarns
    (docs/real-photos-count).  outside: in :data:`OUTSIDE_SETUPS`, when the nets' yarn
    renders more than :data:`COUNT_WIDTH_FACTOR` times wider or narrower than the photo's
    core, the yarn is outside the nets' range (benchmarks/results/count_width.md): search it
    as :data:`OUTSIDE_PARAMS` says, without the nets' prior, instead of ``search`` (the CLI
    turns this off when the user chooses the search, ``--params`` or ``--no-prior``).
    sure_count: a fit that keeps the nets' ply count (a setup without a choice of the
    count, frontlit) searches ``alpha_ply`` only if the nets give their count at least
    this probability; else it keeps their pitch (and searches nothing if nothing else was
    asked).  Why: the search matches the photo's stripe period ``alpha_ply / n``, so with a
    wrong count it fits a wrong pitch, and frontlit the refinement lost where the nets' count
    was wrong what it gained where it was right (docs/compare-tuned); 0.5: the count more
    likely right than wrong, chosen before it was measured (docs/compare-sure-count)."""

    scale: float = 0.2
    spp: int = 4
    seeds_per_eval: int = 2
    search: SearchOptions = field(default_factory=SearchOptions)
    ply_counts: int = DEFAULT_PLY_COUNTS
    display_scale: float = 0.5
    display_spp: int = 16
    learned: float = DEFAULT_LEARNED
    detail: float = 0.0
    match_size: bool = False
    choose_count: bool = True
    outside: bool = True
    sure_count: float = SURE_COUNT

    def __post_init__(self) -> None:
        if not 0.05 <= self.scale <= 1 or not 0.05 <= self.display_scale <= 1:
            raise UserError(f"scales must be in [0.05, 1], got {self.scale}, "
                            f"{self.display_scale}")
        if min(self.spp, self.display_spp, self.seeds_per_eval, self.ply_counts) < 1:
            raise UserError("spp, seeds_per_eval and ply_counts must be >= 1")
        if not (0 <= self.learned < 1e6 and 0 <= self.detail < 1e6):
            raise UserError(f"the weights of the nets' readings must be >= 0, got "
                            f"{self.learned}, {self.detail}")

    def outside_search(self) -> FitOptions:
        """These options with the search of a yarn outside the nets' range
        (:data:`OUTSIDE_PARAMS` with ``keep_cover``; ``search``'s algorithm, seeds and
        budget, raised to the least its four-parameter stage takes;
        :data:`OUTSIDE_SEEDS_PER_EVAL`)."""
        stages = search_stages_of(OUTSIDE_PARAMS)
        least = least_budget((stages["params"], *stages["later"]))
        search = replace(self.search, **stages, budget=max(self.search.budget, least),
                         polish=max(self.search.polish, OUTSIDE_POLISH), keep_cover=True)
        return replace(self, search=search, outside=False,
                       seeds_per_eval=min(self.seeds_per_eval, OUTSIDE_SEEDS_PER_EVAL))

    def without_pitch(self) -> FitOptions | None:
        """These options with ``alpha_ply`` taken out of the search's stages (a fit that
        keeps the nets' pitch, :func:`unsure_count`); None if no stage is left."""
        stages = [kept for stage in self.search.stages
                  if (kept := tuple(k for k in stage if k != "alpha_ply"))]
        if not stages:
            return None
        return replace(self, search=replace(self.search, params=stages[0],
                                            later=tuple(stages[1:])))

    def count_groups(self, setup: str) -> tuple[str, ...]:
        """The groups a fit of a photo of ``setup`` chooses its ply count by (``choose_count``;
        none: the nets' count)."""
        if not self.choose_count or "alpha_ply" not in self.search.searched:
            return ()
        return COUNT_GROUPS[setup]


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
    ``docs/compare-cycles-frontlit``); the hull holds it about as often as the nets'
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
    options: FitOptions | None = None  # those the fit ran with (FitOptions.outside_search)

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

    def to_dict(self, pixel_size_mm: float, setup: str = "frontlit") -> dict:
        options = self.options or FitOptions()
        return {
            "neural": self.neural.to_dict(), "refined": self.refined.to_dict(),
            "loss": {"neural": self.loss_neural, "refined": self.loss_refined},
            "improved": self.improved, "warnings": self.warnings,
            "intervals": {"level": LEVEL, **{k: list(v) for k, v in self.intervals().items()}},
            "evaluations": self.search.evaluations if self.search else 0,
            **({"ply_count_scores": {str(n): round(v, 3) for n, v in self.count_scores.items()}}
               if self.count_scores else {}),
            "seconds": round(self.seconds, 2),
            "settings": {**asdict(options), "pixel_size_mm": pixel_size_mm, "setup": setup,
                         "tilt_deg": round(self.tilt_deg, 3), "prior_sigma": self.sigma},
        }


def exposure_warning(image: np.ndarray) -> str | None:
    """A warning naming the clipped fractions if the photo is strongly mis-exposed."""
    gray = image.mean(axis=-1)
    dark, bright = float((gray <= 1 / 255).mean()), float((gray >= 254 / 255).mean())
    if max(dark, bright) > CLIPPED_WARN:
        return (f"photo looks {'over' if bright > dark else 'under'}-exposed: {bright:.1%} of "
                f"pixels clipped white, {dark:.1%} black; the nets hold for photos that are "
                "not strongly over- or under-exposed")
    return None


def core_contrast(image_srgb: np.ndarray) -> float:
    """Largest per-row median deviation from the background (sRGB): a yarn's core makes it
    large, an empty or flat photo leaves it near 0."""
    gray = to_tensor(image_srgb).mean(dim=1, keepdim=True)
    bg, _ = yarn_centre(gray)
    return float((gray - bg.view(-1, 1, 1, 1)).abs().median(dim=-1).values.max())


def core_colour(image_srgb: np.ndarray) -> np.ndarray:
    """Mean linear RGB (3,) of the middle rows of the yarn's core."""
    t = to_tensor(image_srgb)
    _, centre = yarn_centre(t.mean(dim=1, keepdim=True))
    centred = centre_rows(t, centre)[0].permute(1, 2, 0).numpy()
    h = centred.shape[0]
    band = centred[h // 2 - max(1, h // 30): h // 2 + max(1, h // 30) + 1]
    return srgb_to_linear(band).reshape(-1, 3).mean(axis=0)


def match_colour(objective: RenderObjective, params: YarnParams, photo: np.ndarray,
                 rounds: int = 2) -> YarnParams:
    """Scale the fiber albedo per channel until the render's core colour matches the
    photo's (the radiance grows about linearly with the albedo; two rounds suffice)."""
    target = core_colour(photo)
    for _ in range(rounds):
        got = core_colour(objective.render(params, 0))
        colour = np.clip(np.array(params.color) * target / np.maximum(got, 1e-4), 0.01, 0.95)
        params = params.replace(color=tuple(float(c) for c in colour))
    return params


def image_core_width(img: np.ndarray) -> float:
    """The core's width (px) of an sRGB image (:func:`ipm.refine.stats.core_width`)."""
    return float(core_width(to_tensor(img).mean(dim=1, keepdim=True))[0])


def within_gate(ratio: float) -> bool:
    """Whether a render's core is within :data:`COUNT_WIDTH_FACTOR` of the photo's width
    (``ratio``: :func:`width_ratio`)."""
    return 1 / COUNT_WIDTH_FACTOR <= ratio <= COUNT_WIDTH_FACTOR


def width_ratio(objective: RenderObjective, params: YarnParams, photo: np.ndarray) -> float:
    """How many times as wide as ``photo``'s core the render of ``params`` is
    (:func:`image_core_width`, fiber seed 0)."""
    return image_core_width(objective.render(params, 0)) / max(image_core_width(photo), 1e-9)


def match_size(objective: RenderObjective, params: YarnParams, photo: np.ndarray,
               rounds: int = 2) -> YarnParams:
    """``params`` with R_ply, r_x and r_y scaled by one factor until the render's core is as
    wide as the photo's (:func:`ipm.refine.stats.core_width`; the width grows about linearly
    with the factor, two rounds suffice).

    Why one factor: the core's width is what the image shows of the thickness; how it
    splits between the ply helix and the plies' two radii it hardly shows (``r_y`` is not
    identifiable, nor ``r_x`` in the backlit setup: docs/identifiability.md,
    docs/identifiability-backlit-contour.md).  A search of the three on the real photos,
    thinner than the nets know, flattened the plies (``r_y`` well below ``r_x``:
    docs/real-photos-contour), and flattened plies bump the core's outline twice per ply
    crossing.  Scaling keeps the nets' proportions and matches the width.  Whether a fit
    from the sized start does better is not yet measured, so it is an option."""
    target = image_core_width(photo)
    for _ in range(rounds):
        got = image_core_width(objective.render(params, 0))
        if not (target > 0 and got > 0):
            break
        factor = float(np.clip(target / got, 0.25, 4.0))
        params = params.replace(**{k: clipped(k, getattr(params, k) * factor)
                                   for k in THICKNESS})
    return params


def choose_ply_count(objective: RenderObjective, start: YarnParams, prior: dict[int, float],
                     seeds: Sequence[int]) -> tuple[YarnParams, dict[int, float]]:
    """The ply count of ``start`` chosen by the setup's :data:`COUNT_GROUPS` and the nets'
    probabilities ``prior`` (:func:`ipm.refine.search.ply_count_scores` of the groups' loss
    over ``seeds``), each count with ``start``'s stripe period (:func:`same_period`), and
    the scores; ``start`` and no scores where the setup has no such groups.

    Why the period kept: the stripes' period ``alpha_ply / n`` is what the nets and the
    pitch search read best; a count is then judged by what differs between counts at one
    period.  Why the nets' probabilities: a count they find unlikely needs the loss's word
    by more than its seed noise."""
    groups = COUNT_GROUPS[objective.setup]
    candidates = {n: same_period(start, n) for n in prior}
    candidates = {n: p for n, p in candidates.items() if p is not None}
    if not groups or len(candidates) < 2:
        return start, {}
    weights = {k: 1.0 if k in groups else 0.0 for k in objective.photo_stats}
    scores = ply_count_scores({n: [objective(p, s, weights) for s in seeds]
                               for n, p in candidates.items()}, prior)
    best = min(scores, key=scores.__getitem__)
    return (start if best == start.n else candidates[best]), scores


def fit(photo: Photo, neural: YarnParams, renderer, options: FitOptions = FitOptions(),
        refine: bool = True, on_eval: Callable[[int, float, float], None] | None = None,
        sigma: dict[str, float] | None = None, readings: Readings | None = None,
        detail: tuple[Readings, float] | None = None,
        count_prior: dict[int, float] | None = None) -> FitResult:
    """Fit ``photo`` starting from the nets' parameters ``neural``; ``sigma``, the nets'
    error per parameter (:meth:`ipm.nets.ensemble.Ensemble.sigma`), makes the search a MAP
    estimate around them (:mod:`ipm.refine.search`).
    ``readings``: the nets' readings (:meth:`ipm.nets.ensemble.Ensemble.readings`), added
    to the loss at weight ``options.learned`` when that is above 0.  ``detail``: the detail
    nets' readings and pitch (:meth:`ipm.nets.ensemble.Ensemble.detail_readings`; None for
    a photo too coarse for them), compared on a window at weight ``options.detail``.
    ``count_prior``: the nets' probability of each ply count
    (:meth:`ipm.nets.ensemble.Ensemble.ply_count_probabilities`); with
    ``options.choose_count`` the search starts from the count :func:`choose_ply_count`
    chooses, and with ``options.ply_counts`` above 1 it runs from there with each of the
    likeliest counts too and keeps the lowest loss (:func:`search_ply_counts`).  The refined
    result differs from the nets' only if its loss is lower."""
    t0 = time.perf_counter()
    warnings = [w for w in (exposure_warning(photo.image),) if w]
    scale, frame = search_view(photo, options.scale)
    small = photo.at_pitch(scale)
    seen = core_contrast(small) >= MIN_CORE_CONTRAST
    tilt = photo_tilt(small) if seen else 0.0
    learned = options.learned > 0 and readings is not None
    window = (Detail.of_photo(photo, *detail, weight=options.detail, spp=options.spp)
              if options.detail > 0 and detail is not None and seen else None)
    if options.detail > 0 and detail is None:
        warnings.append(f"no detail nets read photos of {photo.pixel_size_mm:g} mm per pixel "
                        "(the shipped ones need 0.0125 mm or finer); the loss has no detail "
                        "window")

    def objective_of(opts: FitOptions) -> RenderObjective:
        return RenderObjective(renderer, small, scale, opts.spp,
                               weights=search_weights(opts.search.searched),
                               seeds_per_eval=opts.seeds_per_eval, tilt_deg=tilt,
                               readings=readings if learned else None,
                               readings_weight=opts.learned, frame=frame, detail=window)

    objective = objective_of(options)
    if not seen:
        warnings.append("no yarn found in the photo (its core does not stand out from the "
                        "background); the search is skipped and the neural result kept")
        refine = False
    elif refine and options.outside and photo.setup in OUTSIDE_SETUPS:
        # the nets' yarn as they read it, before its colour is matched to the photo: the
        # match changes how dark, and so how wide, a backlit core renders
        ratio = width_ratio(objective, neural, small)
        if not within_gate(ratio):
            warnings.append(f"the nets' yarn renders {ratio:.2g} times as wide as the photo's "
                            "core: the yarn is outside the nets' range, so its thickness "
                            "(the fibers per ply following the plies' width), "
                            "flyaways and ply twist are searched in turn without their "
                            f"prior (stages '{OUTSIDE_PARAMS}')")
            options, sigma = options.outside_search(), None
            objective = objective_of(options)
    count_prior = count_prior or {}
    if refine and unsure_count(options, neural, count_prior, photo.setup):
        warnings.append(f"the nets give their ply count {neural.n} a probability of only "
                        f"{count_prior.get(neural.n, 0.0):.2f}: a ply pitch fitted "
                        "with a wrong count is a wrong pitch, so alpha_ply keeps the nets' "
                        "value")
        without = options.without_pitch()
        refine = without is not None
        if refine:
            options = without
            objective = objective_of(options)
    if seen:
        neural = match_colour(objective, neural, small)
    if not refine:
        loss = _mean_loss(objective, neural, options.search)
        return FitResult(neural, neural, loss, loss, False, warnings,
                         seconds=time.perf_counter() - t0, tilt_deg=tilt, sigma=sigma,
                         options=options)
    start = (match_colour(objective, match_size(objective, neural, small), small)
             if options.match_size else neural)
    scores: dict[int, float] = {}
    choose: Callable[[YarnParams], YarnParams] | None = None
    if count_prior and options.count_groups(objective.setup):
        seeds = (options.search.fiber_seed, *options.search.rescore_seeds)

        def with_chosen_count(p: YarnParams) -> YarnParams:
            ratio = width_ratio(objective, p, small)
            if not within_gate(ratio):
                warnings.append(f"the yarn renders {ratio:.2g} times as wide as the photo's "
                                "core, so its ply count is kept: the count's choice reads "
                                "the core's outline (a search that fits the thickness first, "
                                "--params 'R_ply,r_x,r_y;alpha_ply', chooses it after)")
                return p
            chosen, found = choose_ply_count(objective, p, count_prior, seeds)
            scores.update(found)
            return chosen

        choose = with_chosen_count
        if "alpha_ply" in options.search.stages[0]:  # chosen before the search
            start, choose = with_chosen_count(start), None
    counts = list(dict.fromkeys([start.n, *likeliest_counts(count_prior,
                                                            options.ply_counts)]))
    result = search_ply_counts(objective, start, counts[:options.ply_counts], options.search,
                               on_eval, sigma, choose)
    best, best_loss = ((result.best, result.best_loss) if result.improved
                       else (start, result.start_loss))
    loss_neural, improved = result.start_loss, result.improved
    if start is not neural:  # another start counts only if its loss is lower too
        loss_neural = _mean_loss(objective, neural, options.search)
        improved = best_loss < loss_neural
    refined = match_colour(objective, best, small) if improved else neural
    if not improved:
        warnings.append("the search found no parameters with a lower loss than the nets' "
                        "over the re-scoring seeds" + (" (loss plus the nets' prior)"
                                                       if sigma else "")
                        + "; the neural result is kept")
    return FitResult(neural, refined, loss_neural, best_loss if improved else loss_neural,
                     improved, warnings, result, time.perf_counter() - t0, tilt, sigma,
                     scores, options)


def unsure_count(options: FitOptions, p: YarnParams, count_prior: dict[int, float],
                 setup: str) -> bool:
    """Whether a fit of ``p`` with ``options`` keeps the nets' ply count without choosing
    it (:meth:`FitOptions.count_groups`), searches ``alpha_ply``, and has the nets' count
    below ``options.sure_count`` in ``count_prior`` (the nets' probabilities; none: not
    unsure)."""
    return (bool(count_prior) and not options.count_groups(setup)
            and "alpha_ply" in options.search.searched
            and count_prior.get(p.n, 0.0) < options.sure_count)


def search_view(photo: Photo, scale: float) -> tuple[float, Frame | None]:
    """The scale, and the view if not the yarn frame, that the search renders ``photo`` at.

    A photo that shows less than the yarn frame with pixels finer than ``scale``'s (a
    microscope's 3 x 2.3 mm at 0.002 mm) is searched over its own field of view at the
    pitch that gives it as many pixels as the yarn frame has at ``scale``, but no finer than
    its own pixels or the scene's :data:`PIXEL_SIZE_MM`: its core and ply stripes then span
    as many pixels as a full frame's would, for the same cost per render (at ``scale``'s
    pitch such a photo is 60 x 45 px).  Any other photo: ``(scale, None)``."""
    h, w = photo.image.shape[:2]
    frame_w, frame_h = frame_size(scale)
    area = h * w * photo.pixel_size_mm ** 2
    pitch = max(PIXEL_SIZE_MM, photo.pixel_size_mm, float(np.sqrt(area / (frame_w * frame_h))))
    if pitch >= pixel_size_mm(scale) * (1 - 1e-6):
        return scale, None
    fine = PIXEL_SIZE_MM / pitch
    max_w, max_h = frame_size(fine)
    return fine, Frame(min(max_w, round(w * photo.pixel_size_mm / pitch)),
                       min(max_h, round(h * photo.pixel_size_mm / pitch)), pitch)


def photo_tilt(image_srgb: np.ndarray) -> float:
    """The yarn's tilt in the photo, degrees counter-clockwise (:func:`yarn_tilt`).  The
    renders of the search are tilted the same way, so that a tilted photo's wider core
    profile is not mistaken for a thicker yarn."""
    return float(yarn_tilt(to_tensor(image_srgb).mean(dim=1, keepdim=True))[0])


def search_objective(photo: Photo, renderer, options: FitOptions
                     ) -> tuple[RenderObjective, np.ndarray]:
    """``(objective, small)``: the objective a fit searches ``photo`` with (its view at the
    search's pitch, :func:`search_view`; its tilt; ``options``' samples and seeds per
    evaluation), and the photo at that pitch; for the benchmarks that score what a fit
    sees without searching."""
    scale, frame = search_view(photo, options.scale)
    small = photo.at_pitch(scale)
    return RenderObjective(renderer, small, scale, options.spp,
                           seeds_per_eval=options.seeds_per_eval, tilt_deg=photo_tilt(small),
                           frame=frame), small


def _mean_loss(objective: RenderObjective, p: YarnParams, opts: SearchOptions) -> float:
    return float(np.mean([objective(p, s) for s in (opts.fiber_seed, *opts.rescore_seeds)]))


#: A card within this many stops of the photo's is shown as the scene renders it (a tenth
#: of a stop is not seen).
CARD_TOLERANCE_STOPS = 0.1


def display_renders(renderer, photo: Photo, result: FitResult, options: FitOptions
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, Photometric]:
    """(photo, neural render, refined render) as sRGB at ``display_scale`` (a photo of a
    smaller field of view at a finer pitch, :func:`search_view`), cut to their common
    extent, the renders in the photo's capture, and that capture (:mod:`ipm.refine.capture`:
    frontlit the card's albedo matched on a render at the search's pitch, rendered with; the
    exposure, backlit, and the defocus matched on the refined render, applied to both)."""
    scale, frame = search_view(photo, options.display_scale)
    shown = photo.at_pitch(scale)
    pitch = pixel_size_mm(scale)

    def rendered(p: YarnParams, look: Photometric) -> np.ndarray:
        img = renderer.render(p, options.search.fiber_seed, scale, options.display_spp,
                              photometric=look, frame=frame)
        return centre_crop(img, min(shown.shape[0], img.shape[0]),
                           min(shown.shape[1], img.shape[1]))

    tilted = scene = Photometric(rotation_deg=result.tilt_deg)
    setup = renderer.options.setup
    if setup not in LIGHT_BACKGROUND:  # the card's albedo, from a render at the search's pitch
        probe_scale, probe_frame = search_view(photo, options.scale)
        probe = renderer.render(result.refined, options.search.fiber_seed, probe_scale,
                                options.spp, photometric=tilted, frame=probe_frame)
        small = photo.at_pitch(probe_scale)
        h, w = min(small.shape[0], probe.shape[0]), min(small.shape[1], probe.shape[1])
        card = matched_level(centre_crop(small, h, w), centre_crop(probe, h, w), tilted, setup)
        if abs(np.log2(card.backdrop_gain)) > CARD_TOLERANCE_STOPS:
            scene = card
    refined, neural = (rendered(p, scene) for p in (result.refined, result.neural))
    shown = centre_crop(shown, *refined.shape[:2])
    level = matched_level(shown, refined, scene, setup) if setup in LIGHT_BACKGROUND else scene
    capture = matched_blur(shown, refined, pitch, level)
    return (shown, *(in_capture(img, capture, pitch) for img in (neural, refined)), capture)


def summary_lines(result: FitResult) -> list[str]:
    """The fitted yarn in a few lines for the terminal: the ply count (and the nets') and the
    six raw-yarn parameters with their :data:`LEVEL` intervals (``params.json`` holds all
    twenty and where each interval comes from)."""
    r, n = result.refined, result.neural
    lines = [f"fitted yarn ({LEVEL:.0%} intervals; params.json holds every parameter):",
             f"  n          {r.n:>7d}     plies" + ("" if r.n == n.n else f" (nets: {n.n})")]
    intervals = result.intervals()
    for k in ("R_ply", "alpha_ply", "r_x", "r_y", "alpha", "m"):
        iv = f"[{intervals[k][0]:.3g}, {intervals[k][1]:.3g}]" if k in intervals else ""
        lines.append(f"  {k:<10s} {getattr(r, k):>7.3g} {PAPER_INTERVALS[k].unit:<3s} "
                     f"{iv:<18s} {PAPER_INTERVALS[k].meaning}")
    return lines


def compare_image(panels: list[np.ndarray], labels: list[str]) -> np.ndarray:
    """sRGB panels of one width stacked top to bottom (the yarn is wide), each with its label
    underneath; (H, W, 3) uint8."""
    from PIL import Image, ImageDraw

    w = panels[0].shape[1]
    bar = 18
    out = Image.new("RGB", (w, sum(p.shape[0] + bar for p in panels)), (255, 255, 255))
    draw = ImageDraw.Draw(out)
    top = 0
    for img, label in zip(panels, labels, strict=True):
        out.paste(Image.fromarray((np.clip(img, 0, 1) * 255).round().astype(np.uint8)),
                  (0, top))
        top += img.shape[0]
        draw.text((4, top + 3), label, fill=(0, 0, 0))
        top += bar
    return np.asarray(out)
