"""Knitted patches rendered in THE scene (``ipm knit``): the patch's fibers
(:func:`ipm.knit.knit_patch`, fabric in the image plane, knit face to the camera) in a frame
sized to hold the patch, with the camera, lights and card of the yarn renders."""

from __future__ import annotations

import numpy as np

from ipm.knit import Patch, knit_patch
from ipm.params import YarnParams
from ipm.render.renderer import RENDER_BYTES_PER_VERTEX, Renderer
from ipm.render.scene import Frame

#: Room left around the patch in the frame.
MARGIN = 1.06


def patch_frame(patch: Patch, width: int, height: int) -> Frame:
    """The frame of ``width`` x ``height`` px whose pixel size just holds the patch's
    centre lines (plus the yarn's radius and :data:`MARGIN`)."""
    pts = np.concatenate(patch.centrelines)
    extent = np.abs(pts[:, :2]).max(axis=0) * 2 + patch.diameter
    return Frame(width, height, float(max(extent[0] / width, extent[1] / height) * MARGIN))


def render_patch(renderer: Renderer, patch: Patch, color: tuple[float, float, float],
                 frame: Frame, spp: int, render_seed: int = 0) -> np.ndarray:
    """Linear RGB (H, W, 3) float32 of the patch, seen along -z."""
    return renderer.render_fibers(patch.fibers, color, 1.0, spp, render_seed, np.eye(4), frame)


def knit_and_render(renderer: Renderer, params: YarnParams, pattern: str,
                    stitches: tuple[int, int], size: tuple[int, int], spp: int, seed: int = 0,
                    render_seed: int = 0) -> tuple[np.ndarray, dict, Patch]:
    """Knit ``params`` (``stitches`` = wales, courses) and render the patch at ``size`` =
    (width, height) px: the linear RGB image, the sidecar record that renders it again,
    and the patch."""
    patch = knit_patch(params, pattern, *stitches, seed,
                       extra_bytes_per_vertex=RENDER_BYTES_PER_VERTEX)
    frame = patch_frame(patch, *size)
    image = render_patch(renderer, patch, params.color, frame, spp, render_seed)
    record = {"params": params.to_dict(), "pattern": pattern, "stitches": list(stitches),
              "seed": seed, "render_seed": render_seed, "spp": spp, "width": frame.width,
              "height": frame.height, "pixel_size_mm": frame.pixel_size_mm,
              "yarn_diameter_mm": patch.diameter, "variant": renderer.variant,
              "scene": renderer.settings(1.0, spp, render_seed)["scene"]}
    return image, record, patch
