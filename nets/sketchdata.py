"""Datasets of line drawings in the ``ipm generate`` format, made without a renderer.

Each image is the generator's fibers drawn with Pillow (:func:`ipm.sketch.side_view`) as
light lines on the dark backdrop, so the image depends on the parameters the way a render
does in geometry (not in shading).  Tests and benchmarks of the nets use them where Mitsuba
would be too slow; they are no substitute for ``ipm generate`` when training real models.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image, ImageOps

from ipm.fibers import FiberSet
from ipm.frame import FRAME_HEIGHT_MM, FRAME_WIDTH_MM, PIXEL_SIZE_MM
from ipm.generator import generate
from ipm.io import atomic_path, write_text
from ipm.prior import GuidedPrior
from ipm.sketch import side_view


def write_sketch_dataset(folder: str | Path, count: int, seed: int = 0, scale: float = 0.25,
                         split: str = "train") -> Path:
    """Write ``count`` frames (2000 x 600 px times ``scale``) and ``manifest.jsonl``."""
    folder = Path(folder)
    (folder / "images").mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    lines = []
    for i in range(count):
        params = GuidedPrior().sample(rng)
        fiber_seed = int(rng.integers(2**31))
        fibers = generate(params, fiber_seed)
        img = ImageOps.invert(_draw(fibers, scale, rng))
        name = f"images/{i:06d}.png"
        with atomic_path(folder / name) as tmp:
            img.save(tmp)
        lines.append(json.dumps({"image": name, "params": params.to_dict(), "seed": fiber_seed,
                                 "split": split, "index": i, "scale": scale, "spp": 0,
                                 "pixel_size_mm": PIXEL_SIZE_MM / scale, "photometric": {}}))
    write_text(folder / "manifest.jsonl", "\n".join(lines) + "\n")
    return folder


def _draw(fibers: FiberSet, scale: float, rng: np.random.Generator) -> Image.Image:
    # A grey level per ply plus per-fiber noise, so that ply and fiber twist show as they
    # do through shading in a render (inverted afterwards: light fibers on a dark backdrop).
    shade = 40 + 120 * (fibers.ply % 3) / 2 + rng.uniform(-25, 25, fibers.num_fibers)
    grey = np.clip(shade, 0, 255).astype(int).tolist()
    return side_view(fibers, FRAME_WIDTH_MM, FRAME_HEIGHT_MM, scale / PIXEL_SIZE_MM,
                     colors=[(g, g, g) for g in grey])
