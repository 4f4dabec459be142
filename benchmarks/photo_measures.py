"""Image analysis of a yarn photo that uses neither the nets nor the renderer: the yarn's
core diameter and the period of its ply stripes, in pixels.  It is the independent yardstick
for fits on photos ipm did not make (the real backlit photos, the Cycles sets): a fit is
judged by whether its render measures like the photo.

The analysis itself is :mod:`ipm.textile.image` (``ipm measure`` reports it in a lab's
units); this module runs it on images and checks it on labelled renders.

    python -m ipm.benchmarks.photo_measures IMAGE... [--frontlit] [--pixel-size MM]
    python -m ipm.benchmarks.photo_measures --data DIR [--out FILE]

With ``--data``, a labelled dataset (``ipm generate``, the Cycles sets): how the yardstick
reads the true yarns, per image the core diameter over ``2 (R_ply + max(r_x, r_y))`` and
the stripe period over ``alpha_ply / n`` (medians, and the share within 15 %).
"""

from __future__ import annotations

import argparse

import numpy as np

from ipm.textile.image import gray, measure_image


def measure(path: str, backlit: bool) -> dict[str, float]:
    """Core diameter and ply-stripe period (px) of the photo at ``path``."""
    return measure_image(gray(path), backlit)


def agreement(folder: str, count: int | None = None) -> dict[str, float]:
    """The yardstick against the truth on a labelled dataset (each image's own setup):
    medians of the measured over the true core diameter and stripe period, and the share
    of periods within 15 %."""
    from ipm.dataset import read_manifest

    core, period = [], []
    for r in read_manifest(folder)[:count]:
        m = measure(str(r.image), backlit=r.setup == "backlit")
        p = r.params
        core.append(m["core_diameter_px"] * r.pixel_size_mm / (2 * (p.R_ply + max(p.r_x, p.r_y))))
        period.append(m["stripe_period_px"] * r.pixel_size_mm / (p.alpha_ply / p.n))
    period_ok = np.array(period)[np.isfinite(period)]
    return {"images": len(core), "core_ratio": float(np.median(core)),
            "period_ratio": float(np.median(period_ok)) if len(period_ok) else float("nan"),
            "period_within_15pct": float(np.mean(np.abs(np.array(period) - 1) < 0.15))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("images", nargs="*")
    ap.add_argument("--frontlit", action="store_true", help="light yarn on a dark background")
    ap.add_argument("--pixel-size", type=float, default=None, help="mm per pixel, for mm")
    ap.add_argument("--data", action="append", default=[], help="labelled dataset(s): the "
                    "yardstick against their truth")
    ap.add_argument("--count", type=int, default=None, help="first N images of each dataset")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    if args.data:
        from ipm.benchmarks.machine import markdown_header, publish

        lines = ["| dataset | images | core measured / 2 (R_ply + r) | period measured / "
                 "(alpha_ply / n) | periods within 15 % |", "|---|---|---|---|---|"]
        for folder in args.data:
            a = agreement(folder, args.count)
            lines.append(f"| `{folder}` | {a['images']} | {a['core_ratio']:.2f} | "
                         f"{a['period_ratio']:.2f} | {100 * a['period_within_15pct']:.0f}% |")
        command = "python -m ipm.benchmarks.photo_measures " + " ".join(
            [f"--data {d}" for d in args.data] + ([f"--count {args.count}"] if args.count
                                                  else []) + ([f"--out {args.out}"]
                                                              if args.out else []))
        publish(markdown_header("The net-free yardstick on labelled renders", command,
                                "numpy") + "\n" + "\n".join(lines) + "\n", args.out)
        return
    if not args.images:
        ap.error("give images, or --data DIR")
    scale = args.pixel_size or 1.0
    unit = "mm" if args.pixel_size else "px"
    print(f"| image | core diameter ({unit}) | stripe period ({unit}) |\n|---|---|---|")
    for path in args.images:
        m = measure(path, backlit=not args.frontlit)
        print(f"| {path} | {m['core_diameter_px'] * scale:.4g} | "
              f"{m['stripe_period_px'] * scale:.4g} |")


if __name__ == "__main__":
    main()
