"""Synthetic photos of a millimetre scale, drawn here (not by ipm) to test ``ipm calibrate``.

    python tests/rulers.py   # writes the bundled examples/ruler.png (0.0125 mm per pixel)
"""

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

SUPERSAMPLE = 4


def ruler(pixel_size_mm: float, angle_deg: float = 0.0, size=(1200, 500), noise=0.02,
          seed=0) -> np.ndarray:
    """A steel rule's millimetre ticks (long every 5 and 10 mm), dark on light, turned by
    ``angle_deg``, drawn at 4x and averaged down, with Gaussian sensor noise: (H, W) in [0, 1]."""
    w, h = size
    s = SUPERSAMPLE
    im = Image.new("L", (w * s, h * s), 225)
    draw = ImageDraw.Draw(im)
    period = s / pixel_size_mm
    ca, sa = np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))
    cx, cy = w * s / 2, h * s * 0.75
    for k in range(-int(1.6 * w * s / period), int(1.6 * w * s / period)):
        length = (0.45 if k % 10 == 0 else 0.3 if k % 5 == 0 else 0.18) * h * s
        ends = [(k * period, 0.0), (k * period, -length)]
        draw.line([(cx + ca * x - sa * y, cy + sa * x + ca * y) for x, y in ends], fill=30,
                  width=max(1, int(0.08 * period)))
    img = np.asarray(im.resize((w, h), Image.LANCZOS), dtype=np.float64) / 255
    return np.clip(img + np.random.default_rng(seed).normal(0, noise, img.shape), 0, 1)


if __name__ == "__main__":
    out = Path(__file__).resolve().parent.parent / "examples" / "ruler.png"
    Image.fromarray((ruler(0.0125, angle_deg=4.0) * 255).round().astype(np.uint8)).save(out)
    print(out)
