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
(:func:`ipm.refine.measure.search_view`, the yarn's tilt measured, the fiber colour matched at
the truth); every render uses fiber seeds other than the photo's.

With ``--start nets`` the renders start from the nets' guess instead, at their stripe
period, scored by the fit's own objective and seeds: what a fit's choice of the count
(:func:`ipm.refine.measure.choose_ply_count`) sees, with its thickness errors, and each
group's choice with the nets' probabilities as a fit weighs them.

    python -m ipm.benchmarks.ply_count_loss --data data/cycles-backlit \
        --out benchmarks/results/ply_count_loss_cycles_backlit.md
    python -m ipm.benchmarks.ply_count_loss --start nets --data data-backlit/val \
        --out benchmarks/results/ply_count_nets_backlit_val.md
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish

SEEDS = (1, 2)


def run(data: str, count: int, counts: list[int], spp: int, start: str = "truth"
        ) -> list[dict]:
    """Per photo: the true count and, per candidate count, each group's distance (mean over
    the seeds, and per seed).  ``start``: ``truth`` renders the true yarn with each count
    (fiber seeds :data:`SEEDS`); ``nets`` the nets' guess with their stripe period
    (:func:`ipm.refine.search.same_period`), as a fit sees it (its objective and seeds),
    and records the nets' count and probabilities."""
    from ipm.benchmarks.report import load_records
    from ipm.nets.ensemble import Ensemble
    from ipm.refine.fit import search_objective
    from ipm.refine.measure import match_colour
    from ipm.refine.plan import FitConfig
    from ipm.refine.search import same_period
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options

    records = load_records(data, count)
    setup = records[0].setup
    renderer = Renderer(options=setup_options(setup))
    ens = Ensemble.load(None, setup=setup) if start == "nets" else None
    fit = FitConfig()
    seeds = (fit.fiber_seed, *fit.rescore_seeds) if ens else SEEDS
    rendered = replace(fit, spp=spp, seeds_per_eval=fit.seeds_per_eval if ens else 1)
    out = []
    for i, rec in enumerate(records):
        photo = rec.photo()
        objective, small = search_objective(photo, renderer, rendered)
        row: dict = {"n": rec.params.n, "setup": setup, "losses": {}, "per_seed": {}}
        base = rec.params
        if ens is not None:
            base = ens.predict(photo, base=rec.params)
            row |= {"nets_n": base.n, "nets_p": ens.ply_count_probabilities(photo)}
        base = match_colour(objective, base, small)
        for n in counts:
            p = same_period(base, n)
            if p is None:  # the scaled pitch leaves its range
                continue
            d = [objective.group_distances(p, s) for s in seeds]
            row["losses"][n] = {g: float(np.mean([x[g] for x in d])) for g in d[0]}
            row["per_seed"][n] = d
        out.append(row)
        print(f"photo {i}: n {row['n']}, "
              + ", ".join(f"{n}: {v['silhouette']:.3f}" for n, v in row["losses"].items()),
              flush=True)
    return out


def chosen(row: dict, weights: dict[str, float], prior: bool = False) -> int:
    """The count whose weighted loss is lowest; with ``prior``, whose score of
    :func:`ipm.refine.search.ply_count_scores` (the loss in seed-noise units minus the log
    of the nets' probability) is, as a fit chooses."""
    from ipm.refine.search import ply_count_scores

    def loss(d: dict) -> float:
        return sum(w * d[g] for g, w in weights.items())

    if prior:
        scores = ply_count_scores({int(n): [loss(d) for d in v]
                                   for n, v in row["per_seed"].items()},
                                  {int(n): p for n, p in row["nets_p"].items()})
        return min(scores, key=scores.__getitem__)
    return min((int(n) for n in row["losses"]), key=lambda n: loss(row["losses"][n]))


def summary(rows: list[dict], data: str, command: str) -> str:
    from ipm.refine.objective import DEFAULT_WEIGHTS
    from ipm.setups import setup_of

    nets = "nets_p" in rows[0]
    base = {g: w for g, w in DEFAULT_WEIGHTS.items() if w > 0}
    variants = {"the search's loss": base}
    variants |= {f"without {g}": {k: w for k, w in base.items() if k != g} for g in base}
    variants |= {f"{g} alone": {g: 1.0} for g in base}
    truths = sorted({r["n"] for r in rows})

    def line(name: str, picks: list[int]) -> str:
        right = [n == r["n"] for n, r in zip(picks, rows, strict=True)]
        per = [f"{sum(ok for ok, r in zip(right, rows, strict=True) if r['n'] == n)} / "
               f"{sum(r['n'] == n for r in rows)}" for n in truths]
        return f"| {name} | **{sum(right)} / {len(rows)}** | " + " | ".join(per) + " |"

    lines = ["| choice | right, all | " + " | ".join(f"n = {n}" for n in truths) + " |",
             "|---|---|" + "---|" * len(truths)]
    if nets:
        lines.append(line("the nets", [r["nets_n"] for r in rows]))
    for name, weights in variants.items():
        lines.append(line(name, [chosen(r, weights) for r in rows]))
        if nets:
            lines.append(line(f"{name}, with the nets' probabilities",
                              [chosen(r, weights, prior=True) for r in rows]))
    head = markdown_header("Can the refine loss tell the ply count?", command, "mitsuba",
                           "torch", "kornia")
    if nets:
        groups = setup_of(rows[0]["setup"]).count_groups
        how = ("the nets' guess rendered with each ply count, `alpha_ply` scaled to keep "
               "the nets' stripe period, the fit's objective and fiber seeds; with the nets' "
               "probabilities: the lowest loss in units of its seed noise minus the log "
               "probability (`ipm.refine.search.ply_count_scores`).  A fit chooses by "
               + (f"{', '.join(groups)} with the nets' probabilities" if groups
                  else "nothing: it keeps the nets' count") + " (`ipm.setups`)")
    else:
        how = (f"each photo's true yarn rendered with each ply count, `alpha_ply` scaled to "
               f"keep the stripes' period (mean of fiber seeds {list(SEEDS)})")
    return (head + f"\n{len(rows)} photos of `{data}`: {how}; right: the true count has the "
            f"lowest loss.  Weights of the search's loss: {base}.\n\n" + "\n".join(lines)
            + "\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, help="a labelled set (ipm generate, or a "
                    "Cycles test set)")
    ap.add_argument("--out", default=None)
    ap.add_argument("--count", type=int, default=30)
    ap.add_argument("--counts", default="2,3,4,5,6", help="the ply counts rendered")
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--start", choices=("truth", "nets"), default="truth",
                    help="render each count from the true yarn, or from the nets' guess at "
                    "their period as a fit does")
    args = ap.parse_args()
    rows = run(args.data, args.count, [int(n) for n in args.counts.split(",")], args.spp,
               args.start)
    command = "python -m ipm.benchmarks.ply_count_loss " + " ".join(sys.argv[1:])
    text = summary(rows, args.data, command)
    publish(text, args.out, rows)


if __name__ == "__main__":
    main()
