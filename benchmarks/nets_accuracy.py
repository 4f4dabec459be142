"""Accuracy of a trained ensemble on a held-out dataset made with ``ipm generate`` at seeds
never used for training: per-parameter MAE in raw units and in % of the parameter's
interval and the mean signed error (a bias: how much of the error is one direction), beside
the predict-the-mean baseline (the mean training label, stored with each net) and the
paper's validation table; ply-count and thickness-class accuracy beside the
majority class.  ``--blur-mm`` blurs every photo first (a Gaussian of that sigma in mm, in
linear light: :meth:`ipm.photo.Photo.defocused`), to see how the nets hold up on a
photo with the defocus a render lacks.  ``--view-mm W H`` cuts every photo to its central
W x H mm first, to see how the nets hold on a tighter field of view than theirs (12 x 5.84
mm): :meth:`ipm.photo.Photo.at_pitch` pads the rows and the nets pool along the yarn.

    python -m ipm.benchmarks.nets_accuracy --data data/test [--models DIR] [--blur-mm S]
        [--view-mm W H] [--out benchmarks/results/nets_accuracy.md]
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish
from ipm.dataset import read_manifest
from ipm.nets.ensemble import Ensemble
from ipm.params import (
    PAPER_INTERVALS,
    PAPER_VALIDATION_MAE,
    PARAM_ORDER,
    RAW_CONTINUOUS,
    THICKNESS_CLASSES,
)
from ipm.photo import Photo


def mae_by_param(pred: list, true: list, keys) -> dict[str, float]:
    """Per parameter of ``keys``, the mean absolute error of ``pred`` against ``true`` (lists
    of :class:`ipm.params.YarnParams`, in order)."""
    return {k: float(np.mean([abs(getattr(p, k) - getattr(t, k))
                              for p, t in zip(pred, true, strict=True)])) for k in keys}


def baseline_mae(ens: Ensemble, true: list, pixel_size_mm: float, keys) -> dict[str, float]:
    """Per parameter of ``keys``, the error of predicting the mean training label (stored
    with each net, :meth:`Ensemble.mean_prediction`) for every yarn of ``true``."""
    base = ens.mean_prediction(pixel_size_mm)
    return {k: float(np.mean([abs(base[k] - getattr(t, k)) for t in true])) for k in keys}


def central_view(photo: Photo, width_mm: float, height_mm: float) -> Photo:
    """The photo cut to its central ``width_mm`` x ``height_mm``."""
    h, w = photo.image.shape[:2]
    ch, cw = (min(n, round(mm / photo.pixel_size_mm)) for n, mm in ((h, height_mm),
                                                                    (w, width_mm)))
    top, left = (h - ch) // 2, (w - cw) // 2
    return replace(photo, image=photo.image[top:top + ch, left:left + cw])


def coverage(pairs: list, sigma: dict[str, float]) -> str:
    """How often the 80% interval ``ipm fit`` gives a parameter the search did not touch
    (:func:`ipm.refine.fit.nets_interval`: the nets' validation error as a Gaussian around
    their value) holds the truth."""
    from ipm.refine.fit import nets_interval
    from ipm.refine.search import LEVEL

    def holds(k: str, p, t) -> bool:
        lo, hi = nets_interval(k, getattr(p, k), sigma[k])
        return lo <= getattr(t, k) <= hi

    held = {k: np.mean([holds(k, p, t) for p, t in pairs]) for k in RAW_CONTINUOUS
            if k in sigma}
    return (f"The nets' {LEVEL:.0%} intervals (their validation error as a Gaussian) hold the "
            "truth for " + ", ".join(f"{k} {v:.0%}" for k, v in held.items()) + ".")


def alpha_signal(pairs: list) -> str:
    """What the fiber-twist net follows: the correlation of its alpha with the true alpha,
    with the fiber helix angle gamma (``tan gamma = -alpha / (2 pi r_x)``, the sampler's
    auxiliary variable, which sets the fibers' slant in the image) and with the ply radius
    r_x (``alpha`` scales with it)."""
    pred, true = (np.array([x.alpha for x in xs]) for xs in zip(*pairs, strict=True))
    r_x = np.array([t.r_x for _, t in pairs])
    gamma = np.arctan(-true / (2 * np.pi * r_x))
    c = [np.corrcoef(pred, v)[0, 1] for v in (true, -gamma, -r_x)]
    return (f"The alpha net: correlation of its alpha with the true alpha {c[0]:.2f}, with "
            f"the fiber helix angle gamma {c[1]:.2f}, with r_x {c[2]:.2f} (the true alpha's "
            f"with gamma {np.corrcoef(true, -gamma)[0, 1]:.2f}, with r_x "
            f"{np.corrcoef(true, -r_x)[0, 1]:.2f}).")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, help="held-out set (`ipm generate --out`)")
    ap.add_argument("--models", default=None, help="default: the shipped models")
    ap.add_argument("--crops", type=int, default=3)
    ap.add_argument("--blur-mm", type=float, default=0.0, help="sigma of a Gaussian blur of "
                    "every photo, in mm at the yarn")
    ap.add_argument("--view-mm", type=float, nargs=2, default=None, metavar=("W", "H"),
                    help="cut every photo to its central W x H mm first")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    records = read_manifest(args.data)
    ens = Ensemble.load(args.models, setup=records[0].setup if records else None)
    if not 0 <= args.blur_mm <= 1:
        ap.error(f"--blur-mm must be in [0, 1] mm, got {args.blur_mm}")
    photos = [r.photo().defocused(args.blur_mm) for r in records]
    if args.view_mm:
        photos = [central_view(p, *args.view_mm) for p in photos]
    pred = [ens.predict(p, args.crops) for p in photos]
    true = [r.params for r in records]
    pairs = list(zip(pred, true, strict=True))
    base = ens.mean_prediction(records[0].pixel_size_mm)  # a dataset has one scale
    rows = ["| parameter | MAE | % of range | mean signed error, % of range | baseline MAE | "
            "% of range | vs baseline | paper (val.) |", "|---|---|---|---|---|---|---|---|"]
    for k in PARAM_ORDER:
        if k in ("n", "t_x", "t_y"):
            continue
        iv = PAPER_INTERVALS[k]
        span = iv.width
        err = np.array([getattr(p, k) - getattr(t, k) for p, t in pairs])
        mae = float(np.mean(np.abs(err)))
        b = float(np.mean([abs(base[k] - getattr(t, k)) for t in true]))
        name = f"**{k}**" if k in RAW_CONTINUOUS else k
        rows.append(f"| {name} | {mae:.4g} {iv.unit} | {100 * mae / span:.1f} | "
                    f"{100 * err.mean() / span:+.1f} | {b:.4g} | "
                    f"{100 * b / span:.1f} | {100 * (1 - mae / b):+.0f}% | "
                    f"{PAPER_VALIDATION_MAE.get(k, '')} |")
    rows += ["", alpha_signal(pairs), "", coverage(pairs, ens.sigma(records[0].pixel_size_mm))]
    acc_n = np.mean([p.n == t.n for p, t in pairs])
    bias_n = np.mean([p.n - t.n for p, t in pairs])
    acc_t = np.mean([p.thickness == t.thickness for p, t in pairs])
    maj_n = max(np.mean([t.n == c for t in true]) for c in range(2, 7))
    maj_t = max(np.mean([t.thickness == c for t in true]) for c in THICKNESS_CLASSES)
    rows += ["", f"Ply count n: accuracy {100 * acc_n:.1f}% (majority class "
             f"{100 * maj_n:.1f}%), mean signed error {bias_n:+.2f} plies.  Fiber thickness "
             f"class: accuracy {100 * acc_t:.1f}% "
             f"(majority class {100 * maj_t:.1f}%).", "",
             f"{len(records)} images from `{args.data}`"
             + (f", blurred by a Gaussian of sigma {args.blur_mm:g} mm" if args.blur_mm else "")
             + (", cut to their central {:g} x {:g} mm".format(*args.view_mm)
                if args.view_mm else "")
             + f"; models `{ens.folder}`; {args.crops} crops per net.  Bold: the continuous "
             "raw-yarn parameters, which must beat the baseline by at least 40%."]
    command = " ".join(["python -m ipm.benchmarks.nets_accuracy --data", args.data]
                       + (["--models", args.models] if args.models else [])
                       + (["--blur-mm", f"{args.blur_mm:g}"] if args.blur_mm else [])
                       + (["--view-mm", *(f"{v:g}" for v in args.view_mm)]
                          if args.view_mm else [])
                       + (["--out", args.out] if args.out else []))
    text = (markdown_header("Nets accuracy on held-out renders", command, "torch") + "\n"
            + "\n".join(rows) + "\n")
    publish(text, args.out)


if __name__ == "__main__":
    main()
