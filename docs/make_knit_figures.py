"""Figures of knitted patches and edited yarns (they render, so they live apart from
make_figures.py):

* ``knit_patches.png``: knit and purl patches (8 x 6) of three presets;
* ``edits.png``: the paper's editing figure made with ``ipm edit``: golden, its ply twist
  pitch halved, its flyaways doubled, both, as yarns and as knitted patches.

    python docs/make_knit_figures.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from ipm.edit import apply_edits
from ipm.knit import knit_patch
from ipm.photo import linear_to_srgb
from ipm.presets import preset
from ipm.render.patch import patch_frame, render_patch
from ipm.render.renderer import Renderer

OUT = Path(__file__).parent / "figures"
SPP = 16


def to8(img: np.ndarray) -> Image.Image:
    return Image.fromarray((np.clip(linear_to_srgb(img), 0, 1) * 255).round().astype(np.uint8))


def grid(tiles: list[list[Image.Image]], labels: list[list[str]]) -> Image.Image:
    h, w = tiles[0][0].height, tiles[0][0].width
    out = Image.new("RGB", (len(tiles[0]) * (w + 6) + 6, len(tiles) * (h + 6) + 6), "white")
    draw = ImageDraw.Draw(out)
    for r, row in enumerate(tiles):
        for c, tile in enumerate(row):
            x, y = 6 + c * (w + 6), 6 + r * (h + 6)
            out.paste(tile, (x, y))
            draw.text((x + 6, y + 4), labels[r][c], fill=(255, 255, 255))
    return out


def patch_image(renderer: Renderer, params, pattern: str, size=(600, 300)) -> Image.Image:
    patch = knit_patch(params, pattern, 8, 6, seed=0)
    return to8(render_patch(renderer, patch, params.color, patch_frame(patch, *size), SPP))


def main() -> None:
    renderer = Renderer()
    names = ("golden", "rose", "blue")
    tiles = [[patch_image(renderer, preset(n), pattern) for pattern in ("knit", "purl")]
             for n in names]
    grid(tiles, [[f"{n}, {pattern}" for pattern in ("knit", "purl")] for n in names]).save(
        OUT / "knit_patches.png")

    p = preset("golden")

    edits = {"golden": [], "alpha_ply=*0.5": ["alpha_ply=*0.5"], "g=*2": ["g=*2"],
             "alpha_ply=*0.5, g=*2": ["alpha_ply=*0.5", "g=*2"]}
    rows = []
    for label, spec in edits.items():
        q = apply_edits(p, spec)
        yarn = to8(renderer.render(q, 1, 0.3, SPP)).resize((600, 180))
        rows.append((label, yarn, patch_image(renderer, q, "knit")))
    w = 600
    out = Image.new("RGB", (2 * w + 18, len(rows) * (300 + 6) + 6), "white")
    draw = ImageDraw.Draw(out)
    for i, (label, yarn, knit) in enumerate(rows):
        y = 6 + i * 306
        out.paste(yarn, (6, y + 60))
        out.paste(knit, (w + 12, y))
        draw.text((12, y + 64), label, fill=(255, 255, 255))
    out.save(OUT / "edits.png")
    print(OUT / "knit_patches.png", OUT / "edits.png")


if __name__ == "__main__":
    main()
