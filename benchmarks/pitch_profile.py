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
        --fits /tmp/real-photos/fits.jsonl --out benchmarks/results/pitch_profile_real.md

On a labelled set (``--data``, an ``ipm generate`` dataset or a Cycles test set, whose
truth is known) the sweep starts where ``ipm fit`` starts: the nets' guess of each photo,
colour-matched; ``alpha_ply`` is swept over the box the default search sees
(:func:`ipm.refine.search.search_box` with the nets' sigma) and the search's MAP objective
(:mod:`ipm.refine.search`: the loss in units of its seed noise at the start, plus the nets'
prior) is minimised over the grid for each weighting of :func:`weightings`.  The report
gives each weighting's MAE of ``alpha_ply`` against the nets'.  The per-group curves are
written to the JSON beside the report, so another weighting is a sum, not a render.

    python -m ipm.benchmarks.pitch_profile --data data-frontlit/val --count 30 \\
        --out benchmarks/results/pitch_profile_frontlit_val.md
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
    from ipm.refine.fit import search_objective
    from ipm.refine.plan import FitConfig, plan
    from ipm.refine.stats import weighted_sum

    options = FitConfig()
    photo = Record(photo_file, pixel_size_mm, setup="backlit").photo()
    objective, _ = search_objective(photo, renderer, options)
    stage = objective.stage_weights(plan(options, photo.setup).stages[-1])  # the ply twist
    params = YarnParams.from_dict(row["refined"])
    curves: dict[str, list[float]] = {g: [] for g in (*GROUPS, STAGE)}
    for period in PERIODS_MM:
        d = objective.group_distances(params.replace(alpha_ply=period * params.n),
                                      options.fiber_seed)
        for g in GROUPS:
            curves[g].append(d[g])
        curves[STAGE].append(float(weighted_sum(d, stage)))
    return {g: float(PERIODS_MM[int(np.argmin(c))]) for g, c in curves.items()}


#: Points of the labelled sweep across the search's box of ``alpha_ply``.
GRID = 25


def weightings() -> dict[str, dict[str, float]]:
    """The group weightings compared on labelled sets: every group of the loss
    (:data:`ipm.refine.objective.DEFAULT_WEIGHTS`, which scored a search of the pitch alone
    until :attr:`ipm.setups.CaptureSetup.pitch_groups`), and the groups that see the pitch,
    alone and together, at their default weights."""
    from ipm.refine.objective import DEFAULT_WEIGHTS as w

    def only(*groups: str) -> dict[str, float]:
        return {g: w[g] for g in groups}

    return {"every group of the loss": {g: v for g, v in w.items() if v},
            "period, stripes, contour": only("period", "stripes", "contour"),
            "period, stripes, silhouette": only("period", "stripes", "silhouette"),
            "period, stripes": only("period", "stripes"),
            **{f"{g} alone": only(g) for g in ("core", "period", "stripes", "silhouette",
                                                "contour")}}


def labelled_sweep(record, ensemble, renderer, options) -> dict:
    """The nets' guess of ``record``'s photo and each group's distance to the photo over a
    grid of ``alpha_ply`` in the default search's box (at the search's fiber seed), and at
    the guess over every seed of the search (its seed noise)."""
    from ipm.refine.fit import search_objective
    from ipm.refine.measure import match_colour
    from ipm.refine.search import search_box

    photo = record.photo()
    sigma = ensemble.sigma(photo.pixel_size_mm)
    objective, small = search_objective(photo, renderer, options)
    neural = match_colour(objective, ensemble.predict(photo), small)
    search = options
    lo, hi = search_box(neural, ("alpha_ply",), search.width, sigma, search.box_sigmas)
    values = np.linspace(lo[0], hi[0], GRID)
    along = [objective.group_distances(neural.replace(alpha_ply=float(v)), search.fiber_seed)
             for v in values]
    start = [objective.group_distances(neural, s)
             for s in (search.fiber_seed, *search.rescore_seeds)]
    return {"image": str(record.image), "truth": record.params.alpha_ply,
            "n_truth": record.params.n, "n": neural.n, "neural": neural.alpha_ply,
            "sigma": sigma["alpha_ply"], "prior_weight": search.prior_weight,
            "values": values.tolist(),
            "curves": {g: [d[g] for d in along] for g in along[0]},
            "start": {g: [d[g] for d in start] for g in start[0]}}


def map_pitch(row: dict, weights: dict[str, float], prior: bool = True) -> float:
    """The ``alpha_ply`` of ``row``'s grid (:func:`labelled_sweep`) where the search's
    objective with group ``weights`` is lowest: the weighted loss in units of its seed
    noise at the nets' guess plus the nets' prior (:func:`ipm.refine.search.search`), or
    the weighted loss alone without ``prior``."""
    from ipm.refine.search import seed_noise

    def total(curves: dict[str, list[float]]) -> np.ndarray:
        return sum(w * np.asarray(curves[g]) for g, w in weights.items())

    loss, noise = total(row["curves"]), seed_noise(total(row["start"]))
    values = np.asarray(row["values"])
    z = (values - row["neural"]) / row["sigma"]
    objective = loss / noise + (row["prior_weight"] * 0.5 * z ** 2 if prior else 0.0)
    return float(values[int(np.argmin(objective))])


def labelled_report(rows: list[dict], data: Path) -> str:
    """Per weighting, with and without the nets' prior: the MAE of the grid's best
    ``alpha_ply`` against the nets' guess, and on how many photos it is nearer the truth."""
    truth = np.array([r["truth"] for r in rows])
    neural = np.abs(np.array([r["neural"] for r in rows]) - truth)
    lines = [f"{len(rows)} photos of `{data}`, each swept from the nets' guess over {GRID} "
             "values of `alpha_ply` spanning the default search's box, the other parameters "
             "kept at the nets' (the ply count right on "
             f"{sum(r['n'] == r['n_truth'] for r in rows)}).  "
             f"The nets' MAE of `alpha_ply`: **{neural.mean():.3f} mm**.", "",
             "| groups | MAE with the nets' prior (mm) | change | nearer the truth | "
             "MAE of the loss alone (mm) | change |", "|---|---|---|---|---|---|"]
    for name, weights in weightings().items():
        cells = [name]
        for prior in (True, False):
            err = np.abs(np.array([map_pitch(r, weights, prior) for r in rows]) - truth)
            cells += [f"{err.mean():.3f}", f"{100 * (err.mean() / neural.mean() - 1):+.0f}%"]
            if prior:
                cells.append(f"{int((err < neural).sum())} of {len(rows)}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def labelled_main(args: argparse.Namespace) -> None:
    from ipm.dataset import MANIFEST
    from ipm.nets.ensemble import Ensemble
    from ipm.refine.compare import photos_in
    from ipm.refine.plan import FitConfig
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options
    from ipm.setups import setup_of

    if not (Path(args.data) / MANIFEST).is_file():
        raise SystemExit(f"{args.data} has no labels (a manifest.jsonl with parameters)")
    records = photos_in(args.data, None, args.count)
    if records[0].params is None:
        raise SystemExit(f"{args.data} has no labels (a manifest.jsonl with parameters)")
    setup = records[0].setup
    ensemble = Ensemble.load(None, setup=setup)
    renderer = Renderer(options=setup_options(setup))
    rows = []
    for i, record in enumerate(records):
        rows.append(labelled_sweep(record, ensemble, renderer, FitConfig()))
        print(f"{i + 1}/{len(records)} {record.image.name}: truth {rows[-1]['truth']:.2f}, "
              f"nets {rows[-1]['neural']:.2f} mm", flush=True)
    head = markdown_header("Where the refine loss puts the ply pitch, from the nets' guess",
                           "python -m ipm.benchmarks.pitch_profile " + " ".join(sys.argv[1:]),
                           "mitsuba", "torch", "kornia")
    groups = ", ".join(setup_of(setup).pitch_groups)
    note = (f"The search of `alpha_ply` alone is scored by {groups} "
            f"in the {setup} setup (`ipm.setups`).")
    publish(head + "\n" + labelled_report(rows, args.data) + "\n\n" + note + "\n", args.out,
            rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--photos", type=Path, help="a folder of real photos (with --fits)")
    ap.add_argument("--pixel-size", type=float, help="mm per photo pixel of --photos")
    ap.add_argument("--fits", type=Path, help="fits.jsonl of a real_photos run")
    ap.add_argument("--data", type=Path, help="a labelled set instead: swept from the nets' "
                    "guess of each photo, scored against its truth")
    ap.add_argument("--count", type=int, default=None, help="the first N fits only")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    if args.data:
        return labelled_main(args)
    if not (args.photos and args.pixel_size and args.fits):
        ap.error("give --data, or --photos, --pixel-size and --fits")

    from ipm.benchmarks.real_photos import measures
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options
    from ipm.textile.image import gray

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
