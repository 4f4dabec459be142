"""``ipm measure``'s analysis (:mod:`ipm.textile.image`) on ipm renders whose fibers are
known, against the truth computed here from the fibers and parameters, not by the analysis:

* diameter: the fibers' shadow width (:func:`ipm.textile.fibers.shadow_radius`: every
  fiber's projection drawn at 0.005 mm, the rows fiber covers on at least half the frame's
  length), what an optical tester sees; the plies' envelope ``2 (R_ply + max(r_x, r_y))``
  beside it, which a sleeve of loops hides;
* ply twist: ``1000 / |alpha_ply|`` turns per metre (the analysis given the true ply count,
  as a lab knows its yarn's), and its direction from the fibers: the sense in which the
  first ply's centre (the mean of its fibers in slices along the axis) turns about the axis
  as it advances, in the generator's right-handed frame (right-handed: Z);
* hairiness H: the fibers regenerated from the render's parameters and fiber seed,
  projected as the camera sees them (the generator's z to the right, its x up), and the
  length of every segment whose both ends lie beyond the shadow's edges and inside the
  frame, per mm of the frame's width.

The renders are labelled sets of ``ipm generate`` at the paper's pitch; none was used to
choose anything in the analysis.

    ipm generate --out D/frontlit --count 40 --seed 52 --split test --scale 1 --spp 16
    ipm generate --out D/backlit --count 40 --seed 52 --split test --scale 1 --spp 16 \\
        --setup backlit
    python -m ipm.benchmarks.textile_truth --data D/frontlit --data D/backlit \\
        --out benchmarks/results/textile_truth.md
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from ipm.dataset import read_manifest
from ipm.frame import FRAME_HEIGHT_MM, FRAME_WIDTH_MM
from ipm.generator import generate
from ipm.params import YarnParams
from ipm.textile.fibers import beyond, shadow_coverage, shadow_radius
from ipm.textile.image import gray, measure_photo


def envelope_diameter(p: YarnParams) -> float:
    """The yarn's envelope (mm)."""
    return 2 * (p.R_ply + max(p.r_x, p.r_y))


def true_direction(fs) -> str:
    """S or Z from the fibers: the first ply's centre turning about the axis."""
    pts = np.concatenate([fs.fiber(i) for i in np.flatnonzero((fs.kind == 0) & (fs.ply == 0))
                          ]).astype(np.float64)
    zs = np.linspace(-3, 3, 61)
    centres = [pts[np.abs(pts[:, 2] - z) < 0.05, :2].mean(axis=0) for z in zs]
    angle = np.unwrap([np.arctan2(y, x) for x, y in centres])
    return "Z" if angle[-1] > angle[0] else "S"  # counter-clockwise seen from +z: right-handed


def frame_segments(fs, width_mm: float, height_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """(starts, ends) (K, 3) of the fibers' segments inside the frame, none joining two
    fibers."""
    pts = fs.points.astype(np.float64)
    a, b = pts[:-1], pts[1:]
    same = np.ones(len(pts) - 1, bool)
    same[fs.offsets[1:-1] - 1] = False  # no segment from one fiber's end to the next's start
    inside = ((np.abs(a[:, 2]) < width_mm / 2) & (np.abs(b[:, 2]) < width_mm / 2)
              & (np.abs(a[:, 0]) < height_mm / 2) & (np.abs(b[:, 0]) < height_mm / 2))
    keep = same & inside
    return a[keep], b[keep]


def evaluate(folder: str, count: int | None = None) -> dict:
    """Per image the measured over the true diameter, ply twist and H, and whether the
    direction is right; with the analysis' median time per image."""
    out = {"diameter": [], "envelope": [], "tpm": [], "h": [], "direction": [], "seen": [],
           "mirrored": [], "seconds": []}
    records = read_manifest(folder)[:count]
    for r in records:
        p = r.params
        img = gray(str(r.image))
        t = time.perf_counter()
        m = measure_photo(img, r.pixel_size_mm, r.setup == "backlit", plies=p.n)
        out["seconds"].append(time.perf_counter() - t)
        fs = generate(p, r.seed)
        width, height = img.shape[1] * r.pixel_size_mm, img.shape[0] * r.pixel_size_mm
        radius = shadow_radius(shadow_coverage(fs, width / 2, height / 2))
        truth_h = beyond(*frame_segments(fs, width, height), radius) / width
        out["diameter"].append(m.diameter_mm / (2 * radius))
        out["envelope"].append(m.diameter_mm / envelope_diameter(p))
        out["tpm"].append((m.ply_twist_tpm or np.nan) / (1000 / abs(p.alpha_ply)))
        out["h"].append(m.hairiness_h / truth_h if truth_h > 0 else np.nan)
        out["seen"].append(m.twist_direction is not None)
        truth = true_direction(fs)
        out["direction"].append(m.twist_direction == truth)
        # the render upside down is the mirror image of the yarn: the other direction
        flipped = measure_photo(img[::-1], r.pixel_size_mm, r.setup == "backlit", plies=p.n)
        out["mirrored"].append(flipped.twist_direction == {"S": "Z", "Z": "S"}[truth])
    return {"images": len(records), **{k: np.asarray(v, dtype=float) for k, v in out.items()}}


def _mare(ratios: np.ndarray) -> str:
    """Median absolute relative error of ratios measured / true, in percent (NaN: none)."""
    finite = ratios[np.isfinite(ratios)]
    return f"{100 * np.median(np.abs(finite - 1)):.1f}%" if len(finite) else "-"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", action="append", required=True, help="labelled render set(s)")
    ap.add_argument("--count", type=int, default=None)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    from ipm.benchmarks.machine import markdown_header, publish

    lines = ["| renders | images | diameter (shadow) | diameter against the envelope | "
             "ply twist (turns/m) | H | direction right | direction seen | "
             "direction right, mirrored | median time |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    made = []
    for folder in args.data:
        d = json.loads((Path(folder) / "dataset.json").read_text())
        made.append(f"`{folder}`: seed {d['seed']}, split {d['split']}, scale {d['scale']:g}, "
                    f"{d['spp']} spp, setup {d.get('scene', {}).get('setup', 'frontlit')}")
        e = evaluate(folder, args.count)
        lines.append(f"| `{folder}` | {e['images']} | {_mare(e['diameter'])} | "
                     f"{_mare(e['envelope'])} | "
                     f"{_mare(e['tpm'])} | {_mare(e['h'])} | "
                     f"{int(e['direction'].sum())} of {e['images']} | "
                     f"{int(e['seen'].sum())} of {e['images']} | "
                     f"{int(e['mirrored'].sum())} of {e['images']} | "
                     f"{1000 * np.median(e['seconds']):.0f} ms |")
        print(lines[-1], flush=True)
    command = "python -m ipm.benchmarks.textile_truth " + " ".join(
        [f"--data {d}" for d in args.data] + ([f"--count {args.count}"] if args.count else [])
        + ([f"--out {args.out}"] if args.out else []))
    note = (f"Median absolute relative error against the truth from the fibers (module notes) "
            f"on renders at their own pitch ({FRAME_WIDTH_MM:g} x {FRAME_HEIGHT_MM:g} mm "
            "frames); the ply twist with the true ply count given (`--plies`); direction "
            "seen: the analysis names one (S or Z); mirrored: each render measured upside "
            "down, the mirror image of its yarn, whose direction is the other.  The sets "
            "(`ipm generate`): "
            + "; ".join(made) + ".")
    publish(markdown_header("ipm measure against the fibers' truth", command, "numpy")
            + "\n" + note + "\n\n" + "\n".join(lines) + "\n", args.out)


if __name__ == "__main__":
    main()
