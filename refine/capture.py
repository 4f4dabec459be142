"""The photo's capture as the fit's renders show it: the background's level and the defocus
(a Gaussian blur in linear light), each matched to the photo by an image measure that does
not use the nets.

Why: the scene renders a fixed panel or card level and perfectly sharp fibers, while a
photo has its own exposure, card and lens's depth of field (the Minho microscope photos: a
panel darker than the scene's, cores soft).  The search does not need this (its statistics
are deviations from the background in units of the core's contrast, blurred alike), but a
person comparing the photo with ``refined.png`` does: beside a sharp, bright render every
photo looks wrong.  So ``neural.png``, ``refined.png`` and ``compare.png`` are rendered in
the capture matched here, and ``params.json`` records it (``capture``).

* Background level (:func:`background_level`, the median of the top and bottom rows),
  brought to the photo's in linear light.  Lit from behind (:mod:`ipm.setups`) the
  background is the light itself, so its level is the exposure
  (:attr:`Photometric.exposure_stops`); lit in front it is the card,
  whose grey is the scene's, not the camera's (the yarn's brightness is matched apart, by
  its fibers' colour: :func:`ipm.refine.measure.match_colour`), so the card's albedo is scaled
  (:attr:`Photometric.backdrop_gain`, a render of its own).
* Defocus: the blur at which the render's :func:`sharpness` falls to the photo's; none if
  the render is already as soft as the photo.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from ipm.photo import card_factor, defocus, linear_to_srgb, srgb_to_linear
from ipm.refine.stats import yarn_centre
from ipm.render.photometric import LOOK, NOMINAL, Photometric, apply_to_image
from ipm.setups import setup_of

#: The two bands (pixels) :func:`sharpness` compares: detail finer than a blur of the first
#: against detail between the first and the second.
BANDS_PX = (1.0, 4.0)
#: The blurs (pixels) tried, smallest to largest; the match is interpolated between them.
BLUR_STEPS_PX = np.geomspace(0.25, 16.0, 13)
#: A match moves the exposure at most this many stops, the card's albedo at most 2 ** this
#: many times: enough for the scene's near-black card to turn white (the scene keeps an
#: albedo at most 1).
MAX_STOPS = 6.0


def _gray(srgb: np.ndarray) -> np.ndarray:
    return srgb.mean(axis=-1) if srgb.ndim == 3 else srgb


def background_level(srgb: np.ndarray) -> float:
    """The background's grey level (sRGB) of an image whose yarn runs left to right."""
    g = torch.from_numpy(np.ascontiguousarray(_gray(srgb), dtype=np.float32))[None, None]
    return float(yarn_centre(g)[0][0])


def sharpness(srgb: np.ndarray) -> float:
    """How sharp an image's edges are, whatever how many there are: the standard deviation
    of its finest detail (the image minus its Gaussian blur of ``BANDS_PX[0]``) over that of
    the next band (that blur minus one of ``BANDS_PX[1]``).  Defocus lowers it; the number
    of fibers, their darkness and the exposure hardly move it.

    Why not the fiber texture of the core: a real core's fibers are packed more densely
    than a render's, so its texture is lower at any focus, and a blur matched on it made
    renders softer than the photos' hairs (real-photos-capture-texture@f3f2495, made with it;
    see its contact sheet)."""
    from skimage.filters import gaussian

    g = _gray(srgb).astype(np.float32)
    fine, coarse = (gaussian(g, sigma=s, mode="nearest", preserve_range=True) for s in BANDS_PX)
    return float((g - fine).std() / max(float((fine - coarse).std()), 1e-9))


def matched_level(photo_srgb: np.ndarray, render_linear: np.ndarray, base: Photometric,
                  setup: str) -> Photometric:
    """``base`` with the background level of ``render_linear`` (H, W, 3, rendered in
    ``base``) brought to ``photo_srgb``'s (the same field of view): as the exposure in a
    setup lit from behind (its background is the light), else as the card's albedo
    (:attr:`Photometric.backdrop_gain`, which needs a render of its own)."""
    level = srgb_to_linear(np.float32(background_level(photo_srgb)))
    own = srgb_to_linear(np.float32(background_level(linear_to_srgb(render_linear))))
    stops = float(np.clip(np.log2(max(float(level), 1e-4) / max(float(own), 1e-4)),
                          -MAX_STOPS, MAX_STOPS))
    if setup_of(setup).light_behind:
        return replace(base, exposure_stops=base.exposure_stops + stops)
    return replace(base, backdrop_gain=base.backdrop_gain * 2.0 ** stops)


def matched_blur(photo_srgb: np.ndarray, render_linear: np.ndarray, pixel_size_mm: float,
                 base: Photometric) -> Photometric:
    """``base`` with the defocus (:attr:`Photometric.blur_mm`) at which ``render_linear``
    (rendered in ``base``, then given its exposure) is as sharp as ``photo_srgb`` (the same
    field of view, ``pixel_size_mm`` per pixel; :func:`sharpness`)."""
    exposed = render_linear * 2.0 ** base.exposure_stops
    target = sharpness(photo_srgb)

    def texture(sigma_px: float) -> float:
        return sharpness(linear_to_srgb(defocus(exposed, sigma_px)))

    before, blur = texture(0.0), 0.0
    if before > target:
        prev_s, prev_t = 0.0, before
        for s in BLUR_STEPS_PX:
            t = texture(float(s))
            if t <= target:  # interpolate between the last step above and this one
                blur = float(prev_s + (s - prev_s) * (prev_t - target) / max(prev_t - t, 1e-9))
                break
            prev_s, prev_t = float(s), t
        else:
            blur = float(BLUR_STEPS_PX[-1])
    return replace(base, blur_mm=blur * pixel_size_mm)


def matched_capture(photo_srgb: np.ndarray, render_linear: np.ndarray, pixel_size_mm: float,
                    setup: str, base: Photometric = NOMINAL) -> Photometric:
    """:func:`matched_level` and :func:`matched_blur` of one render (the blur measured before
    a card's new albedo, which hardly moves the sharpness of the yarn's edges)."""
    return matched_blur(photo_srgb, render_linear, pixel_size_mm,
                        matched_level(photo_srgb, render_linear, base, setup))


#: A card within this many stops of the scene's is rendered as the scene's (a tenth of a
#: stop is not seen), so that a photo on the scene's own card is fitted as ever.
CARD_TOLERANCE_STOPS = 0.1


def search_card(image_srgb: np.ndarray, setup: str) -> float:
    """The card's albedo, times the scene's, that a fit renders on to compare with
    ``image_srgb`` (a photo at the search's pitch): lit from the front, the photo's own card
    (:func:`ipm.photo.card_factor`), so that a yarn on a light card is compared with renders
    on that card, the light it throws on the fibers included; 1 for the scene's card
    (within :data:`CARD_TOLERANCE_STOPS`) and for a light panel."""
    level = setup_of(setup).card_linear
    if level is None:
        return 1.0
    gain = card_factor(srgb_to_linear(image_srgb), level)
    ok = np.isfinite(gain) and gain > 0 and abs(np.log2(gain)) > CARD_TOLERANCE_STOPS
    return float(gain) if ok else 1.0


def card_warning(capture: Photometric, setup: str) -> str | None:
    """A warning if a photo's card (:func:`matched_level`, lamps in front) is lighter or
    darker than any the nets were trained on (:data:`ipm.render.photometric.LOOK`'s
    ``backdrop_gain``): how the nets read lighter cards is in benchmarks/results/card_sweep.md."""
    lo, hi = LOOK["backdrop_gain"]
    if setup_of(setup).light_behind or lo <= capture.backdrop_gain <= hi:
        return None
    fix = ("a matte card, not a lit or glossy one" if capture.backdrop_gain > hi
           else "a grey or white matte card, lit as the yarn is")
    return (f"the photo's background is a card {capture.backdrop_gain:.2g} times as light as "
            f"the scene's, outside the {lo:g}-{hi:g} the nets were trained on: they may "
            f"misread the yarn; photograph it over {fix}")


def in_capture(render_linear: np.ndarray, capture: Photometric, pixel_size_mm: float
               ) -> np.ndarray:
    """``render_linear`` (the scene's own capture) under ``capture``'s exposure and defocus,
    as sRGB."""
    look = Photometric(exposure_stops=capture.exposure_stops, blur_mm=capture.blur_mm)
    return linear_to_srgb(apply_to_image(render_linear, look, pixel_size_mm))
