"""What ``ipm fit`` shows the user: the photo and the renders side by side in the photo's
capture (:mod:`ipm.refine.capture`), the fitted yarn in a few lines, and its textile
measures beside the photo's (:mod:`ipm.textile`)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ipm.frame import FRAME_HEIGHT_MM, FRAME_WIDTH_MM, pixel_size_mm
from ipm.params import PAPER_INTERVALS, YarnParams
from ipm.photo import Photo
from ipm.refine.capture import CARD_TOLERANCE_STOPS, in_capture, matched_blur, matched_level
from ipm.refine.measure import search_view
from ipm.refine.objective import centre_crop
from ipm.refine.search import LEVEL
from ipm.render.photometric import Photometric
from ipm.render.scene import Frame, frame_size
from ipm.setups import setup_of

if TYPE_CHECKING:
    from ipm.refine.fit import FitResult
    from ipm.refine.plan import FitConfig



#: The most pixels a photo's renders are shown at: a larger photo's are shown at a coarser
#: pitch over its whole field of view.
MAX_DISPLAY_PIXELS = 4_000_000
#: The fewest samples per pixel of a render shown at a photo's own pixels.
MIN_DISPLAY_SPP = 4


def display_view(photo: Photo, config: FitConfig) -> tuple[float, Frame | None]:
    """The scale, and the view if not the yarn frame, that the photo and its renders are
    shown at.  A photo that shows less than the yarn frame (a microscope's) is shown at its
    own pixels over its own field of view, so that a fiber can be judged beside the photo
    (the search renders it coarser: :func:`search_view`), at most
    :data:`MAX_DISPLAY_PIXELS`; any other photo at ``config.display_scale``."""
    scale, frame = search_view(photo, config.display_scale)
    if frame is None:
        return scale, None
    h, w = photo.image.shape[:2]
    pitch = photo.pixel_size_mm * max(1.0, math.sqrt(h * w / MAX_DISPLAY_PIXELS))
    return pixel_size_mm(pitch), Frame(
        min(round(w * photo.pixel_size_mm / pitch), math.floor(FRAME_WIDTH_MM / pitch)),
        min(round(h * photo.pixel_size_mm / pitch), math.floor(FRAME_HEIGHT_MM / pitch)),
        pitch)


def display_renders(renderer, photo: Photo, result: FitResult, config: FitConfig
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, Photometric]:
    """(photo, neural render, refined render) as sRGB in the :func:`display_view`, cut to
    their common extent, the renders in the photo's capture, and that capture
    (:mod:`ipm.refine.capture`: lit in front, the card's albedo matched on a render at the
    search's pitch, rendered with; lit from behind, the exposure; and the defocus matched
    on the refined render, applied to both).  A view of more pixels than the yarn frame at
    ``display_scale`` is rendered with fewer samples per pixel, as many samples in all (at
    least :data:`MIN_DISPLAY_SPP`): its pixels are finer than the fibers' edges."""
    scale, frame = display_view(photo, config)
    shown = photo.at_pitch(scale)
    pitch = pixel_size_mm(scale)
    budget = math.prod(frame_size(config.display_scale)) * config.display_spp
    spp = config.display_spp if frame is None else min(config.display_spp, max(
        MIN_DISPLAY_SPP, budget // (frame.width * frame.height)))

    def rendered(p: YarnParams, look: Photometric) -> np.ndarray:
        img = renderer.render(p, config.fiber_seed, scale, spp, photometric=look, frame=frame)
        return centre_crop(img, min(shown.shape[0], img.shape[0]),
                           min(shown.shape[1], img.shape[1]))

    tilted = scene = Photometric(rotation_deg=result.tilt_deg)
    setup = renderer.options.setup
    behind = setup_of(setup).light_behind
    if not behind:  # the card's albedo, from a render at the search's pitch
        probe_scale, probe_frame = search_view(photo, config.scale)
        probe = renderer.render(result.refined, config.fiber_seed, probe_scale,
                                config.spp, photometric=tilted, frame=probe_frame)
        small = photo.at_pitch(probe_scale)
        h, w = min(small.shape[0], probe.shape[0]), min(small.shape[1], probe.shape[1])
        card = matched_level(centre_crop(small, h, w), centre_crop(probe, h, w), tilted, setup)
        if abs(np.log2(card.backdrop_gain)) > CARD_TOLERANCE_STOPS:
            scene = card
    refined = rendered(result.refined, scene)
    neural = refined if result.neural == result.refined else rendered(result.neural, scene)
    shown = centre_crop(shown, *refined.shape[:2])
    level = matched_level(shown, refined, scene, setup) if behind else scene
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


def textile_block(photo: Photo, fitted: YarnParams, render: np.ndarray, config: FitConfig
                  ) -> dict:
    """``params.json``'s ``textile``: the photo's measures (:mod:`ipm.textile.image`, at its
    own pitch), the same of the fitted yarn's ``render`` in the photo's capture (at the
    display's pitch), and those of the fitted yarn's fibers (:mod:`ipm.textile.fibers`);
    the ply count the fit's."""
    from ipm.generator import generate
    from ipm.textile.fibers import fiber_measures
    from ipm.textile.image import measure_photo

    behind = setup_of(photo.setup).light_behind
    pitch = pixel_size_mm(display_view(photo, config)[0])
    return {"photo": measure_photo(photo.image.mean(axis=2), photo.pixel_size_mm, behind,
                                   fitted.n).brief(),
            "render": measure_photo(render.mean(axis=2), pitch, behind, fitted.n).brief(),
            "fibers": fiber_measures(fitted, generate(fitted, config.fiber_seed))}


def textile_lines(textile: dict) -> list[str]:
    """The textile block in a few lines: photo | render | fibers."""
    def row(name: str, key: str, fmt: str) -> str:
        cells = [textile[k].get(key) for k in ("photo", "render", "fibers")]
        return f"  {name:<19s} " + " | ".join("-" if v is None else format(v, fmt)
                                              for v in cells)
    return ["textile measures (photo | fit's render | fit's fibers; docs/measure.md):",
            row("diameter (mm)", "diameter_mm", ".3f"),
            row("ply twist (turns/m)", "ply_twist_tpm", ".0f"),
            row("direction", "twist_direction", "s"),
            row("hairiness H", "hairiness_h", ".3g")]
