"""The frontlit nets on cards lighter than any they were trained on: held-out yarns rendered
again in the scene's nominal look with the card's albedo times each ``--gains`` (the
varied look the nets were trained on spans :data:`ipm.render.photometric.LOOK`'s
``backdrop_gain``; a white card is about 30 times the scene's), read by the shipped nets.
What ``ipm fit``'s warning on a light card (:func:`ipm.refine.capture.card_warning`)
stands on.  Each render is read once more with its card darkened back to the scene's
(:func:`darkened`, knowing the factor: an upper bound for a normalisation of the card
before the nets, which ``ipm`` does not do).

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
from ipm.photo import Photo, linear_to_srgb

#: Samples per pixel of the renders: as many as the held-out sets'.
SPP = 16


def darkened(linear: np.ndarray, factor: float) -> np.ndarray:
    """``linear`` (H, W, 3) with its card's light taken down ``factor`` times where the card
    shows: each pixel loses ``(1 - a)`` of the difference, ``a`` the yarn's cover of it, as
    its distance from the card's colour (the median of the top and bottom rows) over the
    core's (the median of the five rows about the row farthest from the card)."""
    h = linear.shape[0]
    edge = max(1, h // 12)
    card = np.median(np.concatenate([linear[:edge], linear[-edge:]]).reshape(-1, 3), axis=0)
    dist = np.abs(linear - card).sum(axis=-1)
    row = int(np.argmax(np.median(dist, axis=1)))
    core = np.median(linear[max(0, row - 2):row + 3].reshape(-1, 3), axis=0)
    cover = np.clip(dist / max(float(np.abs(core - card).sum()), 1e-6), 0, 1)[..., None]
    return np.maximum(linear - (1 - cover) * card * (1 - 1 / factor), 0)


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
    pred: dict[tuple[float, bool], list] = {(g, d): [] for g in gains for d in (False, True)}
    for i, rec in enumerate(records):
        for g in gains:
            linear = renderer.render(rec.params, rec.seed, scale, SPP,
                                     photometric=Photometric(backdrop_gain=g))
            for dark in (False, True):
                img = darkened(linear, g) if dark else linear
                photo = Photo(np.clip(linear_to_srgb(img), 0, 1), rec.pixel_size_mm, "frontlit")
                pred[g, dark].append(ens.predict(photo))
        print(f"{i + 1}/{len(records)}", flush=True)
    true = [r.params for r in records]
    base_mae = baseline_mae(ens, true, records[0].pixel_size_mm, RAW_CONTINUOUS)
    lo, hi = LOOK["backdrop_gain"]
    rows = ["| card albedo (times the scene's) | trained on | card darkened | ply count right | "
            + " | ".join(f"{k} MAE / mean's" for k in RAW_CONTINUOUS) + " |",
            "|---|---|---|---|" + "---|" * len(RAW_CONTINUOUS)]
    data = {}
    for (g, dark), ps in pred.items():
        right = float(np.mean([p.n == t.n for p, t in zip(ps, true, strict=True)]))
        share = {k: v / base_mae[k] for k, v in mae_by_param(ps, true, RAW_CONTINUOUS).items()}
        data[f"{g:g}{' darkened' if dark else ''}"] = {"n_right": right, "mae_over_mean": share}
        rows.append(f"| {g:g} | {'yes' if lo <= g <= hi else 'no'} | "
                    f"{'yes' if dark else 'no'} | {100 * right:.0f}% | "
                    + " | ".join(f"{v:.2f}" for v in share.values()) + " |")
    command = (f"python -m ipm.benchmarks.card_sweep --data {args.data} --count {args.count}"
               + (f" --gains {args.gains}" if args.gains != "1,3,10,30" else "")
               + (f" --out {args.out}" if args.out else ""))
    text = (markdown_header("The frontlit nets on lighter cards", command, "torch", "mitsuba")
            + f"\n{len(records)} yarns of `{args.data}` rendered again in the scene's nominal "
            f"look, {SPP} spp, the card's albedo ({renderer.options.backdrop:g}) times each "
            f"factor (at most 1); the nets' varied look spans {lo:g}-{hi:g} times.  MAE over "
            "the predict-the-mean baseline's on the same yarns; darkened: the card's light taken "
            "back to the scene's where the yarn does not cover it (`darkened`), knowing the "
            "factor.\n\n" + "\n".join(rows) + "\n")
    publish(text, args.out, data)


if __name__ == "__main__":
    main()
