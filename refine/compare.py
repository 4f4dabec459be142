"""``ipm compare``: neural-only against refined reconstructions over many photos.

The photos are a folder of images, or a dataset made with ``ipm generate`` (its
``manifest.jsonl`` gives each image's pixel size and true parameters, so the report also
gives the errors of both reconstructions against the labels).  Each photo is fitted with
:func:`ipm.refine.fit.fit` as ``ipm fit --refine`` does; one JSON line per photo is appended
to ``fits.jsonl`` as it finishes, so a stopped run resumes where it stopped (``ipm bench``
uses the same loop).  The report: ``results.csv`` (a row per photo), ``index.md`` (the
summary and the table) and ``compare.png`` (photo | neural | refined for a few photos).
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ipm.dataset import MANIFEST, PHOTO_SUFFIXES, Record, photo_files, read_manifest
from ipm.errors import UserError
from ipm.io import content_hash, write_text
from ipm.params import PAPER_INTERVALS, RAW_CONTINUOUS, YarnParams
from ipm.photo import Photo, pixel_size_of
from ipm.refine.search import LEVEL
from ipm.setups import DEFAULT_SETUP

FITS = "fits.jsonl"


@dataclass(frozen=True)
class PhotoPrep:
    """What is done to every photo before it is fitted: ``invert`` (negatives) and
    ``blur_mm``, a Gaussian blur of that sigma at the yarn (in linear light), to measure the
    fit on photos less sharp than renders."""

    invert: bool = False
    blur_mm: float = 0.0

    def __post_init__(self) -> None:
        if not 0 <= self.blur_mm <= 1:
            raise UserError(f"blur must be in [0, 1] mm, got {self.blur_mm}")

    def load(self, record: Record) -> Photo:
        if "error" in record.info:  # found when listed (its pixel size): said per photo
            raise UserError(record.info["error"])
        photo = record.photo().defocused(self.blur_mm)
        return photo.inverted() if self.invert else photo


def photos_in(folder: Path, pixel_size_mm: float | None, count: int | None = None,
              setup: str | None = None, calibration: Path | None = None) -> list[Record]:
    """The photos of ``folder`` sorted by name: a dataset's (with labels, pixel sizes and
    capture setup) if it holds a manifest, else every image file (of capture ``setup``,
    :data:`ipm.setups.DEFAULT_SETUP` if None) at its pixel size (``pixel_size_mm``,
    ``calibration`` or its sidecar: :func:`ipm.photo.pixel_size_of`; a photo without one, or
    gone, gets an ``error`` in its record's ``info``, reported in its row; if none has one,
    that is refused).  They must all be of one setup (``setup``, if given), since one
    ensemble and one scene fit them."""
    folder = Path(folder)
    if not folder.is_dir():
        raise UserError(f"{folder} is not a folder of photos")
    if (folder / MANIFEST).is_file():
        photos = read_manifest(folder)
    else:
        photos, errors = [], []
        for p in photo_files(folder):
            try:
                photos.append(Record(p, pixel_size_of(p, pixel_size_mm, calibration),
                                     setup=setup or DEFAULT_SETUP))
            except UserError as e:  # this photo's: reported in its row, the others go on
                errors.append(e)
                photos.append(Record(p, float("nan"), setup=setup or DEFAULT_SETUP,
                                     info={"error": str(e)}))
        if photos and len(errors) == len(photos):
            raise errors[0]  # (none has a pixel size: say it once)
    if not photos:
        raise UserError(f"{folder} holds no photos ({', '.join(PHOTO_SUFFIXES)})")
    setups = sorted({p.setup for p in photos} | ({setup} if setup else set()))
    if len(setups) > 1:
        raise UserError(f"{folder} holds photos of {' and '.join(setups)} setups"
                        + (f" (--setup {setup})" if setup else "") + "; compare one at a time")
    photos.sort(key=lambda p: str(p.image))
    return photos[:count] if count else photos


def fit_row(record: Record, photo: Photo, neural: YarnParams, renderer, config,
            sigma: dict[str, float] | None, count_prior: dict[int, float] | None = None,
            readings=None, detail=None) -> dict:
    """``ipm fit --refine`` on one photo, as one JSON-ready row."""
    from ipm.refine.fit import fit

    res = fit(photo, neural, renderer, config, sigma=sigma, readings=readings, detail=detail,
              count_prior=count_prior)
    return {"image": str(record.image), "neural": res.neural.to_dict(),
            "refined": res.refined.to_dict(), "loss_neural": res.loss_neural,
            "loss_refined": res.loss_refined, "improved": bool(res.improved),
            "tilt_deg": res.tilt_deg, "warnings": res.warnings,
            "trace": res.search.trace if res.search else [], "seconds": res.seconds,
            "intervals": {k: list(v) for k, v in res.intervals().items()},
            "ply_count_scores": {str(n): v for n, v in res.count_scores.items()},
            "prior": res.sigma is not None}


def fit_all(path: Path, photos: Sequence[Record], neural_of: Callable[[int, Photo],
            YarnParams], config, sigma_of: Callable[[Photo], dict[str, float]] | None,
            prep: PhotoPrep = PhotoPrep(),
            progress: Callable[[int, int], None] | None = None,
            count_prior_of: Callable[[Photo], dict[int, float]] | None = None,
            readings=None, detail_of: Callable[[Photo], tuple | None] | None = None
            ) -> list[dict]:
    """Fit every photo (all of one capture setup), resuming from the rows already in the
    JSON-lines file ``path``.

    ``neural_of(i, photo)`` gives the nets' parameters of photo ``i``, ``sigma_of`` their
    error per parameter at the photo's pixel size (the search's prior; None: without one),
    ``count_prior_of``
    the nets' probability of each ply count (default: none, the nets' count), ``readings``
    the nets' readings for the loss and ``detail_of`` the detail nets' for a photo
    (:func:`ipm.refine.fit.fit`).  A row is appended
    (and flushed) as each fit ends; a photo that cannot be read or used gets a row with its
    ``error`` instead, and the others go on.  Each row records the photo's content hash
    (:func:`content_hash`): a row is resumed only for a photo of the same name and content,
    so a replaced photo, or one that could not be read and was fixed, is fitted again.  A
    line torn by a kill is dropped and its photo fitted again."""
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options

    hashes = [content_hash(p.image) for p in photos]
    kept: dict[tuple[str, str], dict] = {}
    for line in path.read_text(encoding="utf-8").splitlines() if path.is_file() else []:
        try:
            row = json.loads(line)
        except json.JSONDecodeError:
            break
        if isinstance(row, dict) and row.get("sha256"):
            kept[(str(row.get("image")), row["sha256"])] = row
    done: list[dict | None] = [kept.get((str(p.image), h)) if h else None
                               for p, h in zip(photos, hashes, strict=True)]
    write_text(path, "".join(json.dumps(r) + "\n" for r in done if r is not None))
    count = sum(r is not None for r in done)
    if progress:
        progress(count, len(photos))
    renderer = None
    with open(path, "a", encoding="utf-8") as f:
        for i in (i for i, r in enumerate(done) if r is None):
            try:
                photo = prep.load(photos[i])
                neural = neural_of(i, photo)
            except UserError as e:  # an unreadable or unusable photo: say so, go on
                row = {"image": str(photos[i].image), "error": str(e)}
            else:
                renderer = renderer or Renderer(options=setup_options(photo.setup))
                row = fit_row(photos[i], photo, neural, renderer, config,
                              sigma_of(photo) if sigma_of else None,
                              count_prior_of(photo) if count_prior_of else None, readings,
                              detail_of(photo) if detail_of else None)
            row["sha256"] = hashes[i]
            f.write(json.dumps(row) + "\n")
            f.flush()
            done[i] = row
            count += 1
            if progress:
                progress(count, len(photos))
    return done


def summary(rows: list[dict], truth: Sequence[YarnParams | None],
            params: Sequence[str] = RAW_CONTINUOUS) -> dict:
    """Counts, median fit time, and with labels the MAE per parameter of ``params`` (the
    continuous raw-yarn ones, and any other the search moved: :func:`reported`) of both
    reconstructions (raw units) and the change in %, and how often each has the true ply
    count."""
    out: dict = {"count": len(rows), "improved": int(sum(r["improved"] for r in rows)),
                 "fit_seconds_median": float(np.median([r["seconds"] for r in rows]))
                 if rows else None, "params": {}}
    labelled = [(r, t) for r, t in zip(rows, truth, strict=False) if t is not None]
    if not labelled:
        return out
    out["n_right"] = {kind: float(np.mean([r[kind]["n"] == t.n for r, t in labelled]))
                      for kind in ("neural", "refined")}
    changed = [(r["neural"]["n"] == t.n, r["refined"]["n"] == t.n) for r, t in labelled
               if r["refined"]["n"] != r["neural"]["n"]]
    out["n_changed"] = {"to_right": sum(b for _, b in changed),
                        "to_wrong": sum(a for a, _ in changed),
                        "wrong_to_wrong": sum(not (a or b) for a, b in changed)}
    for k in params:
        whole = _mae_of(k, labelled)
        a, b = whole["neural"], whole["refined"]
        out["params"][k] = {"neural": a, "refined": b,
                            "change_pct": 100 * (b / a - 1) if a > 0 else 0.0}
        if any(r["refined"][k] != r["neural"][k] for r, _ in labelled):
            # a parameter the search moved: split by whether the nets' ply count is right
            sides = {side: [(r, t) for r, t in labelled
                            if (r["neural"]["n"] == t.n) == (side == "right")]
                     for side in ("right", "wrong")}
            out["params"][k]["by_ply_count"] = {side: _mae_of(k, of_side)
                                                for side, of_side in sides.items() if of_side}
        held = [(r["intervals"][k], getattr(t, k)) for r, t in labelled
                if k in r.get("intervals", {})]
        if held:
            out["params"][k] |= {
                "interval_holds": float(np.mean([lo <= v <= hi for (lo, hi, _), v in held])),
                "interval_width": float(np.mean([hi - lo for (lo, hi, _), _ in held])),
                "interval_source": held[0][0][2]}
    return out


def _mae_of(k: str, labelled: list[tuple[dict, YarnParams]]) -> dict:
    """Photos, and the neural and refined MAE of parameter ``k`` over them."""
    errors = {kind: float(np.mean([abs(r[kind][k] - getattr(t, k)) for r, t in labelled]))
              for kind in ("neural", "refined")}
    return {"photos": len(labelled), **errors}


def reported(config, setup: str) -> tuple[str, ...]:
    """The parameters a report of fits with ``config`` (:class:`ipm.refine.plan.FitConfig`)
    of photos of ``setup`` shows: the continuous raw-yarn ones, then any other the stages
    asked for move (flyaways)."""
    return RAW_CONTINUOUS + tuple(dict.fromkeys(k for k in config.searched(setup)
                                                if k not in RAW_CONTINUOUS))


def csv_text(rows: list[dict], truth: Sequence[YarnParams | None],
             params: Sequence[str] = RAW_CONTINUOUS) -> str:
    """One row per photo: losses, whether the search improved, time, and per parameter of
    ``params`` (and the ply count) the neural, refined (and true) values."""
    keys = ("n", *params)
    labelled = any(t is not None for t in truth)
    head = ["image", "loss_neural", "loss_refined", "improved", "seconds", "tilt_deg"]
    for k in keys:
        head += [f"neural_{k}", f"refined_{k}"] + ([f"true_{k}"] if labelled else [])
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(head)
    for r, t in zip(rows, truth, strict=True):
        cells = [Path(r["image"]).name, f"{r['loss_neural']:.6g}", f"{r['loss_refined']:.6g}",
                 int(r["improved"]), f"{r['seconds']:.1f}", f"{r.get('tilt_deg', 0.0):.3f}"]
        for k in keys:
            cells += [f"{r['neural'][k]:.6g}", f"{r['refined'][k]:.6g}"]
            if labelled:
                cells.append("" if t is None else f"{getattr(t, k):.6g}")
        w.writerow(cells)
    return buf.getvalue()


def markdown(s: dict, rows: list[dict], command: str, figure: str | None) -> str:
    lines = ["# Neural-only vs refined", "", f"Made by `{command}`.", "",
             f"{s['count']} photos; the search kept a candidate other than the nets' guess "
             f"for {s['improved']}; fit time per photo: median "
             f"{s['fit_seconds_median']:.3g} s." if rows else "No photos fitted.", ""]
    if s["params"]:
        lines += ["Errors against the labels (MAE; % of the parameter's range), and how often "
                  f"the refined result's {LEVEL:.0%} interval holds the truth (its mean "
                  "width in % of the range; where it comes from):", "",
                  "| parameter | neural | refined | change | interval holds the truth | "
                  "width | from |", "|---|---|---|---|---|---|---|"]
        for k, v in s["params"].items():
            width = PAPER_INTERVALS[k].width
            held = (f"{v['interval_holds']:.0%} | {100 * v['interval_width'] / width:.1f}% | "
                    f"{v['interval_source']}" if "interval_holds" in v else " | | ")
            lines.append(f"| {k} | {v['neural']:.4g} ({100 * v['neural'] / width:.1f}%) | "
                         f"{v['refined']:.4g} ({100 * v['refined'] / width:.1f}%) | "
                         f"{v['change_pct']:+.0f}% | {held} |")
        lines.append("")
    if "n_right" in s:
        c = s.get("n_changed", {})
        lines += [f"Ply count n right: neural {s['n_right']['neural']:.0%}, refined "
                  f"{s['n_right']['refined']:.0%}" + (
                      f"; the fit changed the nets' count on {sum(c.values())}: wrong to right "
                      f"on {c['to_right']}, right to wrong on {c['to_wrong']}, wrong to "
                      f"another wrong on {c['wrong_to_wrong']}" if c and any(c.values())
                      else "") + ".", ""]
    for k, v in s["params"].items():
        if "by_ply_count" in v:
            lines += [f"`{k}` (MAE, neural -> refined) on the photos whose ply count the nets "
                      "read " + "; ".join(
                          f"{side} ({b['photos']} photo{'' if b['photos'] == 1 else 's'}): "
                          f"{b['neural']:.4g} -> {b['refined']:.4g}"
                          for side, b in v["by_ply_count"].items()) + ".", ""]
    lines += ["The losses are the fit's whole loss at both ends; a search stage decides by the "
              "groups that see its parameters (the ply pitch alone by those that read the "
              "ply period), so a candidate it kept can score higher here.", "",
              "| photo | loss neural | loss refined | improved |", "|---|---|---|---|"]
    lines += [f"| {Path(r['image']).name} | {r['loss_neural']:.4f} | {r['loss_refined']:.4f} "
              f"| {'yes' if r['improved'] else 'no'} |" for r in rows]
    if s.get("failed"):
        lines += ["", "Not fitted:", ""] + [f"- {Path(r['image']).name}: {r['error']}"
                                            for r in s["failed"]]
    if figure:
        lines += ["", f"![photo, neural, refined]({figure})"]
    return "\n".join(lines) + "\n"


def contact_sheet(path: Path, rows: list[dict], photos: Sequence[Record], picks: list[int],
                  tags: dict[int, str], prep: PhotoPrep = PhotoPrep(),
                  display_scale: float = 0.25) -> None:
    """photo | neural | refined for the rows ``picks``, each labelled ``tags[i]`` and its
    losses, rendered with the fit's fiber seed in the shared scene, shown in the photo's
    capture (:func:`ipm.refine.display.display_renders`)."""
    from ipm.photo import write_png
    from ipm.refine.display import compare_image, display_renders
    from ipm.refine.fit import FitResult
    from ipm.refine.plan import FitConfig
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options

    renderer = Renderer(options=setup_options(photos[picks[0]].setup)) if picks else None
    config = FitConfig(display_scale=display_scale, display_spp=16)
    panels, labels = [], []
    for i in picks:
        r = rows[i]
        res = FitResult(YarnParams.from_dict(r["neural"]), YarnParams.from_dict(r["refined"]),
                        r["loss_neural"], r["loss_refined"], r["improved"],
                        tilt_deg=r.get("tilt_deg", 0.0))
        panels += list(display_renders(renderer, prep.load(photos[i]), res, config)[:3])
        labels += [f"{tags[i]}: {Path(r['image']).name}", f"neural  loss {r['loss_neural']:.4f}",
                   f"refined  loss {r['loss_refined']:.4f}"]
    write_png(path, compare_image(panels, labels))


def compare(photos: Sequence[Record], out: Path, ensemble, config,
            prep: PhotoPrep = PhotoPrep(), figure_count: int = 4, progress=None,
            command: str = "ipm compare") -> dict:
    """Fit every photo (:func:`photos_in`), resuming a stopped run in ``out``, and write the
    report; returns the summary."""
    truth = [p.params for p in photos]
    out.mkdir(parents=True, exist_ok=True)
    every = fit_all(out / FITS, photos, lambda i, photo: ensemble.predict(photo), config,
        (lambda photo: ensemble.sigma(photo.pixel_size_mm)) if config.prior else None, prep,
        progress, ensemble.ply_count_probabilities, ensemble.readings,
        lambda photo: ensemble.detail_readings(photo.pixel_size_mm))
    fitted = [i for i, r in enumerate(every) if "error" not in r]
    rows, truth, photos = ([seq[i] for i in fitted] for seq in (every, truth, photos))
    shown = reported(config, ensemble.setup)
    s = summary(rows, truth, shown)
    s["failed"] = [r for r in every if "error" in r]
    write_text(out / "results.csv", csv_text(rows, truth, shown))
    figure = None
    if figure_count and rows:
        gain = [r["loss_neural"] - r["loss_refined"] for r in rows]
        picks = sorted(range(len(rows)), key=lambda i: -gain[i])[:figure_count]
        contact_sheet(out / "compare.png", rows, photos, sorted(picks),
                      {i: f"photo {i}" for i in picks}, prep)
        figure = "compare.png"
    write_text(out / "index.md", markdown(s, rows, command, figure))
    write_text(out / "summary.json", json.dumps(s, indent=2) + "\n")
    return s
