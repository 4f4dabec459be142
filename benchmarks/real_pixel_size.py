"""The pixel size of the real backlit photos (../shared/real-yarns), which their source does
not publish, estimated from the fibers in them: cotton fibers are 12-20 um thick (16 um
taken), and the flyaways' width in pixels is measured by
:func:`ipm.textile.image.fiber_width_px`.  Photos whose flyaways give fewer
than 100 skeleton pixels are left out.  Writes the table and the estimate the other reports
use.

    python -m ipm.benchmarks.real_pixel_size --out benchmarks/results/real_pixel_size.md
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish
from ipm.textile.image import (
    core_diameter_px,
    fiber_width_px,
    gray,
    levelled,
    yarn_signal,
)

COMMAND = "python -m ipm.benchmarks.real_pixel_size --out benchmarks/results/real_pixel_size.md"
FIBER_UM = (12.0, 16.0, 20.0)
MIN_SKELETON = 100
REAL = Path(__file__).resolve().parent.parent.parent / "shared" / "real-yarns"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--photos", default=str(REAL))
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    rows = ["| photo | core (px) | fiber width (px) | skeleton px | um per px (12 / 16 / 20 um "
            "fibers) |", "|---|---|---|---|---|"]
    used = []
    for path in sorted(Path(args.photos).glob("*.png")):
        sig = levelled(yarn_signal(gray(str(path)), backlit=True))
        d = core_diameter_px(sig)
        width, support = fiber_width_px(sig, d)
        ok = support >= MIN_SKELETON
        if ok:
            used.append(width)
        um = " / ".join(f"{f / width:.2f}" for f in FIBER_UM) if ok else "left out"
        rows.append(f"| {path.name} | {d:.0f} | {width:.1f} | {support} | {um} |")
    width = float(np.median(used))
    lo, mid, hi = (f / width / 1000 for f in FIBER_UM)
    text = (markdown_header("Pixel size of the real backlit photos, from their fibers", COMMAND)
            + f"\nMedian fiber width over {len(used)} photos: **{width:.1f} px**, so the pixel "
            f"size is **{mid:.4f} mm** ({lo:.4f}-{hi:.4f} mm for 12-20 um fibers).  Defocused "
            "fibers look wider, so this errs small.\n\n" + "\n".join(rows) + "\n")
    publish(text, args.out)


if __name__ == "__main__":
    main()
