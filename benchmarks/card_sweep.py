"""The frontlit nets on cards lighter than any they were trained on: held-out yarns rendered
again in the scene's nominal look with the card's albedo times each ``--gains`` (the
varied look the nets were trained on spans :data:`ipm.render.photometric.LOOK`'s
``backdrop_gain``; a white card is about 30 times the scene's), read by the shipped nets.
What ``ipm fit``'s warning on a light card (:func:`ipm.refine.capture.card_warning`)
stands on.  Each render is read three ways: its card as it shows, its card brought to the
scene's as the nets read every photo (:meth:`ipm.photo.Photo.scene_view`, the card's
level estimated from the photo), and its card darkened knowing the factor
(:func:`ipm.photo.recarded`: an upper bound for that estimate).

    python -m ipm.benchmarks.card_sweep --data data/test --count 30 \\
        --out benchmarks/results/card_sweep.md
"""

from __future__ import annotations

import argparse

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish
from ipm.benchmarks.nets_accuracy import baseline_mae, mae_by_param
from ipm.dataset import read_manifest
from ipm.frame import PIXEL_SIZE_MM
from ipm.params import RAW_CONTINUOUS
from ipm.photo import Photo, linear_to_srgb, recarded

#: Samples per pixel of the renders: as many as the held-out sets'.
SPP = 16
#: How the nets read each render's card: as it shows, brought to the scene's card by the
#: photo's own estimate (what ``ipm`` does), or darkened knowing the factor.
WAYS = ("as shown", "estimated", "known factor")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, help="a labelled frontlit set (ipm generate)")
    ap.add_argument("--count", type=int, default=30)
    ap.add_argument("--gains", default="1,3,10,30", help="card albedo factors, comma-separated")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()

    from ipm.nets.ensemble import Ensemble
    from ipm.render.photometric import LOOK, Photometric
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options

    gains = [float(g) for g in args.gains.split(",")]
    records = read_manifest(args.data)[:args.count]
    if records[0].setup != "frontlit":
        raise SystemExit(f"{args.data} is a {records[0].setup} set; the card is frontlit's")
    ens = Ensemble.load(None, setup="frontlit")
    renderer = Renderer(options=setup_options("frontlit"))
    scale = PIXEL_SIZE_MM / records[0].pixel_size_mm
    pred: dict[tuple[float, str], list] = {(g, w): [] for g in gains for w in WAYS}
    for i, rec in enumerate(records):
        for g in gains:
            linear = renderer.render(rec.params, rec.seed, scale, SPP,
                                     photometric=Photometric(backdrop_gain=g))
            for way in WAYS:
                img = recarded(linear, g) if way == "known factor" else linear
                photo = Photo(np.clip(linear_to_srgb(img), 0, 1), rec.pixel_size_mm, "frontlit")
                ens.card_normalised = way == "estimated"
                pred[g, way].append(ens.predict(photo))
        print(f"{i + 1}/{len(records)}", flush=True)
    true = [r.params for r in records]
    base_mae = baseline_mae(ens, true, records[0].pixel_size_mm, RAW_CONTINUOUS)
    lo, hi = LOOK["backdrop_gain"]
    rows = ["| card albedo (times the scene's) | trained on | card read | ply count right | "
            + " | ".join(f"{k} MAE / mean's" for k in RAW_CONTINUOUS) + " |",
            "|---|---|---|---|" + "---|" * len(RAW_CONTINUOUS)]
    data = {}
    for (g, way), ps in pred.items():
        right = float(np.mean([p.n == t.n for p, t in zip(ps, true, strict=True)]))
        share = {k: v / base_mae[k] for k, v in mae_by_param(ps, true, RAW_CONTINUOUS).items()}
        data[f"{g:g} {way}"] = {"n_right": right, "mae_over_mean": share}
        rows.append(f"| {g:g} | {'yes' if lo <= g <= hi else 'no'} | {way} | "
                    f"{100 * right:.0f}% | " + " | ".join(f"{v:.2f}" for v in share.values())
                    + " |")
    command = (f"python -m ipm.benchmarks.card_sweep --data {args.data} --count {args.count}"
               + (f" --gains {args.gains}" if args.gains != "1,3,10,30" else "")
               + (f" --out {args.out}" if args.out else ""))
    text = (markdown_header("The frontlit nets on lighter cards", command, "torch", "mitsuba")
            + f"\n{len(records)} yarns of `{args.data}` rendered again in the scene's nominal "
            f"look, {SPP} spp, the card's albedo ({renderer.options.backdrop:g}) times each "
            f"factor (at most 1); the nets' varied look spans {lo:g}-{hi:g} times.  MAE over "
            "the predict-the-mean baseline's on the same yarns.  Card read: as shown; estimated: "
            "brought to the scene's card by the photo's own estimate of its level, as `ipm` "
            "reads every frontlit photo (`Photo.scene_view`); known factor: darkened back "
            "knowing the factor (`recarded`).\n\n" + "\n".join(rows) + "\n")
    publish(text, args.out, data)


if __name__ == "__main__":
    main()
