"""Fits of real backlit photos, judged by image analysis that uses no net
(:mod:`ipm.benchmarks.photo_measures`): each photo is fitted as ``ipm fit --refine --setup
backlit`` does, the fitted yarn is rendered over the photo's own field of view, and the
photo and its render are measured alike.

* Core diameter: the photo's half-contrast width against the render's (relative difference).
* Ply-stripe period: the photo's (autocorrelation along the axis) against the fit's
  ``alpha_ply / n``, the distance between neighbouring plies' crossings.
* Ply count: the fit's ``n`` on the photos whose README calls them 2-ply.
* Hairiness: fibers per mm of yarn that reach :data:`HAIR_SHOWN` mm beyond the core's edge
  (:func:`ipm.textile.image.hairiness`), the render's over the photo's.
* Textile measures (``ipm measure``, :mod:`ipm.textile`): Uster-type H and the Zweigle-type
  counts of the photo against its render's and the fitted fibers' (Spearman across the
  photos, median ratio), the diameter's CV along the yarn and the twist direction read on
  the photo.

Writes the summary page (the table and the medians) to ``--out``
(``benchmarks/results/real_photos.md``), and the heavy outputs to the folder ``--work``,
outside the repository: ``fits.jsonl`` (resumable, as ``ipm compare``; ``settings.json``
holds the run's flags, and a folder of other flags is refused rather than resumed),
``renders/``, ``measures.json`` and ``contact_sheet.png`` (photo | refined render, every
photo).  The renders are in the photo's capture (its panel level and defocus,
:func:`ipm.refine.capture.matched_capture`, recorded in ``captures.json``), as ``ipm fit``
shows them, and measured so.  A change of the code is not seen: refit into a new ``--work``
folder after one.

    python -m ipm.benchmarks.real_photos --photos ../shared/real-yarns --pixel-size 0.0021 \\
        --work /tmp/real-photos
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from ipm.benchmarks.machine import markdown_header, publish
from ipm.dataset import Record, photo_files
from ipm.frame import PIXEL_SIZE_MM
from ipm.photo import write_png
from ipm.refine.capture import in_capture, matched_capture
from ipm.textile.image import gray, hairiness, measure_image, measure_photo

#: Where the summary page goes by default (the heavy outputs go to ``--work``).
PAGE = Path(__file__).parent / "results" / "real_photos.md"

#: The photos in the contact sheet are the Minho dataset's (``../shared/real-yarns``).
ATTRIBUTION = ("The photos: \"Yarn hairiness - loop & protruding fibers dataset\", University "
               "of Minho (F. Pereira et al.), CC BY 4.0.")
#: The renders are measured at this pitch (mm per pixel): fine enough for a 0.3 mm core.
MEASURE_PITCH_MM = 0.01
MEASURE_SPP = 16
#: The distances beyond the core's edge (mm) whose hairiness the report shows.
HAIR_SHOWN = (0.1, 0.2)


def readme_ply_counts(folder: Path) -> dict[str, int]:
    """Ply counts the photos' README states ("2-ply spun yarn" in a file's row)."""
    readme = folder / "README.md"
    if not readme.is_file():
        return {}
    counts = {}
    for line in readme.read_text(encoding="utf-8").splitlines():
        m = re.match(r"\|\s*(\S+\.png)\s*\|.*\|\s*(?:thinner )?(\d)-ply spun yarn", line)
        if m:
            counts[m.group(1)] = int(m.group(2))
    return counts


def measures(image: np.ndarray, pixel_size_mm: float) -> tuple[float, float]:
    """(core diameter, stripe period) in mm of a grey backlit image in [0, 1]."""
    m = measure_image(image, backlit=True)
    return m["core_diameter_px"] * pixel_size_mm, m["stripe_period_px"] * pixel_size_mm


def render_over(renderer, params, photo_shape: tuple[int, int], pixel_size_mm: float,
                tilt_deg: float, seed: int) -> np.ndarray:
    """The yarn ``params`` rendered backlit over the photo's field of view at
    :data:`MEASURE_PITCH_MM`, tilted as the photo's yarn, in the scene's own capture: linear
    (H, W, 3)."""
    from ipm.render.photometric import Photometric
    from ipm.render.scene import Frame

    h, w = (round(n * pixel_size_mm / MEASURE_PITCH_MM) for n in photo_shape)
    return renderer.render(params, seed, PIXEL_SIZE_MM / MEASURE_PITCH_MM, MEASURE_SPP,
                           photometric=Photometric(rotation_deg=tilt_deg),
                           frame=Frame(w, h, MEASURE_PITCH_MM))


def resized(image: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """A grey image in [0, 1] resampled (Lanczos) to ``shape`` (H, W)."""
    im = Image.fromarray((image * 255).round().astype(np.uint8))
    return np.asarray(im.resize(shape[::-1], Image.Resampling.LANCZOS)) / 255.0


def textile_summary(table: list[dict]) -> list[str]:
    """The textile measures (``ipm measure``) of the photos against their fits': Spearman
    across the photos and the median ratio of the render's and of the fibers' over the
    photo's, for H and the Zweigle-type counts; the photos' diameter CV and directions."""
    from scipy.stats import spearmanr

    lines = ["Textile measures (`ipm measure`, docs/measure.md), the photo's against the fit's "
             "render in the photo's capture (measured alike) and against the fitted fibers':", "",
             "| measure | Spearman, render | median render / photo | Spearman, fibers | "
             "median fibers / photo |", "|---|---|---|---|---|"]

    def pick(t, source, key):
        d = t["textile"][source]
        v = d["hairs_per_100m"].get(key) if key != "H" else d["hairiness_h"]
        return float("nan") if v is None else float(v)

    for key, name in (("H", "hairiness H"), ("0.1", "hairs per 100 m at 0.1 mm"),
                      ("0.2", "hairs per 100 m at 0.2 mm"), ("0.5", "hairs per 100 m at 0.5 mm")):
        photo = np.array([pick(t, "photo", key) for t in table])
        cells = []
        for source in ("render", "fibers"):
            other = np.array([pick(t, source, key) for t in table])
            ok = np.isfinite(photo) & np.isfinite(other) & (photo > 0)
            rho = spearmanr(photo[ok], other[ok]).statistic if ok.sum() > 2 else float("nan")
            cells += [f"{rho:.2f}", f"{np.median(other[ok] / photo[ok]):.2f}"]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    cv = [t["textile"]["photo"]["diameter_cv_pct"] for t in table]
    directions = [t["textile"]["photo"]["twist_direction"] or "none" for t in table]
    lines += ["", f"Diameter CV along the yarn (0.3 mm windows), the photos': median "
              f"{np.nanmedian(cv):.1f}% (range {np.nanmin(cv):.1f}-{np.nanmax(cv):.1f}%). "
              "Twist direction read on the photos: " + ", ".join(
                  f"{d} {directions.count(d)}" for d in ("S", "Z", "none")) + "."]
    return lines


def relative(a: float, b: float) -> float:
    return abs(a - b) / b if b > 0 and np.isfinite(a) and np.isfinite(b) else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--photos", type=Path, required=True)
    ap.add_argument("--pixel-size", type=float, required=True, help="mm per photo pixel")
    ap.add_argument("--out", type=Path, default=PAGE, help="the summary page (markdown)")
    ap.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "ipm-real-photos",
                    help="folder for the fits, renders and contact sheet (resumable; keep it "
                    "outside the repository)")
    ap.add_argument("--models", type=Path, default=None, help="default: the shipped backlit")
    ap.add_argument("--budget", type=int, default=None, help="evaluations per search")
    ap.add_argument("--params", default=None, help="the searched parameters and stages, as "
                    "`ipm fit --params` (default: its default)")
    ap.add_argument("--polish", type=int, default=0, help="evaluations of the local polish "
                    "of each stage of two or more parameters, as `ipm fit --polish`")
    ap.add_argument("--ply-counts", type=int, default=1, help="search with each of the nets' "
                    "most likely ply counts, as `ipm fit --ply-counts`")
    ap.add_argument("--no-prior", action="store_true", help="the image loss alone, as `ipm "
                    "fit --no-prior`: for yarns outside the nets' training range")
    ap.add_argument("--match-size", action="store_true", help="start from the nets' yarn "
                    "scaled to the photo's core width, as `ipm fit --match-size`")
    args = ap.parse_args()

    from ipm.errors import UserError
    from ipm.generator import generate
    from ipm.io import check_same_settings, write_text
    from ipm.nets.ensemble import Ensemble
    from ipm.params import YarnParams
    from ipm.refine.compare import fit_all
    from ipm.refine.plan import FitConfig
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options
    from ipm.textile.fibers import fiber_measures

    files = photo_files(args.photos)
    records = [Record(f, args.pixel_size, setup="backlit") for f in files]
    ensemble = Ensemble.load(args.models, setup="backlit")
    options = FitConfig(params=args.params, polish=args.polish, ply_counts=args.ply_counts,
                        match_size=args.match_size, prior=not args.no_prior,
                        **({} if args.budget is None else {"budget": args.budget}))
    args.work.mkdir(parents=True, exist_ok=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    settings = {"photos": str(args.photos), "pixel_size_mm": args.pixel_size,
                "models": str(args.models or "shipped"), "budget": args.budget,
                "params": args.params, "polish": args.polish, "ply_counts": args.ply_counts,
                "prior": not args.no_prior, "match_size": args.match_size}
    try:  # before resuming the fits in the folder
        check_same_settings(args.work / "settings.json", settings, "fits")
    except UserError as e:
        raise SystemExit(f"error: {e}") from None
    write_text(args.work / "settings.json", json.dumps(settings, indent=2) + "\n")
    rows = fit_all(args.work / "fits.jsonl", records, lambda i, photo: ensemble.predict(photo),
                   options, None if args.no_prior else (
                       lambda photo: ensemble.sigma(photo.pixel_size_mm)),
                   progress=lambda done, total: print(f"fits {done}/{total}", flush=True),
                   count_prior_of=ensemble.ply_count_probabilities)
    plies = readme_ply_counts(args.photos)
    renderer = Renderer(options=setup_options("backlit"))
    (args.work / "renders").mkdir(exist_ok=True)
    captures_file = args.work / "captures.json"
    captures = json.loads(captures_file.read_text()) if captures_file.is_file() else {}
    table, panels = [], []
    for f, row in zip(files, rows, strict=True):
        photo = gray(str(f))
        target = args.work / "renders" / f.name
        if not target.is_file() or f.name not in captures:
            refined = YarnParams.from_dict(row["refined"])
            linear = render_over(renderer, refined, photo.shape, args.pixel_size,
                                 row.get("tilt_deg", 0.0), options.fiber_seed)
            capture = matched_capture(resized(photo, linear.shape[:2]), linear,
                                      MEASURE_PITCH_MM, renderer.options.setup)
            write_png(target, in_capture(linear, capture, MEASURE_PITCH_MM))
            captures[f.name] = {"exposure_stops": capture.exposure_stops,
                                "blur_mm": capture.blur_mm}
            write_text(args.work / "captures.json", json.dumps(captures, indent=2) + "\n")
        render = gray(str(target))
        d_photo, period_photo = measures(photo, args.pixel_size)
        d_render, _ = measures(render, MEASURE_PITCH_MM)
        fit = row["refined"]
        hairs_photo = hairiness(photo, args.pixel_size)
        hairs_render = hairiness(render, MEASURE_PITCH_MM)
        refined = YarnParams.from_dict(fit)
        textile_photo = measure_photo(photo, args.pixel_size, True, refined.n).brief()
        textile_render = measure_photo(render, MEASURE_PITCH_MM, True, refined.n).brief()
        textile_fibers = fiber_measures(refined, generate(refined, options.fiber_seed))
        table.append({"photo": f.name, "n_neural": row["neural"]["n"], "n": fit["n"],
                      "textile": {"photo": textile_photo, "render": textile_render,
                                  "fibers": textile_fibers},
                      "plies_readme": plies.get(f.name), "core_photo": d_photo,
                      "core_render": d_render, "core_rel": relative(d_render, d_photo),
                      "period_photo": period_photo, "period_fit": fit["alpha_ply"] / fit["n"],
                      "period_rel": relative(fit["alpha_ply"] / fit["n"], period_photo),
                      "R_ply": fit["R_ply"], "alpha_ply": fit["alpha_ply"],
                      "hairs_photo": [hairs_photo[d] for d in HAIR_SHOWN],
                      "hairs_render": [hairs_render[d] for d in HAIR_SHOWN]})
        panels.append(np.hstack([resized(photo, render.shape), np.ones((render.shape[0], 4)),
                                 render]))
    pairs = [np.hstack([a, np.ones((a.shape[0], 12)), b]) for a, b in
             zip(panels[::2], panels[1::2] + [np.ones_like(panels[0])] * (len(panels) % 2),
                 strict=False)]
    sheet = np.vstack([np.vstack([p, np.ones((8, p.shape[1]))]) for p in pairs])
    write_png(args.work / "contact_sheet.png", np.repeat(sheet[..., None], 3, axis=2))

    two = [t for t in table if t["plies_readme"] is not None]
    core = np.nanmedian([t["core_rel"] for t in table])
    period = np.nanmedian([t["period_rel"] for t in table])
    right = sum(t["n"] == t["plies_readme"] for t in two)
    hair_ratio = [np.nanmedian([t["hairs_render"][i] / t["hairs_photo"][i] for t in table
                                if t["hairs_photo"][i] > 0]) for i in range(len(HAIR_SHOWN))]
    command = "python -m ipm.benchmarks.real_photos " + " ".join(
        f"'{a}'" if ";" in a else a for a in sys.argv[1:])
    lines = [markdown_header("Fits of real backlit photos, measured without the nets", command,
                             "numpy", "torch", "mitsuba"),
             ATTRIBUTION, "",
             f"{len(table)} photos at {args.pixel_size:g} mm per pixel "
             f"([how it was estimated](real_pixel_size.md)); nets `{ensemble.folder}`.", "",
             f"- Core diameter, render against photo: median relative difference "
             f"**{100 * core:.0f}%** (target under 10%).",
             f"- Ply-stripe period, the fit's alpha_ply / n against the photo's: median "
             f"relative difference **{100 * period:.0f}%** (target under 15%).",
             f"- Ply count on the {len(two)} photos the README calls "
             f"{'/'.join(sorted({str(t['plies_readme']) for t in two}))}-ply: right on "
             f"**{right} of {len(two)}** (target 10 of 12).",
             "- Hairiness, fibers per mm reaching " + ", ".join(
                 f"{d:g} mm" for d in HAIR_SHOWN) + " beyond the core's edge: the render's "
             "over the photo's, median " + ", ".join(f"**{r:.2f}**" for r in hair_ratio)
             + " (1: as hairy as the photo).",
             "- The renders in each photo's capture (`captures.json`): defocus, median "
             f"{np.median([c['blur_mm'] for c in captures.values()]):.4f} mm (Gaussian sigma "
             "at the yarn); panel level, median "
             f"{np.median([c['exposure_stops'] for c in captures.values()]):+.2f} stops from "
             "the scene's.", "",
             f"Photo | refined render, every photo: `{args.work / 'contact_sheet.png'}`.", "",
             *textile_summary(table), "",
             "| photo | n (nets) | n (fit) | README | core photo (mm) | core render (mm) | "
             "diff | period photo (mm) | alpha_ply / n (mm) | diff | "
             f"hairs/mm at {' / '.join(f'{d:g}' for d in HAIR_SHOWN)} mm, photo | render |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for t in table:
        lines.append(f"| {t['photo']} | {t['n_neural']} | {t['n']} | "
                     f"{t['plies_readme'] or ''} | {t['core_photo']:.3f} | "
                     f"{t['core_render']:.3f} | {100 * t['core_rel']:.0f}% | "
                     f"{t['period_photo']:.3f} | {t['period_fit']:.3f} | "
                     f"{100 * t['period_rel']:.0f}% | "
                     + " / ".join(f"{h:.1f}" for h in t["hairs_photo"]) + " | "
                     + " / ".join(f"{h:.1f}" for h in t["hairs_render"]) + " |")
    publish("\n".join(lines) + "\n", str(args.out))
    (args.work / "measures.json").write_text(json.dumps(table, indent=2) + "\n")


if __name__ == "__main__":
    main()
