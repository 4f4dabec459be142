"""Can the refine loss tell the ply count?  On labelled photos, the true yarn rendered with
each ply count ``n`` of ``--counts`` (the same plies, ``alpha_ply`` scaled by ``n / n_true``
so that the ply stripes keep their period ``alpha_ply / n``, which the period groups see),
and the share of photos whose true count has the lowest loss, with and without each
statistics group.

Why: a fit chooses the ply count among the nets' likeliest by the loss
(:func:`ipm.refine.search.search_ply_counts`); the period and stripes groups see the
stripes' period alone, which every count matches with its own pitch.  This isolates what the
loss can see from what the search finds: the thickness stays the truth's, where a fit
searches it per count.  The photos are prepared as ``ipm fit`` prepares them
(:func:`ipm.refine.fit.search_view`, the yarn's tilt measured, the fiber colour matched at
the truth); every render uses fiber seeds other than the photo's.

    python -m ipm.benchmarks.ply_count_loss --data data/cycles-backlit \
        --out benchmarks/results/ply_count_loss_cycles_backlit.md
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish

SEEDS = (1, 2)


def run(data: str, count: int, counts: list[int], spp: int) -> list[dict]:
    """Per photo: the true count and, per candidate count, each group's distance (mean over
    :data:`SEEDS`)."""
    from ipm.benchmarks.report import load_records
    from ipm.errors import ParamError
    from ipm.refine.fit import FitOptions, match_colour, photo_tilt, search_view
    from ipm.refine.objective import RenderObjective
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options

    records = load_records(data, count)
    renderer = Renderer(options=setup_options(records[0].setup))
    out = []
    for i, rec in enumerate(records):
        photo = rec.photo()
        scale, frame = search_view(photo, FitOptions().scale)
        small = photo.at_pitch(scale)
        objective = RenderObjective(renderer, small, scale, spp, tilt_deg=photo_tilt(small),
                                    frame=frame)
        truth = match_colour(objective, rec.params, small)
        row = {"n": truth.n, "losses": {}}
        for n in counts:
            try:
                p = truth.replace(n=n, alpha_ply=truth.alpha_ply * n / truth.n)
            except ParamError:  # the scaled pitch leaves its range
                continue
            d = [objective.group_distances(p, s) for s in SEEDS]
            row["losses"][n] = {g: float(np.mean([x[g] for x in d])) for g in d[0]}
        out.append(row)
        print(f"photo {i}: n {truth.n}, "
              + ", ".join(f"{n}: {v['silhouette']:.3f}" for n, v in row["losses"].items()),
              flush=True)
    return out


def chosen(row: dict, weights: dict[str, float]) -> int:
    """The count whose weighted loss is lowest."""
    return min(row["losses"], key=lambda n: sum(w * row["losses"][n][g]
                                                for g, w in weights.items()))


def summary(rows: list[dict], data: str, command: str) -> str:
    from ipm.refine.objective import DEFAULT_WEIGHTS

    base = {g: w for g, w in DEFAULT_WEIGHTS.items() if w > 0}
    variants = {"the search's loss": base}
    variants |= {f"without {g}": {k: w for k, w in base.items() if k != g} for g in base}
    variants |= {f"{g} alone": {g: 1.0} for g in base}
    truths = sorted({r["n"] for r in rows})
    lines = ["| loss | right, all | " + " | ".join(f"n = {n}" for n in truths) + " |",
             "|---|---|" + "---|" * len(truths)]
    for name, weights in variants.items():
        right = [chosen(r, weights) == r["n"] for r in rows]
        per = [f"{sum(ok for ok, r in zip(right, rows, strict=True) if r['n'] == n)} / "
               f"{sum(r['n'] == n for r in rows)}" for n in truths]
        lines.append(f"| {name} | **{sum(right)} / {len(rows)}** | " + " | ".join(per) + " |")
    head = markdown_header("Can the refine loss tell the ply count?", command, "mitsuba",
                           "torch", "kornia")
    return (head + f"\n{len(rows)} photos of `{data}`.  Each photo's true yarn rendered with "
            f"each ply count, alpha_ply scaled to keep the stripes' period; right: the true "
            f"count has the lowest loss (mean of fiber seeds {list(SEEDS)}).  Weights of the "
            f"search's loss: {base}.\n\n" + "\n".join(lines) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, help="a labelled set (ipm generate, or a "
                    "Cycles test set)")
    ap.add_argument("--out", default=None)
    ap.add_argument("--count", type=int, default=30)
    ap.add_argument("--counts", default="2,3,4,5,6", help="the ply counts rendered")
    ap.add_argument("--spp", type=int, default=4)
    args = ap.parse_args()
    rows = run(args.data, args.count, [int(n) for n in args.counts.split(",")], args.spp)
    command = "python -m ipm.benchmarks.ply_count_loss " + " ".join(sys.argv[1:])
    text = summary(rows, args.data, command)
    publish(text, args.out, rows)


if __name__ == "__main__":
    main()
