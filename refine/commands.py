"""``ipm fit``: the user's entry point to the nets and the refinement.  Heavy imports
(torch, mitsuba, kornia) happen inside the command."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from ipm.io import check_not_inputs, check_same_settings, prepare_folder
from ipm.photo import AUTO_SETUP, CALIBRATION_HELP, PIXEL_SIZE_HELP, check_setup_name
from ipm.progress import progress_bar
from ipm.refine.search import (
    DEFAULT_LEARNED,
    DEFAULT_PLY_COUNTS,
    SURE_COUNT,
    SearchOptions,
    search_stages_of,
)
from ipm.render.commands import ForceOpt, PhotoSetupOpt

#: The search's defaults, one place for both commands: :class:`SearchOptions`.
_DEFAULT = SearchOptions()
_DEFAULT_PARAMS = ";".join(",".join(stage) for stage in _DEFAULT.stages)
_LEARNED_HELP = ("weight of the nets' readings in the loss: renders the nets read as they "
                 "read the photo (0: the image statistics alone)")

_DETAIL_HELP = ("weight of the detail nets' readings (alpha, m) of a window rendered at "
                "their pitch each evaluation, for photos as fine as they need (0: none)")
_PARAMS_HELP = ("parameters to search (any but the ply count n; m is rounded), "
                "comma-separated (alpha_ply,R_ply); stages separated by ';' "
                "(alpha_ply;R_ply,r_x: those from alpha_ply's best); the others keep the "
                "nets' values.  A stage of flyaway parameters alone (g,l_hair,d_mean) is "
                "scored by the flyaway profile, over the whole sampler range; alpha_ply "
                "alone after R_ply by the stripes' period and the core's outline; the thickness "
                "without alpha_ply by all but the outline")
_MATCH_SIZE_HELP = ("start the search from the nets' yarn scaled (R_ply, r_x, r_y by one "
                    "factor) to the photo's core width, keeping the nets' proportions: for "
                    "yarns thinner or thicker than the nets know")
_NETS_COUNT_HELP = ("keep the nets' ply count; by default a backlit fit whose search starts "
                    "with alpha_ply first chooses it by the core's outline and the nets' "
                    "probabilities (ipm.refine.objective.COUNT_GROUPS)")
_SURE_COUNT_HELP = ("where a fit keeps the nets' ply count (frontlit), search alpha_ply only "
                    "if the nets give that count at least this probability (0: always)")
_POLISH_HELP = ("evaluations of a local search (BOBYQA) from the best of each stage of two "
                "or more parameters, beyond the budget: a global search's budget only "
                "samples a coarse grid there (0: none)")


def fit(
    photo: Annotated[Path, typer.Argument(help="photo of a yarn running horizontally (PNG, "
                                          "JPEG or TIFF; 8 or 16 bit)")],
    out: Annotated[Path, typer.Option("--out", "-o", help="folder for params.json, the "
                                      "renders and compare.png")] = Path("fit"),
    refine: Annotated[bool, typer.Option("--refine/--no-refine", help="refine the nets' "
                                         "guess by render-and-compare: searches the ply "
                                         "twist alpha_ply, backlit from the ply count "
                                         "the core's outline chooses; backlit, a yarn "
                                         "far thinner or thicker than the nets' reading "
                                         "has its thickness, flyaways and ply twist "
                                         "searched in turn without their prior (measured "
                                         "in benchmarks/README.md)")]
    = False,
    pixel_size: Annotated[float | None, typer.Option(help=PIXEL_SIZE_HELP)] = None,
    calibration: Annotated[Path | None, typer.Option(help=CALIBRATION_HELP)] = None,
    models: Annotated[Path | None, typer.Option(help="trained ensemble folder (default: the "
                                                "models shipped with ipm)")] = None,
    budget: Annotated[int, typer.Option(help="objective evaluations of the search")]
    = _DEFAULT.budget,
    knit: Annotated[str | None, typer.Option(help="also knit the fitted yarn into a patch "
                                             "of this pattern (knit, purl, garter, rib): "
                                             "knit.png, and a panel of compare.png")] = None,
    time_limit: Annotated[float | None, typer.Option("--time", help="wall-time bound of the "
                                                     "search, seconds")] = None,
    ply_counts: Annotated[int, typer.Option(min=1, max=5, help="search with each of the "
                                            "nets' N most likely ply counts and keep the "
                                            "lowest loss (1: the nets' ply count only)")]
    = DEFAULT_PLY_COUNTS,
    algorithm: Annotated[str, typer.Option(help="NLopt algorithm")] = _DEFAULT.algorithm,
    polish: Annotated[int, typer.Option(min=0, help=_POLISH_HELP)] = _DEFAULT.polish,
    params: Annotated[str, typer.Option(help=_PARAMS_HELP)] = _DEFAULT_PARAMS,
    prior: Annotated[bool, typer.Option("--prior/--no-prior", help="keep the search near the "
                                        "nets' guess, weighted by the nets' validation error "
                                        "(MAP); --no-prior: the image loss alone")] = True,
    invert: Annotated[bool, typer.Option("--invert", help="invert the photo first (an odd "
                                         "case, e.g. a negative; a backlit photo takes "
                                         "--setup backlit)")] = False,
    variant: Annotated[str | None, typer.Option(help="Mitsuba variant")] = None,
    setup: PhotoSetupOpt = AUTO_SETUP,
    learned: Annotated[float, typer.Option(min=0, help=_LEARNED_HELP)] = DEFAULT_LEARNED,
    detail: Annotated[float, typer.Option(min=0, help=_DETAIL_HELP)] = 0.0,
    match_size: Annotated[bool, typer.Option("--match-size", help=_MATCH_SIZE_HELP)] = False,
    nets_ply_count: Annotated[bool, typer.Option("--nets-ply-count", help=_NETS_COUNT_HELP)]
    = False,
    sure_count: Annotated[float, typer.Option(min=0, max=1, help=_SURE_COUNT_HELP)]
    = SURE_COUNT,
    force: ForceOpt = False,
) -> None:
    """Infer a yarn's parameters from a photo: the neural ensemble, and with --refine a
    render-and-compare search; writes params.json (neural and refined parameters, their
    losses, the settings), neural.png, refined.png and compare.png (photo | neural |
    refined), the renders shown at the photo's background level and defocus (params.json's
    capture).  The nets and the renders are those of the photo's capture setup (--setup)."""
    from ipm.photo import Photo, pixel_size_of
    from ipm.refine.fit import FitOptions

    options = FitOptions(search=SearchOptions(**search_stages_of(params), algorithm=algorithm,
                                              budget=budget, time_s=time_limit, polish=polish),
                         ply_counts=ply_counts, learned=learned, detail=detail,
                         match_size=match_size, choose_count=not nets_ply_count,
                         outside=params == _DEFAULT_PARAMS and prior, sure_count=sure_count)
    sidecar = photo.with_suffix(".json")
    check_not_inputs([out / f for f in ("neural.png", "refined.png", "compare.png",
                                         "params.json", "knit.png", "knit.json")],
                     [photo, sidecar if sidecar.is_file() else None, calibration], force)
    if knit is not None:
        from ipm.knit import faces

        faces(knit, 1, 1)  # an unknown pattern fails before any work
    check_setup_name(setup)  # an unknown setup fails before any work
    pixel_size = pixel_size_of(photo, pixel_size, calibration)
    shot, note = Photo.read(photo, pixel_size).upright()
    shot, chosen = shot.with_setup(setup)
    if note:
        typer.echo(f"note: {note}", err=True)
    if invert:
        shot = shot.inverted()
    made_folder = not out.exists()
    prepare_folder(out)
    try:
        _fit_into(out, shot, pixel_size, refine, knit, models, options, budget, prior, variant,
                  chosen)
    except BaseException:
        if made_folder and out.is_dir() and not any(out.iterdir()):
            out.rmdir()  # a late error leaves no empty folder behind
        raise


def _fit_into(out, shot, pixel_size, refine, knit, models, options, budget, prior,
              variant, chosen: str | None = None) -> None:
    """The body of ``ipm fit`` once the photo is read and the folder made; ``chosen``: the
    note of the setup told from the photo, said once the nets have read it."""
    from ipm.io import write_text
    from ipm.photo import write_png
    from ipm.refine.capture import card_warning
    from ipm.refine.fit import compare_image, display_renders, fit, summary_lines
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options

    for stale in ([] if refine else ["refined.png"]) + ([] if knit else ["knit.png", "knit.json"]):
        (out / stale).unlink(missing_ok=True)  # from an earlier fit into the same folder
    from ipm.nets.ensemble import Ensemble

    ensemble = Ensemble.load(models, setup=shot.setup)
    neural = ensemble.predict(shot)
    if chosen:
        typer.echo(f"note: {chosen}", err=True)
    renderer = Renderer(variant, setup_options(shot.setup))
    with progress_bar("renders, best loss {task.fields[best]}", transient=True) as bar:
        task = bar.add_task("refining" if refine else "scoring",
                            total=budget * len(options.search.stages) * options.ply_counts,
                            best="-")
        result = fit(shot, neural, renderer, options, refine,
                     on_eval=lambda i, loss, best: bar.update(task, completed=i,
                                                             best=f"{best:.4f}"),
                     sigma=ensemble.sigma(pixel_size) if prior else None,
                     count_prior=ensemble.ply_count_probabilities(shot),
                     readings=ensemble.readings,
                     detail=ensemble.detail_readings(pixel_size))
    if w := ensemble.upsampling_warning(pixel_size):
        result.warnings.insert(0, w)
    for w in result.warnings:
        typer.echo(f"warning: {w}", err=True)
    shown, neural_img, refined_img, capture = display_renders(renderer, shot, result, options)
    if w := card_warning(capture, shot.setup):
        typer.echo(f"warning: {w}", err=True)
        result.warnings.append(w)
    write_png(out / "neural.png", neural_img)
    panels, labels = [shown, neural_img], ["photo", f"neural  loss {result.loss_neural:.4f}"]
    if refine:
        write_png(out / "refined.png", refined_img)
        panels.append(refined_img)
        labels.append(f"refined  loss {result.loss_refined:.4f}"
                      + ("" if result.improved else "  (no improvement: neural kept)"))
    if knit is not None:
        panels.append(_knit_panel(renderer, result.refined if refine else result.neural, knit,
                                  panels[0].shape[1], out))
        labels.append(f"{knit} patch of the {'refined' if refine else 'neural'} yarn")
    write_png(out / "compare.png", compare_image(panels, labels))
    shown_in = {"exposure_stops": round(capture.exposure_stops, 3),  # the renders' look,
                "backdrop_gain": round(capture.backdrop_gain, 3),  # not the yarn's
                "blur_mm": round(capture.blur_mm, 5)}
    write_text(out / "params.json", json.dumps({**result.to_dict(pixel_size, shot.setup),
                                                "capture": shown_in}, indent=2))
    for line in summary_lines(result):
        typer.echo(line, err=True)
    typer.echo(f"loss neural {result.loss_neural:.4f} -> refined {result.loss_refined:.4f} "
               f"({result.seconds:.0f} s); wrote {out}/params.json, compare.png", err=True)


def _knit_panel(renderer, params, pattern: str, width: int, out: Path):
    """Knit ``params`` into an 8 x 6 patch ``width`` px wide and half as high; writes
    knit.png and its sidecar knit.json into ``out`` and returns the image."""
    from ipm.io import write_text
    from ipm.photo import linear_to_srgb, write_png
    from ipm.render.patch import knit_and_render

    linear, record, _ = knit_and_render(renderer, params, pattern, (8, 6), (width, width // 2),
                                        spp=16)
    image = linear_to_srgb(linear)
    write_png(out / "knit.png", image)
    write_text(out / "knit.json", json.dumps(record, indent=2))
    return image


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
    budget: Annotated[int, typer.Option(help="objective evaluations of each search")]
    = _DEFAULT.budget,
    algorithm: Annotated[str, typer.Option(help="NLopt algorithm")] = _DEFAULT.algorithm,
    polish: Annotated[int, typer.Option(min=0, help=_POLISH_HELP)] = _DEFAULT.polish,
    params: Annotated[str, typer.Option(help=_PARAMS_HELP)] = _DEFAULT_PARAMS,
    ply_counts: Annotated[int, typer.Option(min=1, max=5, help="search with each of the "
                                            "nets' N most likely ply counts and keep the "
                                            "lowest loss (1: the nets' ply count only)")]
    = DEFAULT_PLY_COUNTS,
    prior: Annotated[bool, typer.Option("--prior/--no-prior", help="MAP search around the "
                                        "nets' guess (see ipm fit)")] = True,
    invert: Annotated[bool, typer.Option("--invert", help="invert the photos first (an odd "
                                         "case, e.g. negatives; backlit photos take "
                                         "--setup backlit)")] = False,
    blur_mm: Annotated[float, typer.Option("--blur-mm", min=0, max=1, help="blur every photo "
                                           "by a Gaussian of this sigma (mm at the yarn) "
                                           "first: the fits on photos less sharp than "
                                           "renders")] = 0.0,
    setup: Annotated[str | None, typer.Option(help="capture setup of a folder of photos "
                                              "(frontlit, backlit); a dataset records its "
                                              "own")] = None,
    learned: Annotated[float, typer.Option(min=0, help=_LEARNED_HELP)] = DEFAULT_LEARNED,
    detail: Annotated[float, typer.Option(min=0, help=_DETAIL_HELP)] = 0.0,
    match_size: Annotated[bool, typer.Option("--match-size", help=_MATCH_SIZE_HELP)] = False,
    nets_ply_count: Annotated[bool, typer.Option("--nets-ply-count", help=_NETS_COUNT_HELP)]
    = False,
    sure_count: Annotated[float, typer.Option(min=0, max=1, help=_SURE_COUNT_HELP)]
    = SURE_COUNT,
) -> None:
    """Neural-only vs refined over many photos: `ipm fit --refine` on each, then a table
    (CSV and Markdown) and a figure of photo | neural | refined."""
    import shlex
    import sys

    from ipm.io import write_text
    from ipm.nets.ensemble import Ensemble
    from ipm.refine import compare as cmp
    from ipm.refine.fit import FitOptions

    options = FitOptions(search=SearchOptions(**search_stages_of(params), algorithm=algorithm,
                                              budget=budget, polish=polish),
                         ply_counts=ply_counts,
                         learned=learned, detail=detail, match_size=match_size,
                         choose_count=not nets_ply_count,
                         outside=params == _DEFAULT_PARAMS and prior, sure_count=sure_count)
    listed = cmp.photos_in(photos, pixel_size, count, setup, calibration)
    setup = listed[0].setup
    ensemble = Ensemble.load(models, setup=setup)
    prepare_folder(out)
    settings = {"photos": str(photos), "count": len(listed), "pixel_size_mm": pixel_size,
                **({"calibration": str(calibration)} if calibration else {}),
                "models": str(models) if models else "shipped", "budget": budget,
                "algorithm": algorithm, "params": list(options.search.params), "prior": prior,
                "invert": invert}
    settings |= {"blur_mm": blur_mm} if blur_mm else {}  # only when set: older folders resume
    settings |= {"setup": setup} if setup != "frontlit" else {}
    settings |= {"learned": learned} if learned else {}
    settings |= {"detail": detail} if detail else {}
    settings |= {"ply_counts": ply_counts} if ply_counts > 1 else {}  # (older: one)
    settings |= {"polish": polish} if polish else {}
    settings |= {"match_size": True} if match_size else {}
    settings |= {"sure_count": sure_count}
    count_groups = options.count_groups(setup)
    settings |= {"count_groups": list(count_groups)} if count_groups else {}
    later = options.search.later
    settings |= {"later_stages": [list(s) for s in later]} if later else {}
    saved = out / "settings.json"
    check_same_settings(saved, settings, "a comparison")
    write_text(saved, json.dumps(settings, indent=2) + "\n")
    with progress_bar() as bar:
        task = bar.add_task("fits", total=len(listed))
        s = cmp.compare(listed, out, ensemble, options, prior,
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
