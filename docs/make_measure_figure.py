"""The figure of docs/measure.md: ``ipm measure`` on one of the real microscope photos, what
it found drawn over the photo (the same drawing ``ipm measure -o`` writes per photo).

    python docs/make_measure_figure.py   # writes docs/figures/measure_real.png
"""

from __future__ import annotations

from pathlib import Path

from PIL import Image

from ipm.textile.image import analyse, gray
from ipm.textile.report import overlay

PHOTO = Path(__file__).resolve().parents[2] / "shared" / "real-yarns" / "minho_10.png"
PIXEL_SIZE_MM, PLIES, WIDTH = 0.0021, 2, 960


def main() -> None:
    img = gray(str(PHOTO))
    m, drawing = analyse(img, PIXEL_SIZE_MM, backlit=True, plies=PLIES)
    drawn = Image.fromarray(overlay(img, m, drawing))
    height = round(drawn.height * WIDTH / drawn.width)
    out = Path(__file__).parent / "figures" / "measure_real.png"
    drawn.resize((WIDTH, height), Image.Resampling.LANCZOS).save(out, optimize=True)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
