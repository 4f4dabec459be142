"""Figures of the docs that need only the yarn core.

    python docs/make_figures.py   # writes docs/figures/helix_mapping.png
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from ipm.fibers import FiberSet
from ipm.generator import Level, raw_yarn
from ipm.sketch import side_view

OUT = Path(__file__).parent / "figures"


def helix_mapping() -> Image.Image:
    """Paper Fig. 5, exaggerated: one ply mapped onto a steep helix by shifting orthogonal
    to the global axis (Zhao et al.) and by the local-frame transformation (ours).  Grey:
    fibers; red: the fiber vertices of a few template heights, i.e. ply cross-sections."""
    levels = [Level(60, 0.6, -40.0), Level(1, 1.2, 4.0)]
    panels = []
    for mapping in ("global", "local"):
        fibers, _ = raw_yarn(levels, np.random.default_rng(0), length=6.0, mapping=mapping)
        f, v = fibers.shape[:2]
        fs = FiberSet(points=fibers.reshape(-1, 3).astype(np.float32),
                      offsets=np.arange(f + 1) * v, radii=np.full((f, 2), 0.01, np.float32),
                      kind=np.zeros(f, np.uint8), ply=np.zeros(f, np.int16))
        img = side_view(fs, 8.0, 4.4, 60, colors=[(170, 170, 170)] * f)
        draw = ImageDraw.Draw(img)
        for i in range(v // 8, v, v // 6):
            for _, y, z in fibers[:, i]:
                u, w = (z + 4.0) * 60, (2.2 - y) * 60
                draw.ellipse([u - 2, w - 2, u + 2, w + 2], fill=(200, 30, 30))
        title = "global-axis shift (Zhao et al.)" if mapping == "global" else \
            "local coordinate frame (ours)"
        draw.text((8, 6), title, fill=(0, 0, 0))
        panels.append(img)
    out = Image.new("RGB", (panels[0].width * 2 + 10, panels[0].height), (255, 255, 255))
    out.paste(panels[0], (0, 0))
    out.paste(panels[1], (panels[0].width + 10, 0))
    return out


if __name__ == "__main__":
    OUT.mkdir(exist_ok=True)
    helix_mapping().save(OUT / "helix_mapping.png")
    print(OUT / "helix_mapping.png")
