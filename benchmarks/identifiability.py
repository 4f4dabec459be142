"""Identifiability of each refined parameter by each group of the refine loss: 1-D sweeps
around the truth on held-out photos.

The photos are the first ``--yarns`` of a held-out set made with ``ipm generate`` (photometric
variation on: exposure, white balance, tilt, shift, sensor noise), prepared exactly as
``ipm fit`` prepares a photo (resampled to the search's pixel pitch, the yarn's tilt measured,
the fiber colour matched at the true parameters).  For each parameter, the loss of every
statistics group (:data:`ipm.refine.stats.GROUPS`) and the weighted loss of the search
(:data:`ipm.refine.objective.DEFAULT_WEIGHTS`) are evaluated with fiber seeds other than the
photo's at the truth +- 2.5, 5, 7.5 and 10 % of the parameter's prior range.  A (parameter,
group) pair passes when, over the yarns, the sweep's minimum sits within 5 % of the range of
the truth (median) and the group's spread across fiber seeds at the truth is small against
its rise at +- 10 % (median ratio < 0.25).  The weights of the search follow from this table.
An integer parameter (``m``) is swept at the rounded values.

With ``--detail W`` each evaluation also renders a 3.2 x 3.2 mm window at the detail nets'
pitch, compared with the photo's by those nets' readings (groups ``detail_net_*``,
:class:`ipm.refine.objective.Detail`); the photos must be as fine as the detail nets
(``data/test-full``, 0.01 mm).

    python -m ipm.benchmarks.identifiability --data data/test --yarns 6 \\
        --out benchmarks/results/identifiability_frontlit.md
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish
from ipm.params import PAPER_INTERVALS, RAW_CONTINUOUS

STEPS = (-0.1, -0.075, -0.05, -0.025, 0.0, 0.025, 0.05, 0.075, 0.1)
SPREAD_SEEDS = (0, 1, 2, 3, 4)
TOTAL = "search loss"


def group_losses(objective, params, seed: int) -> dict[str, float]:
    """Each group's loss and the weighted search loss of one evaluation of ``objective``."""
    from ipm.refine.stats import weighted_sum

    out = objective.group_distances(params, seed)
    out[TOTAL] = float(weighted_sum(out, objective.weights))
    return out


def sweep(objective, truth, name: str) -> dict[str, dict]:
    """Per group: the sweep's argmin (fraction of the range), the spread across fiber seeds
    at the truth and the rise at +- 10 %."""
    iv = PAPER_INTERVALS[name]
    span = iv.width
    steps, losses = [], []
    for d in STEPS:
        v = getattr(truth, name) + d * span
        v = round(v) if iv.integer else v
        if iv.lo <= v <= iv.hi:
            steps.append(d)
            losses.append(group_losses(objective, truth.replace(**{name: v}), 0))
    at_truth = [group_losses(objective, truth, s) for s in SPREAD_SEEDS]
    out = {}
    for g in losses[0]:
        curve = [loss[g] for loss in losses]
        ends = [c for d, c in zip(steps, curve, strict=True) if abs(d) == 0.1]
        truth_g = [t[g] for t in at_truth]
        out[g] = {"argmin": float(steps[int(np.argmin(curve))]),
                  "spread": float(np.std(truth_g)),
                  "rise": float(np.mean(ends) - np.mean(truth_g)) if ends else float("nan")}
    return out


def run(data: str, names, yarns: int, scale: float, spp: int, seeds_per_eval: int,
        learned: float = 0.0, detail: float = 0.0) -> dict:
    """The sweeps; with ``learned`` > 0 the loss also holds the shipped nets' readings (groups
    ``net_*``, :meth:`ipm.nets.ensemble.Ensemble.readings`) at that weight, with ``detail``
    > 0 the detail nets' readings of a detail window (module doc)."""
    from ipm.benchmarks.report import load_records
    from ipm.nets.ensemble import Ensemble
    from ipm.refine.measure import match_colour, photo_tilt
    from ipm.refine.objective import Detail, RenderObjective
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options

    records = load_records(data, yarns)
    setup = records[0].setup
    ensemble = Ensemble.load(setup=setup) if learned > 0 or detail > 0 else None
    readings = ensemble.readings if learned > 0 else None
    renderer = Renderer(options=setup_options(setup))
    results: dict[str, list] = {n: [] for n in names}
    for i, rec in enumerate(records):
        photo = rec.photo().at_pitch(scale)
        window = None
        if detail > 0:
            nets = ensemble.detail_readings(rec.pixel_size_mm)
            if nets is None:
                raise SystemExit(f"{data}: photos of {rec.pixel_size_mm:g} mm are too coarse "
                                 "for the detail nets")
            window = Detail.of_photo(rec.photo(), *nets, weight=detail, spp=spp)
        objective = RenderObjective(renderer, photo, scale, spp, seeds_per_eval=seeds_per_eval,
                                    tilt_deg=photo_tilt(photo), readings=readings,
                                    readings_weight=learned, detail=window)
        truth = match_colour(objective, rec.params, photo)
        for n in names:
            results[n].append(sweep(objective, truth, n))
            r = results[n][-1][TOTAL]
            print(f"yarn {i} {n}: argmin {r['argmin']:+.3f} "
                  f"spread/rise {r['spread'] / max(r['rise'], 1e-12):.2f}", flush=True)
    return results


def verdicts(results: dict) -> dict[str, dict[str, dict]]:
    """{parameter: {group: median |argmin| %, worst %, median spread/rise, ok}}."""
    out: dict = {}
    for n, rs in results.items():
        out[n] = {}
        for g in rs[0]:
            off = np.array([abs(r[g]["argmin"]) for r in rs]) * 100
            ratio = np.array([r[g]["spread"] / r[g]["rise"] if r[g]["rise"] > 0 else np.inf
                              for r in rs])
            out[n][g] = {"offset": float(np.median(off)), "worst": float(off.max()),
                         "ratio": float(np.median(ratio)),
                         "ok": bool(np.median(off) <= 5 and np.median(ratio) < 0.25)}
    return out


def summary(results: dict, scale: float, spp: int, yarns: int, data: str, command: str
            ) -> str:
    v = verdicts(results)
    groups = list(next(iter(v.values())))
    rows = ["| parameter | " + " | ".join(groups) + " |", "|---|" + "---|" * len(groups)]
    for n, per in v.items():
        rows.append(f"| `{n}` | " + " | ".join(
            f"{'**' if g[1]['ok'] else ''}{g[1]['offset']:.1f} / {g[1]['ratio']:.2f}"
            f"{'**' if g[1]['ok'] else ''}" for g in per.items()) + " |")
    head = markdown_header("Identifiability of the refine loss", command, "mitsuba", "torch",
                           "kornia")
    return (head + f"\n{yarns} held-out photos of `{data}`, scale {scale}, {spp} spp.  Each "
            "cell: median |argmin - truth| in % of the parameter's range / median spread "
            "across fiber seeds over the rise at +-10 %; bold: identifiable (<= 5 % and "
            "< 0.25).\n\n" + "\n".join(rows) + "\n")


def main() -> None:
    from ipm.refine.objective import DEFAULT_WEIGHTS

    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, help="held-out set made with ipm generate")
    ap.add_argument("--out", default=None)
    ap.add_argument("--yarns", type=int, default=10)
    ap.add_argument("--params", default=",".join(RAW_CONTINUOUS))
    ap.add_argument("--scale", type=float, default=0.2)
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--seeds-per-eval", type=int, default=2)
    ap.add_argument("--learned", type=float, default=0.0, help="weight of the nets' readings "
                    "in the loss (0: the image statistics alone)")
    ap.add_argument("--detail", type=float, default=0.0, help="weight of the detail nets' "
                    "readings of a detail window in the loss (0: off)")
    args = ap.parse_args()
    results = run(args.data, args.params.split(","), args.yarns, args.scale, args.spp,
                  args.seeds_per_eval, args.learned, args.detail)
    command = "python -m ipm.benchmarks.identifiability " + " ".join(sys.argv[1:])
    text = summary(results, args.scale, args.spp, args.yarns, args.data, command)
    learned = f", every net_* group {args.learned:g}" if args.learned else ""
    learned += f", every detail_* group {args.detail:g}" if args.detail else ""
    text += (f"\nFiber seeds averaged per evaluation: {args.seeds_per_eval}; weights of the "
             f"search loss {DEFAULT_WEIGHTS}{learned}.\n")
    publish(text, args.out, results)


if __name__ == "__main__":
    main()
