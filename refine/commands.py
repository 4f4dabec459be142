"""``ipm fit``: the user's entry point to the nets and the refinement.  Heavy imports
(torch, mitsuba, kornia) happen inside the command."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from ipm.errors import UserError
from ipm.frame import PIXEL_SIZE_MM
from ipm.io import check_writable_folder


def _prepare_folder(folder: Path) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UserError(f"cannot create output folder {folder}: {e.strerror}") from None
    check_writable_folder(folder)


def fit(
    photo: Annotated[Path, typer.Argument(help="photo of a yarn running horizontally (PNG, "
                                          "JPEG or TIFF; 8 or 16 bit)")],
    out: Annotated[Path, typer.Option("--out", "-o", help="folder for params.json, the "
                                      "renders and compare.png")] = Path("fit"),
    refine: Annotated[bool, typer.Option("--refine/--no-refine", help="refine the nets' "
                                         "guess by render-and-compare")] = False,
    pixel_size: Annotated[float, typer.Option(help="mm per photo pixel at the yarn (the "
                                              "scene's is 0.01)")] = PIXEL_SIZE_MM,
    models: Annotated[Path | None, typer.Option(help="trained ensemble folder (default: the "
                                                "models shipped with ipm)")] = None,
    budget: Annotated[int, typer.Option(help="objective evaluations of the search")] = 80,
    time_limit: Annotated[float | None, typer.Option("--time", help="wall-time bound of the "
                                                     "search, seconds")] = None,
    algorithm: Annotated[str, typer.Option(help="NLopt algorithm")] = "LN_BOBYQA",
    prior: Annotated[bool, typer.Option("--prior/--no-prior", help="keep the search near the "
                                        "nets' guess, weighted by the nets' validation error "
                                        "(MAP); --no-prior: the image loss alone")] = True,
    invert: Annotated[bool, typer.Option("--invert", help="invert the photo first (backlit: "
                                         "dark yarn on a light background)")] = False,
    variant: Annotated[str | None, typer.Option(help="Mitsuba variant")] = None,
) -> None:
    """Infer a yarn's parameters from a photo: the neural ensemble, and with --refine a
    render-and-compare search; writes params.json (neural and refined parameters, their
    losses, the settings), neural.png, refined.png and compare.png (photo | neural |
    refined)."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from ipm.io import write_text
    from ipm.photo import read_image, write_png
    from ipm.refine.fit import FitOptions, compare_image, display_renders, fit
    from ipm.refine.search import SearchOptions
    from ipm.render.renderer import Renderer

    options = FitOptions(search=SearchOptions(algorithm=algorithm, budget=budget,
                                              time_s=time_limit))
    image = read_image(photo)
    if invert:
        image = 1 - image
    _prepare_folder(out)
    from ipm.nets.ensemble import Ensemble

    ensemble = Ensemble.load(models)
    neural = ensemble.predict(image, pixel_size)
    renderer = Renderer(variant)
    columns = (TextColumn("{task.description}"), BarColumn(),
               TextColumn("{task.completed}/{task.total} renders, best loss {task.fields[best]}"),
               TimeRemainingColumn())
    with Progress(*columns, transient=True) as bar:
        task = bar.add_task("refining" if refine else "scoring", total=budget, best="-")
        result = fit(image, pixel_size, neural, renderer, options, refine,
                     on_eval=lambda i, loss, best: bar.update(task, completed=i,
                                                             best=f"{best:.4f}"),
                     sigma=ensemble.sigma() if prior else None)
    for w in result.warnings:
        typer.echo(f"warning: {w}", err=True)
    shown, neural_img, refined_img = display_renders(renderer, image, pixel_size, result,
                                                     options)
    write_png(out / "neural.png", neural_img)
    panels, labels = [shown, neural_img], ["photo", f"neural  loss {result.loss_neural:.4f}"]
    if refine:
        write_png(out / "refined.png", refined_img)
        panels.append(refined_img)
        labels.append(f"refined  loss {result.loss_refined:.4f}"
                      + ("" if result.improved else "  (no improvement: neural kept)"))
    write_png(out / "compare.png", compare_image(panels, labels))
    write_text(out / "params.json", json.dumps(result.to_dict(options, pixel_size), indent=2))
    typer.echo(f"loss neural {result.loss_neural:.4f} -> refined {result.loss_refined:.4f} "
               f"({result.seconds:.0f} s); wrote {out}/params.json, compare.png", err=True)
