"""The render-and-compare objective: loss of a yarn's render against one photo.

The photo (sRGB, at the scene's pixel pitch for the render scale, see :mod:`ipm.photo`) and
the render are cut to their common centred extent; the render is sRGB-encoded like a photo;
both go through :func:`ipm.refine.stats.yarn_statistics`, the photo's once.  The objective
is deterministic for a given fiber seed: the render seed is fixed.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from functools import partial

import numpy as np
import torch

from ipm.frame import YARN_LENGTH_MM, pixel_size_mm, view_yarn_length
from ipm.params import YarnParams
from ipm.photo import linear_to_srgb
from ipm.prior import FLYAWAY_RANGES
from ipm.refine.stats import (
    GROUPS,
    group_distances,
    stat_distance,
    yarn_centre,
    yarn_statistics,
)
from ipm.render.photometric import Photometric
from ipm.render.scene import Frame

#: Group weights from ``python -m ipm.benchmarks.identifiability`` on 10 held-out photos
#: (docs/identifiability.md): the core profile (R_ply), the axial autocorrelation (alpha_ply,
#: R_ply) and the stripes' spectrum distribution (alpha_ply, R_ply) put their minimum at the
#: truth with a seed spread small against their rise; the stripes at twice the weight, for
#: their wide basin (:func:`ipm.refine.stats._axial_spectrum_cdf`).  The other groups add
#: seed noise for less (the histogram at its former weight 10 made most of the loss's
#: noise), so they are off.  The silhouette's edges tell an even ply count from an odd one,
#: which the stripes' period cannot (``python -m ipm.benchmarks.ply_count_loss``; the real
#: photos' ply counts in real-photos-silhouette@e1028a1).  The contour reads the ply period
#: off the core's outline, where the stripes inside a real photo's grey core and a render's
#: opaque one differ; with it the real photos' fitted periods came nearer theirs
#: (real-photos-contour@dbf762e against real-photos-material@090878d), though alone it is not
#: where the period's minimum is (benchmarks/results/pitch_profile_real.md).
DEFAULT_WEIGHTS = {"core": 1.0, "flyaways": 0.0, "orientation": 0.0, "spectrum": 0.0,
                   "period": 1.0, "stripes": 2.0, "silhouette": 1.0, "contour": 0.25,
                   "histogram": 0.0}
#: How many (params, seed) pairs' render statistics a :class:`RenderObjective` keeps.
STATS_KEPT = 64
#: The weight of the ``flyaways`` group in a search that moves flyaway parameters.
FLYAWAY_WEIGHT = 1.0


def search_weights(searched: Iterable[str]) -> dict[str, float]:
    """The group weights of a search of the parameters ``searched`` (all its stages):
    :data:`DEFAULT_WEIGHTS`, and the ``flyaways`` group at :data:`FLYAWAY_WEIGHT` if any
    stage moves a flyaway parameter (:data:`ipm.prior.FLYAWAY_RANGES`), so that the fit's
    loss sees what that stage changed."""
    if any(k in FLYAWAY_RANGES for k in searched):
        return {**DEFAULT_WEIGHTS, "flyaways": FLYAWAY_WEIGHT}
    return DEFAULT_WEIGHTS


#: Learned statistics of an sRGB image at a pixel size (mm): named groups of (1, K) tensors.
Readings = Callable[[np.ndarray, float], dict[str, torch.Tensor]]


#: (width, height) px of a :class:`Detail` window: the detail nets' training windows
#: (``scripts/make_nets.sh``).
DETAIL_WINDOW = (320, 320)


@dataclass(frozen=True)
class Detail:
    """A second view every evaluation renders: a small window at the detail nets' pitch
    (``frame``, centred on the yarn), compared with the same window of the photo (``photo``,
    sRGB at ``frame.pixel_size_mm``) by the ``readings`` of the detail nets alone, at
    ``weight``, as groups ``detail_<group>``.  Why: at the search's pitch the fibers do not
    show, and neither the hand-made statistics nor the coarse nets see the fiber twist
    ``alpha`` (docs/identifiability.md); the detail nets read it where the fibers' slant
    shows (``nets/models/README.md``)."""

    photo: np.ndarray
    frame: Frame
    readings: Readings
    weight: float = 1.0
    spp: int = 4

    @classmethod
    def of_photo(cls, photo, readings: Readings, pitch_mm: float, weight: float = 1.0,
                 spp: int = 4) -> Detail:
        """The :data:`DETAIL_WINDOW` of ``photo`` (an :class:`ipm.photo.Photo`) resampled to
        ``pitch_mm``, the detail nets' pitch: in the middle along the yarn, and centred on
        its core across it (:func:`ipm.refine.stats.yarn_centre`), as the renders' window
        is on theirs."""
        frame = Frame(*DETAIL_WINDOW, pitch_mm)
        image = photo.at_pitch(pixel_size_mm(pitch_mm))  # the scale of that pitch
        h, w = min(frame.height, image.shape[0]), min(frame.width, image.shape[1])
        _, centre = yarn_centre(to_tensor(image).mean(dim=1, keepdim=True))
        top = int(np.clip(round(float(centre[0])) - h // 2, 0, image.shape[0] - h))
        left = (image.shape[1] - w) // 2
        return cls(image[top:top + h, left:left + w], frame, readings, weight, spp)


def centre_crop(img: np.ndarray, h: int, w: int) -> np.ndarray:
    top, left = (img.shape[0] - h) // 2, (img.shape[1] - w) // 2
    return img[top:top + h, left:left + w]


def to_tensor(img: np.ndarray) -> torch.Tensor:
    """(H, W, 3) float -> (1, 3, H, W) float64 tensor."""
    return torch.from_numpy(np.ascontiguousarray(img, dtype=np.float64)).permute(2, 0, 1)[None]


class RenderObjective:
    """``objective(params, seed) -> float``: the statistics loss of the yarn ``params``
    rendered at ``scale`` with ``spp`` samples against ``photo``.

    renderer: an :class:`ipm.render.renderer.Renderer`.  photo: (H, W, 3) sRGB in [0, 1]
    at the pixel pitch of ``scale``.  ``seeds_per_eval``: the render's statistics are the
    mean over that many fiber seeds (``seed``, ``seed + 1000``, ...), which shrinks the
    seed noise of the loss at that many times the cost.  ``readings``: learned statistics,
    ``readings(image, pixel_size_mm) -> {group: (1, K) tensor}`` (the nets' readings,
    :meth:`ipm.nets.ensemble.Ensemble.readings`), computed alike on the photo and every
    render and weighted by ``readings_weight``.  ``frame``: render only this view (a
    photo's smaller field of view, at its pitch, :func:`ipm.refine.measure.search_view`)
    instead of the yarn frame at ``scale``.  ``detail``: a second view rendered and compared
    per evaluation (:class:`Detail`).  ``evaluations`` counts renders of the main view.
    The statistics of the last :data:`STATS_KEPT` (params, seed) pairs are kept: a fit
    scores its start under several weightings (the ply count's choice, the search's start,
    the whole-loss rule), and the render of one pair is always the same.  A ``frame``
    renders only the yarn its view shows (:func:`ipm.frame.view_yarn_length`).  ``card``: the
    card's albedo, times the scene's, the renders are made on (the photo's own card,
    :func:`ipm.refine.capture.search_card`).
    """

    def __init__(self, renderer, photo: np.ndarray, scale: float, spp: int,
                 render_seed: int = 0, weights: dict[str, float] | None = None,
                 seeds_per_eval: int = 1, tilt_deg: float = 0.0,
                 readings: Readings | None = None, readings_weight: float = 1.0,
                 frame: Frame | None = None, detail: Detail | None = None,
                 card: float = 1.0) -> None:
        from ipm.render.scene import frame_size

        w, h = frame_size(scale) if frame is None else (frame.width, frame.height)
        self.size = (min(h, photo.shape[0]), min(w, photo.shape[1]))
        self.frame = frame
        self.renderer, self.scale, self.spp, self.render_seed = renderer, scale, spp, render_seed
        self.weights = DEFAULT_WEIGHTS if weights is None else weights
        self.seeds_per_eval = seeds_per_eval
        self.capture = Photometric(rotation_deg=tilt_deg, backdrop_gain=card)
        self.setup = renderer.options.setup
        self.readings = readings
        self.pixel_size_mm = pixel_size_mm(scale) if frame is None else frame.pixel_size_mm
        self.length = (YARN_LENGTH_MM if frame is None else
                       view_yarn_length(frame.width * frame.pixel_size_mm,
                                        frame.height * frame.pixel_size_mm))
        self.detail = detail
        self._kept: OrderedDict[tuple, dict[str, torch.Tensor]] = OrderedDict()
        self.photo_stats = self.statistics(centre_crop(photo, *self.size))
        self.weights = {**self.weights, **{k: readings_weight for k in self.photo_stats
                                           if k not in GROUPS}}
        if detail is not None:
            self.photo_stats |= self.detail_statistics(detail.photo)
            self.weights |= {k: detail.weight for k in self.photo_stats
                             if k.startswith("detail_")}
        self.evaluations = 0

    def statistics(self, img: np.ndarray) -> dict[str, torch.Tensor]:
        """The statistics groups of an sRGB image (H, W, 3): the hand-made ones and the
        learned ``readings``."""
        stats = yarn_statistics(to_tensor(img))
        if self.readings is not None:
            stats |= self.readings(img, self.pixel_size_mm)
        return stats

    def detail_statistics(self, img: np.ndarray) -> dict[str, torch.Tensor]:
        """The detail nets' readings of an sRGB window at the detail pitch, as groups
        ``detail_<group>``."""
        d = self.detail
        window = centre_crop(img, min(d.frame.height, img.shape[0]),
                             min(d.frame.width, img.shape[1]))
        return {f"detail_{k}": v for k, v in d.readings(window, d.frame.pixel_size_mm).items()}

    def render_detail(self, params: YarnParams, seed: int) -> np.ndarray:
        """The sRGB render of the :class:`Detail` window."""
        d = self.detail
        scale = pixel_size_mm(d.frame.pixel_size_mm)
        return linear_to_srgb(self.renderer.render(params, seed, scale, d.spp,
                                                   self.render_seed, self.capture, d.frame))

    def render(self, params: YarnParams, seed: int) -> np.ndarray:
        """The sRGB render (H, W, 3) the objective compares, cut to the photo's extent."""
        img = self.renderer.render(params, seed, self.scale, self.spp, self.render_seed,
                                   self.capture, self.frame, self.length)
        self.evaluations += 1
        return centre_crop(linear_to_srgb(img), *self.size)

    def loss_of_image(self, img: np.ndarray) -> float:
        return float(stat_distance(self.statistics(img), self.photo_stats, self.weights)[0])

    def _mean_stats(self, params: YarnParams, seed: int) -> dict[str, torch.Tensor]:
        if (params, seed) in self._kept:
            return self._kept[params, seed]
        stats = []
        for k in range(self.seeds_per_eval):
            stats.append(self.statistics(self.render(params, seed + 1000 * k)))
            if self.detail is not None:
                stats[-1] |= self.detail_statistics(self.render_detail(params, seed + 1000 * k))
        self._kept[params, seed] = {g: torch.stack([s[g] for s in stats]).mean(dim=0)
                                    for g in stats[0]}
        if len(self._kept) > STATS_KEPT:
            self._kept.popitem(last=False)
        return self._kept[params, seed]

    def group_distances(self, params: YarnParams, seed: int) -> dict[str, float]:
        """Each statistics group's distance to the photo's (unweighted), of the statistics
        averaged over ``seeds_per_eval`` fiber seeds."""
        d = group_distances(self._mean_stats(params, seed), self.photo_stats)
        return {g: float(v[0]) for g, v in d.items()}

    def __call__(self, params: YarnParams, seed: int,
                 weights: dict[str, float] | None = None) -> float:
        return float(stat_distance(self._mean_stats(params, seed), self.photo_stats,
                                   self.weights if weights is None else weights)[0])

    def for_stage(self, stage) -> Callable[[YarnParams, int], float]:
        """The objective of a search ``stage`` (:class:`ipm.refine.search.Stage`; why each
        stage is scored as it is: :mod:`ipm.refine.plan`): the groups its ``scored_by``
        names, or all but its ``without``, at their weights in this objective; the
        objective itself if the stage is scored by the whole loss."""
        weights = self.stage_weights(stage)
        return self if weights is None else partial(self, weights=weights)

    def stage_weights(self, stage) -> dict[str, float] | None:
        """The group weights :meth:`for_stage` scores ``stage`` with; None for the
        objective's own."""
        if stage.scored_by is None and not stage.without:
            return None
        kept = [k for k in self.photo_stats if k not in stage.without
                and (stage.scored_by is None or k in stage.scored_by)]
        return {k: self.weights.get(k, 0.0) if k in kept else 0.0 for k in self.photo_stats}
