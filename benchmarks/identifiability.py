"""Identifiability of each yarn parameter by the refine loss: 1-D sweeps around the truth.

For each parameter and each of ``--yarns`` synthetic yarns (guided prior, seed 2000 + i), the
"photo" is a render with fiber seed 1000 + i; the loss is evaluated with fiber seed 0 (as in
a search: other fibers than the photo's) at the truth +- 2.5, 5, 7.5 and 10 % of the
parameter's prior range.  A parameter passes when, over the yarns, the sweep's minimum sits
within 5 % of the range of the truth (median) and the loss's spread across five fiber seeds
at the truth is small against its rise at +- 10 % (median ratio < 0.25).

    python -m ipm.benchmarks.identifiability --out docs/identifiability.md
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from ipm.benchmarks.machine import markdown_header
from ipm.io import write_text
from ipm.params import PAPER_INTERVALS
from ipm.photo import linear_to_srgb
from ipm.prior import GuidedPrior
from ipm.refine.objective import DEFAULT_WEIGHTS

COMMAND = "python -m ipm.benchmarks.identifiability --out docs/identifiability.md"
CANDIDATES = ("alpha", "alpha_ply", "R_ply", "r_x", "r_y", "j", "j_xy", "p", "beta", "l_hair",
              "s", "l_loop", "d_mean", "d_std")
STEPS = (-0.1, -0.075, -0.05, -0.025, 0.0, 0.025, 0.05, 0.075, 0.1)
SPREAD_SEEDS = (0, 1, 2, 3, 4)


def sweep(objective, truth, name: str) -> dict:
    iv = PAPER_INTERVALS[name]
    span = iv.hi - iv.lo
    steps, losses = [], []
    for d in STEPS:
        v = getattr(truth, name) + d * span
        if iv.lo <= v <= iv.hi:
            steps.append(d)
            losses.append(objective(truth.replace(**{name: v}), 0))
    at_truth = [objective(truth, s) for s in SPREAD_SEEDS]
    ends = [loss for d, loss in zip(steps, losses, strict=True) if abs(d) == 0.1]
    rise = float(np.mean(ends) - np.mean(at_truth)) if ends else float("nan")
    return {"argmin": float(steps[int(np.argmin(losses))]), "spread": float(np.std(at_truth)),
            "rise": rise, "steps": steps, "losses": losses}


def run(names, yarns: int, scale: float, spp: int, seeds_per_eval: int) -> dict:
    from ipm.refine.objective import RenderObjective
    from ipm.render.renderer import Renderer

    renderer = Renderer()
    truths = GuidedPrior().sample_many(yarns, seed=2000)
    results: dict[str, list] = {n: [] for n in names}
    for i, truth in enumerate(truths):
        photo = linear_to_srgb(renderer.render(truth, 1000 + i, scale, spp, render_seed=7))
        objective = RenderObjective(renderer, photo, scale, spp, seeds_per_eval=seeds_per_eval)
        for n in names:
            results[n].append(sweep(objective, truth, n))
            r = results[n][-1]
            print(f"yarn {i} {n}: argmin {r['argmin']:+.3f} "
                  f"spread/rise {r['spread'] / max(r['rise'], 1e-12):.2f}", flush=True)
    return results


def summary(results: dict, scale: float, spp: int, yarns: int) -> str:
    rows = ["| parameter | median abs(argmin - truth) (% of range) | worst (%) | "
            "median spread / rise | verdict |", "|---|---|---|---|---|"]
    for n, rs in results.items():
        off = np.array([abs(r["argmin"]) for r in rs]) * 100
        ratio = np.array([r["spread"] / r["rise"] if r["rise"] > 0 else np.inf for r in rs])
        ok = np.median(off) <= 5 and np.median(ratio) < 0.25
        rows.append(f"| `{n}` | {np.median(off):.1f} | {off.max():.1f} | "
                    f"{np.median(ratio):.2f} | {'identifiable' if ok else 'not identifiable'} |")
    head = markdown_header("Identifiability of the refine loss", COMMAND, "mitsuba", "torch",
                           "kornia")
    return (head + f"\n{yarns} yarns, scale {scale}, {spp} spp.\n\n" + "\n".join(rows) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=None)
    ap.add_argument("--yarns", type=int, default=10)
    ap.add_argument("--params", default=",".join(CANDIDATES))
    ap.add_argument("--scale", type=float, default=0.2)
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--seeds-per-eval", type=int, default=2)
    args = ap.parse_args()
    results = run(args.params.split(","), args.yarns, args.scale, args.spp, args.seeds_per_eval)
    text = summary(results, args.scale, args.spp, args.yarns)
    text += (f"Fiber seeds averaged per evaluation: {args.seeds_per_eval}; "
             f"group weights {DEFAULT_WEIGHTS}.\n")
    if args.out:
        write_text(args.out, text)
        write_text(args.out.rsplit(".", 1)[0] + ".json", json.dumps(results, indent=1))
    print(text)


if __name__ == "__main__":
    main()
