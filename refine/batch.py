"""``ipm fit FOLDER``: every photo of a folder fitted as ``ipm fit`` fits one, each into its
own folder of ``OUT`` (:mod:`ipm.refine.fitter`), by this process, local worker processes or
Ray actors (:mod:`ipm.workers`), and a yarn test report of them all: ``fits.csv`` (a row a
photo, in the order of their names: the frames of a bobbin in the order taken),
``report.png`` (each quantity along the frames and its distribution) and ``report.md``.

A photo's folder is written by the driver when its fit returns, ``params.json`` last, and
names the photo's content hash: the same command run again skips every photo whose folder
holds its ``params.json`` and fits the rest, so a run stopped at any moment (Ctrl-C, a kill,
a lost node) loses only the photos in flight.  The report is made from the folders alone,
so it is the same however many times the run was stopped.  A photo that cannot be fitted is
named with its one-line reason and the others go on; the exit status says whether any
failed.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ipm.errors import UserError
from ipm.io import check_same_settings, content_hash, prepare_folder, write_bytes, write_text
from ipm.params import RAW_CONTINUOUS
from ipm.refine.fitter import PARAMS, RUN, FitJob

SETTINGS = "settings.json"
CSV = "fits.csv"
FIGURE = "report.png"
PAGE = "report.md"
#: The memory one worker may take (GB): a fit's nets, renderer and photo; a run asks the
#: machine for this much per local worker before it starts (benchmarks/results/batch_fit.md
#: has the measured peak).
WORKER_GB = 1.5
#: The report's quantities: (CSV column, label), drawn along the frames and as histograms.
FIGURE_ROWS = (("photo_diameter_mm", "diameter, photo (mm)"),
               ("photo_ply_twist_tpm", "ply twist, photo (turns/m)"),
               ("photo_hairiness_h", "hairiness H, photo"),
               ("fibers_hairiness_h", "hairiness H, fitted fibers"),
               ("alpha_ply", "ply pitch alpha_ply (mm), fitted"))


@dataclass(frozen=True)
class Item:
    """A photo of the folder: its ``path``, the ``folder`` of ``OUT`` its fit goes to, its
    ``pixel_size`` (mm) and content hash, or the ``error`` that keeps it from being
    fitted."""

    path: Path
    folder: str
    pixel_size: float | None = None
    sha256: str | None = None
    error: str | None = None


def list_photos(folder: Path, pixel_size: float | None, calibration: Path | None
                ) -> list[Item]:
    """The photos of ``folder`` by name, each with its pixel size (:func:`pixel_size_of`)
    or its error; a folder in ``OUT`` per photo, named by its stem (by its whole name where
    two stems are the same).  Refused in one line if there are none, or none has a pixel
    size."""
    from collections import Counter

    from ipm.dataset import PHOTO_SUFFIXES, photo_files
    from ipm.photo import pixel_size_of

    files = photo_files(folder)
    if not files:
        raise UserError(f"{folder} holds no photos ({', '.join(PHOTO_SUFFIXES)})")
    stems = Counter(p.stem for p in files)
    items, errors = [], []
    for p in files:
        name = p.stem if stems[p.stem] == 1 else p.name.replace(".", "_")
        try:
            size = pixel_size_of(p, pixel_size, calibration)
        except UserError as e:
            errors.append(e)
            items.append(Item(p, name, error=str(e)))
            continue
        sha = content_hash(p)
        items.append(Item(p, name, size, sha, None if sha else f"{p}: cannot read it"))
    if len(errors) == len(items):
        raise errors[0]
    return items


def fitted(out: Path, item: Item) -> dict | None:
    """The ``params.json`` of ``item``'s folder in ``out`` if it holds the fit of this very
    photo (same content hash), else None."""
    path = out / item.folder / PARAMS
    try:
        params = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return None
    return params if params.get("photo", {}).get("sha256") == item.sha256 else None


def check_memory(workers: int, gb: float = WORKER_GB) -> None:
    """Refuse, before any worker starts, ``workers`` local workers the free memory cannot
    hold at :data:`WORKER_GB` each."""
    try:
        free = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") / 2**30
        with open("/proc/meminfo", encoding="ascii") as f:  # what Linux can give back too
            info = dict(line.split(":", 1) for line in f)
        free = max(free, int(info["MemAvailable"].split()[0]) / 2**20)
    except (OSError, ValueError, KeyError):
        return  # not known here: not refused
    if workers * gb > free:
        fits = max(1, int(free // gb))
        raise UserError(f"{workers} workers need about {workers * gb:.1f} GB and "
                        f"{free:.1f} GB is free; use --workers {fits}")


def settings_of(job: FitJob, pixel_size: float | None, calibration: Path | None,
                models: Path | None) -> dict:
    """What a folder's fit records in ``OUT/settings.json``: a rerun with other settings is
    refused (one folder, one way of fitting)."""
    return json.loads(json.dumps({  # as read back (tuples as lists)
        "refine": job.refine, "knit": job.knit, "invert": job.invert, "setup": job.setup,
        "config": asdict(job.config), "pixel_size_mm": pixel_size,
        "calibration": str(calibration) if calibration else None,
        "models": str(models) if models else "shipped"}))


def fit_folder(folder: Path, out: Path, job: FitJob, pixel_size: float | None,
               calibration: Path | None, models: Path | None, variant: str | None,
               workers: int | None, ray: str | None) -> int:
    """``ipm fit FOLDER -o OUT``; returns the exit status (1 if a photo failed).  An
    interruption is raised on, once the workers are stopped."""
    import typer

    from ipm.progress import progress_bar
    from ipm.refine.fitter import FitOutput, Fitter
    from ipm.workers import Workers

    if out.resolve() == folder.resolve():
        raise UserError(f"--out {out} is the folder of photos; give another folder")
    if models is not None and not models.is_dir():
        raise UserError(f"--models {models} is not a folder of nets")
    items = list_photos(folder, pixel_size, calibration)
    settings = settings_of(job, pixel_size, calibration, models)
    if out.is_dir() and not (out / SETTINGS).is_file() and any(out.iterdir()):
        raise UserError(f"{out} is not empty and holds no {SETTINGS} of a folder's fit; "
                        "choose an empty or new --out")
    check_same_settings(out / SETTINGS, settings, "a folder's fit")
    prepare_folder(out)
    write_text(out / SETTINGS, json.dumps(settings, indent=2) + "\n")
    failed = {i: it.error for i, it in enumerate(items) if it.error}
    todo = [i for i, it in enumerate(items) if not it.error and fitted(out, it) is None]
    count = min(workers or (10**6 if ray else 1), len(todo))
    if todo and ray is None and count > 1:
        check_memory(count)
    with progress_bar("failed {task.fields[failed]}") as bar:
        task = bar.add_task("photos", total=len(items), completed=len(items) - len(todo),
                            failed=len(failed))
        ended: set[int] = set()  # fitted or failed in this run
        try:
            if todo:
                if ray and models:  # Ray's nodes need not have the folder: its nets go along
                    from ipm.nets.store import pack_ensemble

                    models = pack_ensemble(models)
                with Workers(Fitter, (models, variant), count, ray) as pool:
                    for i, r in pool.run("fit_file", _tasks(items, todo, job, failed)):
                        ended.add(i)
                        if "error" in r:
                            failed[i] = r["error"]
                            typer.echo(f"error: {r['error']}", err=True)
                        else:
                            run = {"fit_seconds": round(r["seconds"], 2), "worker": r["worker"]}
                            r["files"][RUN] = (json.dumps(run) + "\n").encode()
                            FitOutput(r["files"], r["lines"]).write(out / items[i].folder)
                        done = ended | (failed.keys() & set(todo))  # (unreadable when sent)
                        bar.update(task, completed=len(items) - len(todo) + len(done),
                                   failed=len(failed))
        except BaseException as e:
            if type(e).__name__ in ("BrokenProcessPool", "RayActorError", "ActorDiedError"):
                raise UserError(f"a worker stopped ({type(e).__name__}: killed, or out of "
                                "memory?); the photos fitted are kept: run the same command "
                                "to resume") from None
            left = sum(fitted(out, it) is None for it in items)  # an interruption or a bug
            typer.echo(f"{left} of {len(items)} photos not fitted yet; the same command "
                       "resumes", err=True)
            raise
    rows = report_rows(out, items, failed)
    write_report(out, rows, folder)
    for i in sorted(failed):
        typer.echo(f"error: not fitted: {_named(items[i], failed[i])}", err=True)
    typer.echo(f"{len(items) - len(failed)} of {len(items)} photos fitted; wrote {out}/{PAGE}, "
               f"{CSV}, {FIGURE}", err=True)
    return 1 if failed else 0


def _tasks(items: Sequence[Item], todo: list[int], job: FitJob, failed: dict[int, str]):
    """The workers' tasks: each photo's bytes, read when a worker is free; a photo that can
    no longer be read is failed here."""
    for i in todo:
        it = items[i]
        try:
            data = it.path.read_bytes()
        except OSError as e:
            failed[i] = f"{it.path}: cannot read it ({e.strerror})"
            continue
        yield i, (it.path.name, data, it.pixel_size, job)


def _named(item: Item, error: str) -> str:
    return error if error.startswith(str(item.path)) or error.startswith(item.path.name) \
        else f"{item.path.name}: {error}"


# -- the report ------------------------------------------------------------------------------
def report_rows(out: Path, items: Sequence[Item], failed: dict[int, str]) -> list[dict]:
    """A row a photo, in the folder's order: its fit's parameters with their intervals and
    textile measures from its ``params.json``, or its error."""
    rows = []
    for i, it in enumerate(items):
        row = {"photo": it.path.name, "folder": it.folder}
        params = None if i in failed else fitted(out, it)
        if params is None:
            rows.append(row | {"status": "failed", "error": _named(it, failed.get(
                i, "not fitted"))})
            continue
        refined, intervals = params["refined"], params["intervals"]
        row |= {"status": "fitted", "error": "", "n": refined["n"]}
        for k in RAW_CONTINUOUS:
            row[k] = refined[k]
            lo, hi = intervals.get(k, [None, None])[:2]
            row |= {f"{k}_lo": lo, f"{k}_hi": hi}
        row |= {k: refined[k] for k in ("g", "l_hair", "l_loop", "d_mean")}
        row |= {"loss_neural": params["loss"]["neural"], "loss_refined": params["loss"]["refined"],
                "improved": params["improved"], "warnings": len(params["warnings"])}
        textile = params.get("textile", {})
        for source, keys in (("photo", ("diameter_mm", "diameter_cv_pct", "ply_twist_tpm",
                                        "twist_direction", "hairiness_h", "s3")),
                             ("render", ("diameter_mm", "hairiness_h")),
                             ("fibers", ("diameter_mm", "ply_twist_tpm", "twist_direction",
                                         "hairiness_h"))):
            row |= {f"{source}_{k}": textile.get(source, {}).get(k) for k in keys}
        rows.append(row)
    return rows


def columns(rows: list[dict]) -> list[str]:
    """The CSV's columns: every key of the rows, in the order first met."""
    return list(dict.fromkeys(k for r in rows for k in r))


def write_report(out: Path, rows: list[dict], folder: Path) -> None:
    """``fits.csv``, ``report.png`` and ``report.md`` of ``rows``, each atomically."""
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns(rows), lineterminator="\n")
    writer.writeheader()
    writer.writerows({k: _cell(v) for k, v in r.items()} for r in rows)
    write_text(out / CSV, buf.getvalue())
    write_bytes(out / FIGURE, figure(rows))
    write_text(out / PAGE, page(rows, folder))


def _cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def _values(rows: list[dict], key: str) -> tuple[np.ndarray, np.ndarray]:
    """(frame numbers, values) of the fitted rows that have ``key``."""
    pairs = [(i, r[key]) for i, r in enumerate(rows)
             if r["status"] == "fitted" and isinstance(r.get(key), (int, float))]
    return (np.array([p[0] for p in pairs], dtype=float),
            np.array([p[1] for p in pairs], dtype=float))


def figure(rows: list[dict]) -> bytes:
    """The report's figure as PNG bytes: each of :data:`FIGURE_ROWS` along the frames
    (with its 80% interval where the fit gives one) and as a histogram."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(FIGURE_ROWS), 2, figsize=(11, 2.3 * len(FIGURE_ROWS)),
                             gridspec_kw={"width_ratios": (3, 1)}, squeeze=False)
    for (key, label), (along, hist) in zip(FIGURE_ROWS, axes, strict=True):
        x, v = _values(rows, key)
        if any(f"{key}_lo" in r for r in rows):
            _, lo = _values(rows, f"{key}_lo")
            _, hi = _values(rows, f"{key}_hi")
            if len(lo) == len(v):
                along.fill_between(x, lo, hi, color="#ccd", step="mid", label="80% interval")
        along.plot(x, v, ".-", color="#333", lw=0.8, ms=4)
        if len(v):
            along.axhline(float(np.median(v)), color="#c33", lw=0.8, ls="--", label="median")
            hist.hist(v, bins=min(20, max(5, len(v) // 3)), color="#777",
                      orientation="horizontal")
        along.set(ylabel=label)
        if len(v):
            along.legend(loc="upper right", fontsize=7, frameon=False)
        hist.set(xlabel="photos")
    axes[-1][0].set(xlabel="frame (photos in name order)")
    failed = sum(r["status"] == "failed" for r in rows)
    fig.suptitle(f"{len(rows) - failed} photos fitted" + (f", {failed} failed" if failed
                                                          else ""))
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80, metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def page(rows: list[dict], folder: Path) -> str:
    """``report.md``: the medians and spreads of the main quantities, the failures, and
    the files."""
    fitted_rows = [r for r in rows if r["status"] == "fitted"]
    lines = [f"# Fits of {folder.name}", "",
             f"{len(fitted_rows)} of {len(rows)} photos fitted (`{CSV}`: a row a photo, its "
             "folder holds params.json and the renders).", ""]
    if fitted_rows:
        lines += ["| quantity | median | 10th-90th percentile | CV |", "|---|---|---|---|"]
        for key, label in FIGURE_ROWS + (("R_ply", "ply radius R_ply (mm), fitted"),):
            _, v = _values(rows, key)
            if len(v):
                p10, p50, p90 = np.percentile(v, (10, 50, 90))
                cv = 100 * np.std(v) / abs(np.mean(v)) if np.mean(v) else float("nan")
                lines.append(f"| {label} | {p50:.4g} | {p10:.4g}-{p90:.4g} | {cv:.1f}% |")
        directions = [r.get("photo_twist_direction") for r in fitted_rows]
        lines += ["", "Twist direction seen on the photos: " + ", ".join(
            f"{d or 'not seen'} {directions.count(d)}" for d in dict.fromkeys(directions)) + ".",
            ""]
    failed = [r for r in rows if r["status"] == "failed"]
    if failed:
        lines += ["Not fitted:", ""] + [f"- {r['error']}" for r in failed] + [""]
    lines += [f"![each quantity along the frames and its distribution]({FIGURE})", ""]
    return "\n".join(lines)
