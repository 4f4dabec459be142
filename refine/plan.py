"""A fit as named stages: :class:`FitConfig`, the one description of how a photo is fitted
(``ipm fit`` and ``ipm compare`` make their options from its fields), and :func:`plan`, the
stages the fit of one photo runs, chosen before the search by its gates.

The stages, each searched from the best of the one before, and the loss groups
(:mod:`ipm.refine.stats`) each is scored by:

* **ply count**: the count that the setup's ``count_groups`` (:mod:`ipm.setups`) and the
  nets' probabilities choose (:func:`ipm.refine.measure.choose_ply_count`), each count at
  the nets' stripe period; before the first stage that moves ``alpha_ply``, in a setup with
  such groups, unless ``nets_ply_count``.  Why not always first: the choice sees the
  thickness it starts from, and on the real photos, thinner than any yarn the nets know, at
  the nets' thickness it chose 4 plies for most of the 2-ply yarns (real-photos-count@35cd98b).
* **thickness** (``R_ply``, ``r_x``, ``r_y`` without ``alpha_ply``): the whole loss but the
  ``contour``.  At a pitch not yet fitted the outline's period is wrong, and plies
  flattened to half their width bump the outline twice as often: on the real photos a
  thickness stage scored with the contour left the pitch stage after it at about twice the
  photo's period on several photos (real-photos-contour@dbf762e against
  real-photos-contour-pitch@8c0ba8a).
* **flyaways** (flyaway parameters alone): the ``flyaways`` group alone.  Flyaways that
  cross the core band move the period and stripes groups too, and on a real photo a grid of
  flyaway amounts and lengths moved those more than the flyaway group: scored by every
  group, the stage would follow the stripes.
* **ply twist** (``alpha_ply`` alone): the setup's ``pitch_groups``, those that read the ply
  period.  The core profile and the silhouette read the thickness too, and a search of the
  pitch alone keeps the thickness: a ply twist tighter or looser than the photo's then
  makes up for a ply radius the nets got wrong (benchmarks/results/pitch_profile_*_val.md);
  on the real photos the core group pulled the pitch back towards the nets' where the
  stripes put it at the photo's (real-photos-flyaways@4c80682 against real-photos-pitch@31dc737).
  The contour, the outline's period, helps where the outline is a crisp silhouette.
* any other stage: the whole loss.

A setup's default search is the ply twist alone: the loss also has its minimum at the truth
for ``R_ply`` and ``r_x`` (docs/identifiability.md), but a second stage searching them from
the twist's best moved them further from the truth than the nets' values
(compare-staged@26a8a03), and the image statistics do not see ``alpha``, so the other
parameters keep the nets' values.

The gates of :func:`plan`, each a different list of stages:

* **outside the nets' range**: in a setup with ``outside_stages``, when the nets' yarn
  renders more than :data:`COUNT_WIDTH_FACTOR` times wider or narrower than the photo's
  core (:func:`ipm.refine.measure.width_ratio`, benchmarks/results/count_width.md), the
  default search becomes those stages (thickness, flyaways, ply count, ply twist) without
  the nets' prior, whose reading of such a yarn is off their training data; a polish of
  each stage of several parameters (:data:`OUTSIDE_POLISH`); the fibers per ply following
  the plies' width (``keep_cover``, :func:`ipm.refine.search.same_cover`); one fiber seed
  per evaluation (:data:`OUTSIDE_SEEDS_PER_EVAL`).  The recipe that fitted the real photos
  lit from behind (real-photos-default@d6136c7), whose yarns are thinner than any the nets
  know.  Not where the core's half-contrast width follows the light: there ipm's own
  held-out renders, whose thickness the nets read well, reached the gate too.
* **an unsure ply count**: a fit that keeps the nets' count searches ``alpha_ply`` only if
  the nets give their count at least ``sure_count``; else its stages lose ``alpha_ply``
  (none left: no search).  The search matches the photo's stripe period ``alpha_ply / n``,
  so with a wrong count it fits a wrong pitch, and the refinement lost where the nets'
  count was wrong what it gained where it was right (compare-tuned@221fbc4).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ipm.errors import UserError
from ipm.prior import FLYAWAY_RANGES
from ipm.refine.search import SearchOptions, Stage, least_budget, parse_stages
from ipm.setups import SETUPS, setup_of

#: The thickness parameters: a stage moving them without the ply pitch is scored without the
#: ``contour`` group.
THICKNESS = ("R_ply", "r_x", "r_y")
#: A yarn whose render's core is not within this factor of the photo's width is not one the
#: nets can read: a fit searches it as outside their range, and chooses its ply count only
#: once within it, since the choice reads the core's outline at that thickness (on the real
#: photos, whose yarns the nets render far wider, it misread the count:
#: real-photos-count@35cd98b; the widths of each set of photos: count_width.md).
COUNT_WIDTH_FACTOR = 1.5
#: The polish of each stage of several parameters of a yarn outside the nets' range.
OUTSIDE_POLISH = 16
#: Fiber seeds per evaluation of that search: one, at half the renders of two.  Its stages
#: re-score their best candidates on more seeds, and on the real photos one seed met the
#: targets as two did, within the spread between runs (real-photos-one-seed@8468b85).
OUTSIDE_SEEDS_PER_EVAL = 1

_PARAMS_HELP = ("parameters to search (any but the ply count n; m is rounded), "
                "comma-separated (alpha_ply,R_ply); stages separated by ';' "
                "(alpha_ply;R_ply,r_x: those from alpha_ply's best); the others keep the "
                "nets' values; default: the capture setup's stages (--dry-run lists them).  "
                "A stage of flyaway parameters alone (g,l_hair,d_mean) is scored by the "
                "flyaway profile, over the whole sampler range; alpha_ply alone by the "
                "groups that read the ply period; the thickness without alpha_ply by all "
                "but the outline")


def _option(default, help: str, *decls: str, **limits):
    """A field that is also an option of ``ipm fit`` and ``ipm compare``: its help, its flag
    names if not the field's, and typer's ``min``/``max``."""
    return field(default=default, metadata={"help": help, "decls": decls, **limits})


@dataclass(frozen=True)
class FitConfig:
    """How a photo is fitted.  The fields with help are the commands' options (their help
    says what each does); the others are the renders' and the search's fixed settings:
    scale, spp: resolution and samples of the renders inside the search; seeds_per_eval:
    fiber seeds averaged per evaluation; display_scale, display_spp: the renders written
    for the user; width, fiber_seed, rescore_seeds, rescore_top, prior_weight, box_sigmas:
    those of :class:`ipm.refine.search.SearchOptions`."""

    params: str | None = _option(None, _PARAMS_HELP)
    budget: int = _option(30, "objective evaluations of each stage's search")
    algorithm: str = _option("GN_DIRECT_L", "NLopt algorithm")
    polish: int = _option(0, "evaluations of a local search (BOBYQA) from the best of each "
                          "stage of two or more parameters, beyond the budget: a global "
                          "search's budget only samples a coarse grid there (0: none)", min=0)
    time_s: float | None = _option(None, "wall-time bound of each stage's search, seconds",
                                   "--time")
    ply_counts: int = _option(1, "search with each of the nets' N most likely ply counts and "
                              "keep the lowest loss (1: the nets' ply count only)", min=1, max=5)
    prior: bool = _option(True, "keep the search near the nets' guess, weighted by the nets' "
                          "validation error (MAP); --no-prior: the image loss alone",
                          "--prior/--no-prior")
    learned: float = _option(0.0, "weight of the nets' readings in the loss: renders the nets "
                             "read as they read the photo (0: the image statistics alone)",
                             min=0)
    detail: float = _option(0.0, "weight of the detail nets' readings (alpha, m) of a window "
                            "rendered at their pitch each evaluation, for photos as fine as "
                            "they need (0: none)", min=0)
    match_size: bool = _option(False, "start the search from the nets' yarn scaled (R_ply, "
                               "r_x, r_y by one factor) to the photo's core width, keeping "
                               "the nets' proportions: for yarns thinner or thicker than the "
                               "nets know", "--match-size")
    nets_ply_count: bool = _option(False, "keep the nets' ply count; by default, in a capture "
                                   "setup whose loss tells the count (the silhouette), a fit "
                                   "chooses it by the loss and the nets' probabilities "
                                   "before it searches alpha_ply", "--nets-ply-count")
    sure_count: float = _option(0.5, "where a fit keeps the nets' ply count, search alpha_ply "
                                "only if the nets give that count at least this probability "
                                "(0: always)", min=0, max=1)
    scale: float = 0.2
    spp: int = 4
    seeds_per_eval: int = 2
    display_scale: float = 0.5
    display_spp: int = 16
    # a stage's settings, defaulting to the one search's (SearchOptions holds them)
    width: float = SearchOptions.width
    fiber_seed: int = SearchOptions.fiber_seed
    rescore_seeds: tuple[int, ...] = SearchOptions.rescore_seeds
    rescore_top: int = SearchOptions.rescore_top
    prior_weight: float = SearchOptions.prior_weight
    box_sigmas: float = SearchOptions.box_sigmas

    def __post_init__(self) -> None:
        if not 0.05 <= self.scale <= 1 or not 0.05 <= self.display_scale <= 1:
            raise UserError(f"scales must be in [0.05, 1], got {self.scale}, "
                            f"{self.display_scale}")
        if min(self.spp, self.display_spp, self.seeds_per_eval, self.ply_counts) < 1:
            raise UserError("spp, seeds_per_eval and ply_counts must be >= 1")
        if not (0 <= self.learned < 1e6 and 0 <= self.detail < 1e6):
            raise UserError(f"the weights of the nets' readings must be >= 0, got "
                            f"{self.learned}, {self.detail}")
        texts = [self.params] if self.params is not None else [s.stages for s in SETUPS.values()]
        for params in (params for text in texts for params in parse_stages(text)):
            self.search_options(params, self.budget, self.polish)  # each stage's checks

    def search_options(self, params: tuple[str, ...], budget: int, polish: int,
                       keep_cover: bool = False) -> SearchOptions:
        """How a stage of ``params`` is searched."""
        return SearchOptions(params=params, algorithm=self.algorithm, budget=budget,
                             time_s=self.time_s, width=self.width, fiber_seed=self.fiber_seed,
                             rescore_seeds=self.rescore_seeds, rescore_top=self.rescore_top,
                             prior_weight=self.prior_weight, box_sigmas=self.box_sigmas,
                             polish=polish, keep_cover=keep_cover)

    def stage_params(self, setup: str) -> tuple[tuple[str, ...], ...]:
        """The parameters of the stages asked for (``params``, else the setup's), before any
        gate."""
        return parse_stages(self.params if self.params is not None else setup_of(setup).stages)

    def searched(self, setup: str) -> list[str]:
        """Every parameter of :meth:`stage_params`, in the stages' order."""
        return [k for stage in self.stage_params(setup) for k in stage]

    def gates_outside(self, setup: str) -> bool:
        """Whether a fit of a photo of ``setup`` checks that the yarn is within the nets'
        range: its setup has ``outside_stages``, the search is the setup's and the prior on."""
        s = setup_of(setup)
        return (s.outside_stages is not None and self.prior
                and self.stage_params(setup) == parse_stages(s.stages))

    def chooses_count(self, setup: str) -> bool:
        """Whether a fit of a photo of ``setup`` chooses its ply count (module doc)."""
        return (not self.nets_ply_count and bool(setup_of(setup).count_groups)
                and "alpha_ply" in self.searched(setup))


@dataclass(frozen=True)
class Plan:
    """What a fit runs: its ``stages``, the fiber seeds per evaluation, whether the nets'
    prior holds the search (``prior``), and the gate that chose it (None: none did)."""

    stages: tuple[Stage, ...]
    seeds_per_eval: int
    prior: bool
    gate: str | None = None

    @property
    def searched(self) -> list[str]:
        return [k for stage in self.stages for k in stage.params]

    def to_dict(self) -> dict:
        return {"stages": [s.to_dict() for s in self.stages], "gate": self.gate,
                "seeds_per_eval": self.seeds_per_eval, "prior": self.prior}

    def lines(self) -> list[str]:
        """The plan for the terminal (``ipm fit --dry-run``)."""
        head = (f"stages ({self.seeds_per_eval} fiber seed(s) per evaluation, "
                f"{'with' if self.prior else 'without'} the nets' prior"
                + (f"; gate: {self.gate}" if self.gate else "") + "):")
        rows = []
        for i, s in enumerate(self.stages, 1):
            by = ("the whole loss" + (f" but {', '.join(s.without)}" if s.without else "")
                  if s.scored_by is None else ", ".join(s.scored_by))
            what = (f"search {','.join(s.params)}: {s.search.budget} evaluations"
                    + (f" + polish {s.search.polish}" if s.search.polish else "")
                    + (", m follows the plies' width" if s.search.keep_cover else "")
                    if s.search else "choose among the nets' likely counts")
            rows.append(f"  {i}. {s.name:<10s} {what}; scored by {by}")
        return [head, *(rows or ["  none: the nets' result is kept"])]


def stage_name(params: tuple[str, ...]) -> str:
    """What a stage of ``params`` is called."""
    if params == ("alpha_ply",):
        return "ply twist"
    if all(k in FLYAWAY_RANGES for k in params):
        return "flyaways"
    if set(params) <= set(THICKNESS):
        return "thickness"
    return "+".join(params)


def stage_for(params: tuple[str, ...], setup: str, search: SearchOptions | None = None
              ) -> Stage:
    """The stage searching ``params`` in a fit of a photo of ``setup``: its name and the
    loss it is scored by (module doc); ``search``: how (:meth:`FitConfig.search_options`)."""
    scoring: dict = {}
    if all(k in FLYAWAY_RANGES for k in params):
        scoring = {"scored_by": ("flyaways",)}
    elif params == ("alpha_ply",):
        scoring = {"scored_by": setup_of(setup).pitch_groups}
    elif set(params) & set(THICKNESS) and "alpha_ply" not in params:
        scoring = {"without": ("contour",)}
    return Stage(stage_name(params), search, **scoring)


def plan(config: FitConfig, setup: str, count_probability: float | None = None,
         outside: bool = False) -> Plan:
    """The stages a fit of a photo of ``setup`` runs (module doc).  ``count_probability``:
    the nets' probability of their own ply count (None: no probabilities, so no choice of
    the count and no unsure count); ``outside``: the yarn is outside the nets' range
    (:meth:`FitConfig.gates_outside`, decided by the caller on a render)."""
    s = setup_of(setup)
    stages = parse_stages(s.outside_stages) if outside else config.stage_params(setup)
    budget, polish = config.budget, config.polish
    if outside:
        budget, polish = max(budget, least_budget(stages)), max(polish, OUTSIDE_POLISH)
    knows = count_probability is not None
    choose = knows and config.chooses_count(setup)
    gate = "outside the nets' range" if outside else None
    if (knows and not choose and "alpha_ply" in config.searched(setup)
            and count_probability < config.sure_count):
        stages = tuple(kept for stage in stages
                       if (kept := tuple(k for k in stage if k != "alpha_ply")))
        gate = "unsure ply count"
    out: list[Stage] = []
    for params in stages:
        if choose and "alpha_ply" in params:
            out.append(Stage("ply count", scored_by=s.count_groups))
            choose = False
        cover = outside and bool({"r_x", "r_y"} & set(params)) and "m" not in params
        search = config.search_options(params, budget, polish if len(params) > 1 else 0, cover)
        out.append(stage_for(params, setup, search))
    seeds = config.seeds_per_eval
    return Plan(tuple(out), min(seeds, OUTSIDE_SEEDS_PER_EVAL) if outside else seeds,
                config.prior and not outside, gate)


def within_gate(ratio: float) -> bool:
    """Whether a render's core is within :data:`COUNT_WIDTH_FACTOR` of the photo's width
    (``ratio``: :func:`ipm.refine.measure.width_ratio`)."""
    return 1 / COUNT_WIDTH_FACTOR <= ratio <= COUNT_WIDTH_FACTOR
