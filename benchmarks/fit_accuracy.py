"""Neural-only vs refined: per-parameter MAE of ``ipm fit`` on held-out renders.

    python -m ipm.benchmarks.fit_accuracy --data data/test --count 30 \\
        [--out benchmarks/results/fit_accuracy.md]

The held-out set is made with ``ipm generate`` at seeds never used in training (photometric
variation on).  Each photo goes through the shipped ensemble and the default refinement
(:class:`ipm.refine.fit.FitOptions`); the table compares both with the labels.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish
from ipm.params import PAPER_INTERVALS
from ipm.photo import read_image

REFINED = ("alpha", "alpha_ply", "R_ply", "r_x", "r_y")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--count", type=int, default=30)
    ap.add_argument("--models", default=None)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    from ipm.nets.data import read_manifest
    from ipm.nets.ensemble import Ensemble
    from ipm.refine.fit import FitOptions, fit
    from ipm.render.renderer import Renderer

    ens, renderer, opts = Ensemble.load(args.models), Renderer(), FitOptions()
    records = read_manifest(args.data)[: args.count]
    err = {k: ([], []) for k in REFINED}
    seconds, improved = [], 0
    for r in records:
        image = read_image(r.image)
        t0 = time.perf_counter()
        res = fit(image, r.pixel_size_mm, ens.predict(image, r.pixel_size_mm), renderer, opts)
        seconds.append(time.perf_counter() - t0)
        improved += res.improved
        for k in REFINED:
            err[k][0].append(abs(getattr(res.neural, k) - getattr(r.params, k)))
            err[k][1].append(abs(getattr(res.refined, k) - getattr(r.params, k)))
        print(f"{r.image}: loss {res.loss_neural:.4f} -> {res.loss_refined:.4f}", flush=True)
    rows = ["| parameter | neural MAE | % of range | refined MAE | % of range | change |",
            "|---|---|---|---|---|---|"]
    for k, (a, b) in err.items():
        span = PAPER_INTERVALS[k].hi - PAPER_INTERVALS[k].lo
        ma, mb = float(np.mean(a)), float(np.mean(b))
        rows.append(f"| {k} | {ma:.4g} | {100 * ma / span:.1f} | {mb:.4g} | "
                    f"{100 * mb / span:.1f} | {100 * (mb / ma - 1):+.0f}% |")
    rows += ["", f"{len(records)} photos from `{args.data}`; the search kept a better candidate "
             f"for {improved}; fit time per photo: median {np.median(seconds):.0f} s."]
    command = f"python -m ipm.benchmarks.fit_accuracy --data {args.data} --count {args.count}"
    publish(markdown_header("Neural-only vs refined", command, "mitsuba", "torch", "nlopt")
            + "\n" + "\n".join(rows) + "\n", args.out)


if __name__ == "__main__":
    main()
