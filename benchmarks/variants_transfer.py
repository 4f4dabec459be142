"""Do the paper's semi-supervised losses help the nets hold on images ipm did not render?

The paper adapts its nets to real photos with two losses on unlabelled photos: L_recon, an
auto-encoder's reconstruction (the ``reg-ae`` variants), and L_latent, the real photos' mean
latent code pulled to the synthetic one's (``reg-latent``).  ``benchmarks/train_variants.sh``
trains the four variants (``reg``, ``reg-ae``, ``reg-latent``, ``reg-ae-latent``) at the
shipped nets' CPU scale, for the backlit setup with the 24 backlit photos as the real set.
This reads each variant and the shipped ensemble with the nets alone (no refinement) on

* labelled sets (``--data``, repeatable: ipm's held-out renders, the Cycles cross-renderer
  set): per continuous raw-yarn parameter the MAE over the predict-the-mean baseline's (issue
  21's target on the Cycles set: at most 0.6), and the ply-count accuracy;
* the real photos (``--photos``), judged by image analysis that uses no net
  (:mod:`ipm.benchmarks.photo_measures`): the ply count on the photos their README calls
  2-ply, the ply-stripe period ``alpha_ply / n`` against the photo's, and the core diameter
  of the predicted yarn's render against the photo's.

The real photos are the adapted variants' unlabelled training set (as in the paper, whose
real set is the photos it reads): on them the table shows whether the adaptation reached
the photos it saw; on the Cycles set, which no variant saw, whether it carries to another
renderer.  ``reg`` is the fair reference for the other three (the same net and recipe
without the extra losses); the ensemble (a net per parameter, longer training) is shown
beside them.

    python -m ipm.benchmarks.variants_transfer --variants runs-variants-backlit \\
        --data data-backlit/test --data data/cycles-backlit \\
        --photos ../shared/real-yarns --pixel-size 0.0021 \\
        --out benchmarks/results/variants_backlit.md
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish
from ipm.benchmarks.real_photos import (
    MEASURE_PITCH_MM,
    measures,
    readme_ply_counts,
    relative,
    render_over,
)
from ipm.benchmarks.report import ENSEMBLE, accuracy, baseline_accuracy, load_approaches
from ipm.dataset import Record, photo_files, read_manifest
from ipm.params import RAW_CONTINUOUS
from ipm.textile.image import gray

#: The parameters of issue 21's cross-renderer target, in its order.
TARGET = ("alpha", "alpha_ply", "R_ply", "r_x", "r_y", "m")


def labelled(approaches: dict, folder: Path, count: int | None, crops: int,
             progress) -> dict:
    """Per approach: MAE over the baseline's per parameter of :data:`TARGET`, and the
    ply-count accuracy, on the labelled set in ``folder``."""
    records = read_manifest(folder)[:count]
    truth = [r.params for r in records]
    base = baseline_accuracy(approaches[ENSEMBLE].mean_prediction(records[0].pixel_size_mm),
                             truth)
    preds: dict[str, list] = {name: [] for name in approaches}
    for i, r in enumerate(records):
        photo = r.photo()
        for name, ens in approaches.items():
            preds[name].append(ens.predict(photo, crops).to_dict())
        progress(f"{folder}", i + 1, len(records))
    out = {}
    for name, ps in preds.items():
        acc = accuracy(ps, truth, TARGET)
        out[name] = {"ratio": {k: acc["params"][k]["mae"] / base[k]["mae"] for k in TARGET},
                     "n_accuracy": acc["n_accuracy"]}
    return {"count": len(records), "approaches": out}


def real(approaches: dict, folder: Path, pixel_size_mm: float, crops: int, progress) -> dict:
    """Per approach, on the real photos in ``folder`` (measured without the nets): the ply
    count right on the README's 2-ply photos, and the median relative difference of the
    stripe period and of the core diameter (the predicted yarn rendered over the photo's
    field of view)."""
    from ipm.refine.plan import FitConfig
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options

    files = photo_files(folder)
    plies = readme_ply_counts(folder)
    renderer = Renderer(options=setup_options("backlit"))
    seed = FitConfig().fiber_seed
    rows: dict[str, list] = {name: [] for name in approaches}
    for i, f in enumerate(files):
        image = gray(str(f))
        d_photo, period_photo = measures(image, pixel_size_mm)
        photo = Record(f, pixel_size_mm, setup="backlit").photo()
        for name, ens in approaches.items():
            p = ens.predict(photo, crops)
            render = render_over(renderer, p, image.shape, pixel_size_mm, 0.0, seed)
            d_render, _ = measures(render, MEASURE_PITCH_MM)
            rows[name].append({"photo": f.name, "n": p.n, "plies": plies.get(f.name),
                               "core_rel": relative(d_render, d_photo),
                               "period_rel": relative(p.alpha_ply / p.n, period_photo)})
        progress(f"{folder}", i + 1, len(files))
    out = {}
    for name, rs in rows.items():
        two = [r for r in rs if r["plies"] is not None]
        out[name] = {"n_right": sum(r["n"] == r["plies"] for r in two), "n_of": len(two),
                     "core_rel": float(np.nanmedian([r["core_rel"] for r in rs])),
                     "period_rel": float(np.nanmedian([r["period_rel"] for r in rs])),
                     "rows": rs}
    return {"count": len(files), "approaches": out}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variants", type=Path, required=True,
                    help="folder of benchmarks/train_variants.sh's runs")
    ap.add_argument("--models", type=Path, default=None, help="default: the shipped backlit")
    ap.add_argument("--data", type=Path, action="append", default=[],
                    help="a labelled set (`ipm generate`, the Cycles sets); repeatable")
    ap.add_argument("--count", type=int, default=None, help="photos per labelled set")
    ap.add_argument("--photos", type=Path, default=None, help="real backlit photos")
    ap.add_argument("--pixel-size", type=float, default=None, help="mm per real photo pixel")
    ap.add_argument("--crops", type=int, default=3)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    if args.photos is not None and args.pixel_size is None:
        ap.error("--photos needs --pixel-size")
    approaches = load_approaches(args.models, args.variants, setup="backlit")

    def progress(what: str, done: int, total: int) -> None:
        print(f"{what}: {done}/{total}", end="\r" if done < total else "\n", flush=True)

    sets = {str(d): labelled(approaches, d, args.count, args.crops, progress)
            for d in args.data}
    photos = (real(approaches, args.photos, args.pixel_size, args.crops, progress)
              if args.photos is not None else None)

    lines = []
    for name, s in sets.items():
        lines += [f"## `{name}` ({s['count']} images): MAE over the predict-the-mean "
                  "baseline's (lower is better; issue 21's target on the Cycles set: at most "
                  "0.6), ply-count accuracy", "",
                  "| nets | " + " | ".join(TARGET) + " | ply count |",
                  "|---|" + "---|" * (len(TARGET) + 1)]
        for a, r in s["approaches"].items():
            lines.append(f"| {a} | " + " | ".join(f"{r['ratio'][k]:.2f}" for k in TARGET)
                         + f" | {100 * r['n_accuracy']:.0f}% |")
        lines.append("")
    if photos is not None:
        lines += [f"## Real photos (`{args.photos}`, {photos['count']} at {args.pixel_size:g} "
                  "mm per pixel), measured without the nets", "",
                  "| nets | ply count right (README's 2-ply) | stripe period, median relative "
                  "difference | core diameter of the render, median relative difference |",
                  "|---|---|---|---|"]
        for a, r in photos["approaches"].items():
            lines.append(f"| {a} | {r['n_right']} of {r['n_of']} | "
                         f"{100 * r['period_rel']:.0f}% | {100 * r['core_rel']:.0f}% |")
        lines.append("")
    command = " ".join(["python -m ipm.benchmarks.variants_transfer --variants",
                        str(args.variants)]
                       + (["--models", str(args.models)] if args.models else [])
                       + [f"--data {d}" for d in args.data]
                       + (["--count", str(args.count)] if args.count else [])
                       + (["--photos", str(args.photos), "--pixel-size", f"{args.pixel_size:g}"]
                          if args.photos is not None else [])
                       + ["--out", args.out])
    head = markdown_header("The paper's semi-supervised losses, nets alone, on images ipm did "
                           "not render", command, "torch", "mitsuba")
    intro = (f"Nets: the shipped ensemble (`{approaches[ENSEMBLE].folder}`) and the variants "
             f"in `{args.variants}` ({', '.join(a for a in approaches if a != ENSEMBLE)}), "
             f"each read with {args.crops} crops; the continuous raw-yarn parameters "
             f"({', '.join(k for k in RAW_CONTINUOUS)}) and the ply count.  The real photos "
             "are the adapted variants' unlabelled training set; the Cycles set no net saw.")
    publish(head + "\n" + intro + "\n\n" + "\n".join(lines), args.out,
            data={"sets": sets, "photos": photos})


if __name__ == "__main__":
    main()
