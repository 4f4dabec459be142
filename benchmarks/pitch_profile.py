"""Where each group of the refine loss puts the ply pitch on real photos, against the
photo's stripe period measured without the nets.

For each photo of a finished ``real_photos`` run (its ``fits.jsonl``), the fit's refined
yarn is swept over a grid of ply pitches ``alpha_ply`` (everything else kept), rendered as
``ipm fit`` renders inside its search (the photo's view at the search pitch, its tilt, two
fiber seeds per evaluation), and each statistics group's distance to the photo is taken.
A group's pitch is its argmin over the grid, read as the period ``alpha_ply / n``; it is
compared with the photo's stripe period from the net-free yardstick
(:func:`ipm.benchmarks.real_photos.measures`).  This is the identifiability sweep
(``benchmarks/identifiability.py``) on photos ipm did not make, where the truth is not known
and the yardstick stands in for it.

    python -m ipm.benchmarks.pitch_profile --photos ../shared/real-yarns --pixel-size 0.0021 \\
        --fits docs/real-photos-material/fits.jsonl --out benchmarks/results/pitch_profile_real.md
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish

#: The periods ``alpha_ply / n`` swept, in mm: a 3 mm view's 0.4-2.2 mm.
PERIODS_MM = tuple(np.round(np.arange(0.4, 2.21, 0.05), 3))
#: The groups reported, and the search's sum of the alpha_ply stage after the thickness.
GROUPS = ("period", "stripes", "contour")
STAGE = "alpha_ply stage"


def profile(photo_file: Path, row: dict, pixel_size_mm: float, renderer) -> dict:
    """Per group (and the pitch stage's weighted sum), the period (mm) at its lowest."""
    from ipm.dataset import Record
    from ipm.params import YarnParams
    from ipm.refine.fit import FitOptions, photo_tilt, search_view
    from ipm.refine.objective import RenderObjective
    from ipm.refine.stats import weighted_sum

    options = FitOptions()
    photo = Record(photo_file, pixel_size_mm, setup="backlit").photo()
    scale, frame = search_view(photo, options.scale)
    small = photo.at_pitch(scale)
    objective = RenderObjective(renderer, small, scale, options.spp,
                                seeds_per_eval=options.seeds_per_eval,
                                tilt_deg=photo_tilt(small), frame=frame)
    stage = objective.stage_weights(("alpha_ply",), ("R_ply",))
    params = YarnParams.from_dict(row["refined"])
    curves: dict[str, list[float]] = {g: [] for g in (*GROUPS, STAGE)}
    for period in PERIODS_MM:
        d = objective.group_distances(params.replace(alpha_ply=period * params.n),
                                      options.search.fiber_seed)
        for g in GROUPS:
            curves[g].append(d[g])
        curves[STAGE].append(float(weighted_sum(d, stage)))
    return {g: float(PERIODS_MM[int(np.argmin(c))]) for g, c in curves.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--photos", type=Path, required=True)
    ap.add_argument("--pixel-size", type=float, required=True, help="mm per photo pixel")
    ap.add_argument("--fits", type=Path, required=True, help="fits.jsonl of a real_photos run")
    ap.add_argument("--count", type=int, default=None, help="the first N fits only")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()

    from ipm.benchmarks.photo_measures import gray
    from ipm.benchmarks.real_photos import measures
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options

    rows = [json.loads(line) for line in args.fits.read_text().splitlines() if line.strip()]
    rows = rows[: args.count]
    renderer = Renderer(options=setup_options("backlit"))
    table = []
    for row in rows:
        if "error" in row:
            continue
        f = args.photos / Path(row["image"]).name
        _, photo_period = measures(gray(str(f)), args.pixel_size)
        found = profile(f, row, args.pixel_size, renderer)
        table.append({"photo": f.name, "photo_period": photo_period, **found})
        print(f.name, f"{photo_period:.2f}", " ".join(f"{g} {v:.2f}" for g, v in found.items()),
              flush=True)
    cols = (*GROUPS, STAGE)
    off = {g: [abs(t[g] - t["photo_period"]) / t["photo_period"] for t in table
               if np.isfinite(t["photo_period"])] for g in cols}
    lines = [markdown_header("The ply pitch each loss group finds on real photos",
                             "python -m ipm.benchmarks.pitch_profile " + " ".join(sys.argv[1:]),
                             "mitsuba", "torch", "kornia"),
             f"{len(table)} photos at {args.pixel_size:g} mm per pixel, each fit of "
             f"`{args.fits}` swept over periods `alpha_ply / n` of {PERIODS_MM[0]:g}-"
             f"{PERIODS_MM[-1]:g} mm in steps of {PERIODS_MM[1] - PERIODS_MM[0]:.2f} mm, the "
             f"rest of its parameters kept.  `{STAGE}`: the weighted sum the search of the "
             "pitch after the thickness minimises.", "",
             "Median relative difference from the photo's period (net-free): " + ", ".join(
                 f"{g} **{100 * np.median(off[g]):.0f}%**" for g in cols) + ".", "",
             "| photo | photo's period (mm) | " + " | ".join(cols) + " |",
             "|---|---|" + "---|" * len(cols)]
    lines += [f"| {t['photo']} | {t['photo_period']:.2f} | "
              + " | ".join(f"{t[g]:.2f}" for g in cols) + " |" for t in table]
    publish("\n".join(lines) + "\n", args.out, table)


if __name__ == "__main__":
    main()
