"""What a fit measures of a photo and of its renders, apart from the loss: whether a yarn
is seen and how it is exposed, tilted and coloured, how wide its core is against a render's,
the view the search renders it in, and the ply count the loss chooses."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ipm.frame import PIXEL_SIZE_MM, pixel_size_mm
from ipm.params import YarnParams, clipped
from ipm.photo import Photo, srgb_to_linear
from ipm.refine.objective import RenderObjective, to_tensor
from ipm.refine.plan import THICKNESS
from ipm.refine.search import ply_count_scores, same_period
from ipm.refine.stats import centre_rows, core_width, yarn_centre, yarn_tilt
from ipm.render.scene import Frame, frame_size

#: A photo with more than this fraction of pixels at either end of the range is strongly
#: under- or over-exposed, where the paper's nets do not hold.
CLIPPED_WARN = 0.02
#: The core must differ from the background by this much (sRGB) for a yarn to be seen.
MIN_CORE_CONTRAST = 0.03


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
    identifiable, nor ``r_x`` lit from behind: docs/identifiability.md and its
    contour page).  A search of the three on the real photos,
    thinner than the nets know, flattened the plies (``r_y`` well below ``r_x``:
    real-photos-contour@dbf762e), and flattened plies bump the core's outline twice per ply
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
                     seeds: Sequence[int], groups: Sequence[str]
                     ) -> tuple[YarnParams, dict[int, float]]:
    """The ply count of ``start`` chosen by the loss ``groups`` (a setup's
    ``count_groups``, :mod:`ipm.setups`) and the nets' probabilities ``prior``
    (:func:`ipm.refine.search.ply_count_scores` of the groups' loss over ``seeds``), each
    count with ``start``'s stripe period (:func:`same_period`), and the scores; ``start``
    and no scores without groups.

    Why the period kept: the stripes' period ``alpha_ply / n`` is what the nets and the
    pitch search read best; a count is then judged by what differs between counts at one
    period.  Why the nets' probabilities: a count they find unlikely needs the loss's word
    by more than its seed noise."""
    candidates = {n: same_period(start, n) for n in prior}
    candidates = {n: p for n, p in candidates.items() if p is not None}
    if not groups or len(candidates) < 2:
        return start, {}
    weights = {k: 1.0 if k in groups else 0.0 for k in objective.photo_stats}
    scores = ply_count_scores({n: [objective(p, s, weights) for s in seeds]
                               for n, p in candidates.items()}, prior)
    best = min(scores, key=scores.__getitem__)
    return (start if best == start.n else candidates[best]), scores


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
    fine = pixel_size_mm(pitch)  # the scale of that pitch
    max_w, max_h = frame_size(fine)
    return fine, Frame(min(max_w, round(w * photo.pixel_size_mm / pitch)),
                       min(max_h, round(h * photo.pixel_size_mm / pitch)), pitch)


def photo_tilt(image_srgb: np.ndarray) -> float:
    """The yarn's tilt in the photo, degrees counter-clockwise (:func:`yarn_tilt`).  The
    renders of the search are tilted the same way, so that a tilted photo's wider core
    profile is not mistaken for a thicker yarn."""
    return float(yarn_tilt(to_tensor(image_srgb).mean(dim=1, keepdim=True))[0])

