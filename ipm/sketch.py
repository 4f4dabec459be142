"""Line drawings of fibers with Pillow: a quick look at geometry without a renderer."""

from __future__ import annotations

from PIL import Image, ImageDraw

from ipm.fibers import FiberKind, FiberSet

KIND_COLORS = {FiberKind.CORE: (40, 40, 40), FiberKind.HAIR: (200, 60, 40),
               FiberKind.LOOP: (40, 90, 200)}


def side_view(fs: FiberSet, width_mm: float, height_mm: float, px_per_mm: float,
              colors: list[tuple[int, int, int]] | None = None) -> Image.Image:
    """Orthographic view along -x: the yarn axis ``z`` runs left to right, ``y`` up.

    ``colors`` gives one colour per fiber; by default fibers are coloured by kind.
    """
    w, h = int(round(width_mm * px_per_mm)), int(round(height_mm * px_per_mm))
    img = Image.new("RGB", (w, h), (255, 255, 255))
    draw = ImageDraw.Draw(img)
    for f, pts in enumerate(fs.fibers()):
        u = (pts[:, 2] + width_mm / 2) * px_per_mm
        v = (height_mm / 2 - pts[:, 1]) * px_per_mm
        col = colors[f] if colors else KIND_COLORS[FiberKind(int(fs.kind[f]))]
        draw.line(list(zip(u.tolist(), v.tolist(), strict=True)), fill=col, width=1)
    return img
