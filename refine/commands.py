"""``ipm fit``: the user's entry point to the nets and the refinement.  Heavy imports
(torch, mitsuba, kornia) happen inside the command."""

from __future__ import annotations

import functools
import inspect
import json
from dataclasses import fields
from pathlib import Path
from typing import Annotated, get_type_hints

import typer

from ipm.errors import UserError
from ipm.io import check_not_inputs, check_same_settings, prepare_folder
from ipm.photo import CALIBRATION_HELP, PIXEL_SIZE_HELP
from ipm.progress import progress_bar
from ipm.refine.plan import FitConfig
from ipm.render.commands import ForceOpt, PhotoSetupOpt
from ipm.setups import AUTO_SETUP, DEFAULT_SETUP, INVERT_HELP, NAMES, check_setup_name, setup_of
from ipm.workers import RAY_HELP

#: The config of a command called without one (the options' defaults).
DEFAULT_CONFIG = FitConfig()


def with_fit_options(command):
    """``command`` with an option for each field of :class:`FitConfig` that has help (each
    option is defined there, once, for ``ipm fit`` and ``ipm compare``), gathered into the
    command's ``config`` argument."""
    hints = get_type_hints(FitConfig)
    extra = []
    for f in fields(FitConfig):
        if "help" in f.metadata:
            m = f.metadata
            option = typer.Option(*m["decls"], help=m["help"],
                                  **{k: m[k] for k in ("min", "max") if k in m})
            extra.append(inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY,
                                           default=f.default,
                                           annotation=Annotated[hints[f.name], option]))
    signature = inspect.signature(command, eval_str=True)
    own = [p for p in signature.parameters.values() if p.name != "config"]

    @functools.wraps(command)
    def with_config(**kwargs):
        config = FitConfig(**{p.name: kwargs.pop(p.name) for p in extra})
        return command(config=config, **kwargs)

    with_config.__signature__ = signature.replace(parameters=own + extra)
    with_config.__annotations__ = {p.name: p.annotation for p in own + extra}
    return with_config


@with_fit_options
def fit(
    photo: Annotated[Path, typer.Argument(help="photo of a yarn running horizontally (PNG, "
                                          "JPEG or TIFF; 8 or 16 bit), or a folder of "
                                          "them (each fitted into its own folder in --out, "
                                          "with a summary report)")],
    out: Annotated[Path, typer.Option("--out", "-o", help="folder for params.json, the "
                                      "renders and compare.png; for a folder of photos, "
                                      "a folder per photo and the report (a stopped run "
                                      "resumes)")] = Path("fit"),
    refine: Annotated[bool, typer.Option("--refine/--no-refine", help="refine the nets' "
                                         "guess by render-and-compare, in the stages of "
                                         "the capture setup and the photo (--dry-run "
                                         "lists them)")] = False,
    dry_run: Annotated[bool, typer.Option("--dry-run", help="read the photo and the nets, "
                                          "print the stages the fit would run and stop")]
    = False,
    pixel_size: Annotated[float | None, typer.Option(help=PIXEL_SIZE_HELP)] = None,
    calibration: Annotated[Path | None, typer.Option(help=CALIBRATION_HELP)] = None,
    models: Annotated[Path | None, typer.Option(help="trained ensemble folder (default: the "
                                                "models shipped with ipm)")] = None,
    knit: Annotated[str | None, typer.Option(help="also knit the fitted yarn into a patch "
                                             "of this pattern (knit, purl, garter, rib): "
                                             "knit.png, and a panel of compare.png")] = None,
    invert: Annotated[bool, typer.Option("--invert", help=INVERT_HELP)] = False,
    variant: Annotated[str | None, typer.Option(help="Mitsuba variant")] = None,
    setup: PhotoSetupOpt = AUTO_SETUP,
    force: ForceOpt = False,
    workers: Annotated[int | None, typer.Option(min=1, help="photos of a folder fitted side "
                                                "by side, each by a process with its own nets "
                                                "and renderer (default: 1; with --ray, one a "
                                                "CPU of the cluster); refused if the free "
                                                "memory cannot hold them")] = None,
    ray: Annotated[str | None, typer.Option(help=RAY_HELP)] = None,
    config: FitConfig = DEFAULT_CONFIG,
) -> None:
    """Infer a yarn's parameters from a photo: the neural ensemble, and with --refine a
    render-and-compare search; writes params.json (neural and refined parameters, their
    losses, the stages run, the settings), neural.png, refined.png and compare.png (photo |
    neural | refined), the renders shown at the photo's background level and defocus
    (params.json's capture).  The nets and the renders are those of the photo's capture
    setup (--setup)."""
    from ipm.photo import pixel_size_of
    from ipm.refine.fitter import FIT_FILES, FitJob, read_shot

    job = FitJob(refine, knit, invert, setup, config)
    if knit is not None:
        from ipm.knit import faces

        faces(knit, 1, 1)  # an unknown pattern fails before any work
    check_setup_name(setup)  # an unknown setup fails before any work
    if photo.is_dir():
        if dry_run:
            raise UserError("--dry-run reads one photo; give a photo, not a folder")
        from ipm.refine.batch import fit_folder

        raise typer.Exit(fit_folder(photo, out, job, pixel_size, calibration, models, variant,
                                    workers, ray))
    if workers is not None or ray is not None:
        raise UserError("--workers and --ray fit a folder of photos; give a folder")
    sidecar = photo.with_suffix(".json")
    check_not_inputs([out / f for f in FIT_FILES],
                     [photo, sidecar if sidecar.is_file() else None, calibration], force)
    pixel_size = pixel_size_of(photo, pixel_size, calibration)
    read = read_shot(photo, pixel_size, job)
    if dry_run:
        _dry_run(read, job, models, variant)
        return
    made_folder = not out.exists()
    prepare_folder(out)
    try:
        _fit_into(out, read, job, models, variant)
    except BaseException:
        if made_folder and out.is_dir() and not any(out.iterdir()):
            out.rmdir()  # a late error leaves no empty folder behind
        raise


def _dry_run(read, job, models, variant) -> None:
    """``ipm fit --dry-run``: the stages the fit of the photo ``read`` would run (the gates
    measured on the photo, the nets' reading and a render of the nets' yarn), nothing
    written."""
    from ipm.refine.fit import fit
    from ipm.refine.fitter import Fitter

    shot, config = read.photo, job.config
    for line in read.lines:
        typer.echo(line, err=True)
    fitter = Fitter(models, variant)
    ensemble = fitter.nets(shot.setup)
    neural = ensemble.predict(shot)
    if read.chosen:
        typer.echo(f"note: {read.chosen}", err=True)
    result = fit(shot, neural, fitter.renderer(shot.setup), config, job.refine,
                 sigma=ensemble.sigma(shot.pixel_size_mm) if config.prior else None,
                 count_prior=ensemble.ply_count_probabilities(shot), dry_run=True)
    for w in result.warnings:
        typer.echo(f"warning: {w}", err=True)
    typer.echo("\n".join(result.plan.lines()))


def _fit_into(out: Path, read, job, models, variant) -> None:
    """The body of ``ipm fit PHOTO`` once the photo is read and the folder made: the fit
    with a progress bar over its renders, its lines said as they come, its files written."""
    from ipm.refine.fitter import Fitter

    with progress_bar("renders, best loss {task.fields[best]}", transient=True) as bar:
        def on_eval(total: int):
            task = bar.add_task("refining" if job.refine else "scoring", best="-", total=total)
            return lambda i, loss, best: bar.update(task, completed=i, best=f"{best:.4f}")

        result = Fitter(models, variant).fit(read, job, on_eval,
                                             say=lambda line: typer.echo(line, err=True))
    result.write(out)
    typer.echo(f"wrote {out}/params.json, compare.png", err=True)


@with_fit_options
def compare(
    photos: Annotated[Path, typer.Argument(help="folder of photos, or a dataset made with "
                                           "`ipm generate` (then errors against its labels "
                                           "are reported too)")],
    out: Annotated[Path, typer.Option("--out", "-o", help="report folder (index.md, "
                                      "results.csv, compare.png); a stopped run resumes")]
    = Path("compare"),
    pixel_size: Annotated[float | None, typer.Option(help=PIXEL_SIZE_HELP + "; a dataset "
                                                     "records its own")] = None,
    calibration: Annotated[Path | None, typer.Option(help=CALIBRATION_HELP)] = None,
    count: Annotated[int | None, typer.Option(min=1, help="fit only the first N photos (by "
                                              "name)")] = None,
    models: Annotated[Path | None, typer.Option(help="trained ensemble folder (default: the "
                                                "models shipped with ipm)")] = None,
    invert: Annotated[bool, typer.Option("--invert", help=INVERT_HELP)] = False,
    blur_mm: Annotated[float, typer.Option("--blur-mm", min=0, max=1, help="blur every photo "
                                           "by a Gaussian of this sigma (mm at the yarn) "
                                           "first: the fits on photos less sharp than "
                                           "renders")] = 0.0,
    setup: Annotated[str | None, typer.Option(help=f"capture setup of a folder of photos "
                                              f"({', '.join(NAMES)}); a dataset records its "
                                              "own")] = None,
    config: FitConfig = DEFAULT_CONFIG,
) -> None:
    """Neural-only vs refined over many photos: `ipm fit --refine` on each, then a table
    (CSV and Markdown) and a figure of photo | neural | refined."""
    import shlex
    import sys

    from ipm.io import write_text
    from ipm.refine import compare as cmp

    listed = cmp.photos_in(photos, pixel_size, count, setup, calibration)
    setup = listed[0].setup
    from ipm.nets.ensemble import Ensemble  # torch: after the checks, which are one line

    ensemble = Ensemble.load(models, setup=setup)
    prepare_folder(out)
    stages = config.stage_params(setup)
    settings = {"photos": str(photos), "count": len(listed), "pixel_size_mm": pixel_size,
                **({"calibration": str(calibration)} if calibration else {}),
                "models": str(models) if models else "shipped", "budget": config.budget,
                "algorithm": config.algorithm, "params": list(stages[0]),
                "prior": config.prior, "invert": invert}
    settings |= {"blur_mm": blur_mm} if blur_mm else {}  # only when set: older folders resume
    settings |= {"setup": setup} if setup != DEFAULT_SETUP else {}
    settings |= {"learned": config.learned} if config.learned else {}
    settings |= {"detail": config.detail} if config.detail else {}
    settings |= {"ply_counts": config.ply_counts} if config.ply_counts > 1 else {}
    settings |= {"polish": config.polish} if config.polish else {}
    settings |= {"match_size": True} if config.match_size else {}
    settings |= {"time_s": config.time_s} if config.time_s else {}
    settings |= {"sure_count": config.sure_count}
    count_groups = setup_of(setup).count_groups if config.chooses_count(setup) else ()
    settings |= {"count_groups": list(count_groups)} if count_groups else {}
    settings |= {"later_stages": [list(s) for s in stages[1:]]} if len(stages) > 1 else {}
    saved = out / "settings.json"
    check_same_settings(saved, settings, "a comparison")
    write_text(saved, json.dumps(settings, indent=2) + "\n")
    with progress_bar() as bar:
        task = bar.add_task("fits", total=len(listed))
        s = cmp.compare(listed, out, ensemble, config,
                        cmp.PhotoPrep(invert=invert, blur_mm=blur_mm),
                        progress=lambda done, total: bar.update(task, completed=done),
                        command="ipm " + " ".join(shlex.quote(a) for a in sys.argv[1:]))
    for k, v in s["params"].items():
        typer.echo(f"{k:10s} MAE neural {v['neural']:.4g} -> refined {v['refined']:.4g} "
                   f"({v['change_pct']:+.0f}%)", err=True)
    for r in s["failed"]:
        named = r["error"] if r["error"].startswith(r["image"]) else f"{r['image']}: {r['error']}"
        typer.echo(f"error: not fitted: {named}", err=True)
    typer.echo(f"{s['improved']}/{s['count']} photos improved; wrote {out}/index.md, "
               "results.csv" + (", compare.png" if s["count"] else ""), err=True)
    if s["failed"]:
        typer.echo(f"{len(s['failed'])} of {len(listed)} photos failed", err=True)
        raise typer.Exit(1)
