"""The paper's 12 real yarns rendered side by side: a one-look check that renders look like
yarn photos (``ipm render --contact-sheet``)."""

from __future__ import annotations

import os

import numpy as np
from PIL import Image, ImageDraw

from ipm.io import atomic_path
from ipm.presets import PRESET_NAMES, preset
from ipm.render.renderer import Renderer, to_srgb8
from ipm.render.scene import DEFAULT_OPTIONS, SceneOptions

COLUMNS = 2
GAP_PX = 6


def contact_sheet(out: str | os.PathLike, scale: float = 0.25, spp: int = 16, seed: int = 1,
                  variant: str | None = None, options: SceneOptions = DEFAULT_OPTIONS
                  ) -> np.ndarray:
    """Render every preset at ``scale`` and tile them, labelled, into a PNG at ``out``.

    Returns the sheet (H, W, 3) uint8 sRGB.
    """
    renderer = Renderer(variant, options)
    tiles = [to_srgb8(renderer.render(preset(name), seed, scale, spp)) for name in PRESET_NAMES]
    h, w, _ = tiles[0].shape
    rows = -(-len(tiles) // COLUMNS)
    sheet = Image.new("RGB", (COLUMNS * w + (COLUMNS + 1) * GAP_PX,
                              rows * h + (rows + 1) * GAP_PX), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for i, (name, tile) in enumerate(zip(PRESET_NAMES, tiles, strict=True)):
        x = GAP_PX + (i % COLUMNS) * (w + GAP_PX)
        y = GAP_PX + (i // COLUMNS) * (h + GAP_PX)
        sheet.paste(Image.fromarray(tile), (x, y))
        dark_text = tile[:12].mean() > 128  # lit from behind: its top is the bright panel
        draw.text((x + 4, y + 3), name, fill=(0, 0, 0) if dark_text else (255, 255, 255))
    with atomic_path(out) as tmp:
        sheet.save(tmp, format="PNG")
    return np.asarray(sheet)
