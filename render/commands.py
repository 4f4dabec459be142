"""``ipm render``, ``ipm generate`` and ``ipm doctor``.  Mitsuba is imported inside the
commands only: importing ``ipm`` (and its CLI) must stay light."""

from __future__ import annotations

import json
from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

from ipm.errors import UserError
from ipm.io import check_not_inputs, check_output
from ipm.params import YARN_HELP
from ipm.setups import DEFAULT_SETUP, PHOTO_SETUP_HELP, SETUP_HELP
from ipm.workers import RAY_HELP

DEFAULT_RENDER_SCALE = 0.25
DEFAULT_RENDER_SPP = 16
VariantOpt = Annotated[str | None, typer.Option(
    help="Mitsuba variant: llvm_ad_rgb (default, CPU), cuda_ad_rgb or scalar_rgb; "
         "also the IPM_VARIANT environment variable")]
SetupOpt = Annotated[str, typer.Option(help=SETUP_HELP)]

PhotoSetupOpt = Annotated[str, typer.Option(help=PHOTO_SETUP_HELP)]
CardOpt = Annotated[float | None, typer.Option(
    min=0.0, max=1.0, help="the card's albedo behind a yarn lit from the front, 0 (black) to 1 "
    "(white); default: the scene's dark card")]
ForceOpt = Annotated[bool, typer.Option("--force", help="write over an output that is an "
                                        "input, or a file this command did not make")]


class RenderFormat(str, Enum):
    png = "png"
    xml = "xml"


def render(
    params: Annotated[Path | None, typer.Argument(help=YARN_HELP)]
    = None,
    out: Annotated[Path, typer.Option("-o", "--out", help="image to write (.png); with "
                                      "--format xml, the scene file")] = Path("yarn.png"),
    preset: Annotated[str | None, typer.Option(help="render one of the paper's 12 yarns "
                                               "instead of a JSON file")] = None,
    scale: Annotated[float, typer.Option(help="resolution: 1 = the 2000 x 600 px frame at "
                                         "0.01 mm per pixel")] = DEFAULT_RENDER_SCALE,
    spp: Annotated[int, typer.Option(min=1, help="samples per pixel")] = DEFAULT_RENDER_SPP,
    seed: Annotated[int, typer.Option(help="seed of the fiber generator")] = 1,
    render_seed: Annotated[int, typer.Option(help="seed of the path tracer's sampler")] = 0,
    contact_sheet: Annotated[bool, typer.Option("--contact-sheet", help="render the 12 "
                                                "presets side by side into --out")] = False,
    format: Annotated[RenderFormat, typer.Option(help="png: render; xml: write a Mitsuba "
                                                 "scene (+ curve file) to render elsewhere")]
    = RenderFormat.png,
    variant: VariantOpt = None,
    setup: Annotated[str | None, typer.Option(
        help=f"{SETUP_HELP}; default: the one a fit's params.json or a render's sidecar "
             f"records, else {DEFAULT_SETUP}")] = None,
    card: CardOpt = None,
    force: ForceOpt = False,
) -> None:
    """Render a yarn like a photo of one of the capture setups; writes ``<out>.json`` beside
    the image (parameters, seeds, render settings, setup and ``pixel_size_mm``)."""
    from ipm.params import YarnParams
    from ipm.presets import preset as get_preset
    from ipm.render.scene import frame_size, setup_options

    frame_size(scale)
    if setup is None:
        setup = recorded_setup(params) if params is not None else None
        if setup is not None and setup != DEFAULT_SETUP:
            typer.echo(f"note: rendered {setup}, the setup {params} records; --setup to "
                       "choose", err=True)
    options = setup_options(setup or DEFAULT_SETUP, card)
    check_output(out)
    if format is RenderFormat.png and out.suffix.lower() != ".png":
        raise UserError(f"{out}: ipm render writes PNG images; give a .png name")
    if contact_sheet:
        if params is not None or preset is not None:
            raise UserError("--contact-sheet renders the 12 presets; give no parameters")
        from ipm.render.contact_sheet import contact_sheet as make_sheet

        make_sheet(out, scale=scale, spp=spp, seed=seed, variant=variant, options=options)
        typer.echo(f"contact sheet of the 12 presets -> {out}", err=True)
        return
    if (params is None) == (preset is None):
        raise UserError("give a parameter file or --preset NAME (or --contact-sheet)")
    p = get_preset(preset) if preset else YarnParams.load(params)
    xml = Path(out).with_suffix(".xml")
    check_not_inputs([xml, xml.with_name(xml.stem + "_curves.txt")]
                     if format is RenderFormat.xml else [out, out.with_suffix(".json")],
                     [params], force)
    if format is RenderFormat.xml:
        from ipm.render.export import save_scene_xml

        files = save_scene_xml(out, p, seed, scale=scale, spp=spp, variant=variant,
                               options=options)
        typer.echo(f"Mitsuba scene -> {', '.join(map(str, files))}", err=True)
        return
    from ipm.io import write_text
    from ipm.render.renderer import Renderer, save_png

    renderer = Renderer(variant, options)
    image = renderer.render(p, seed, scale, spp, render_seed)
    save_png(out, image)
    record = {"params": p.to_dict(), "seed": seed, **renderer.settings(scale, spp, render_seed)}
    write_text(out.with_suffix(".json"), json.dumps(record, indent=2) + "\n")
    typer.echo(f"{image.shape[1]}x{image.shape[0]} px, {record['pixel_size_mm']:.4g} mm/px "
               f"-> {out}", err=True)


def recorded_setup(path: Path) -> str | None:
    """The capture setup a yarn file records: a fit's ``params.json`` (its settings) or a
    render's sidecar; None for bare parameters or a file that cannot be read (its reader
    says why)."""
    import os
    import stat

    try:
        if not stat.S_ISREG(os.stat(path).st_mode):
            return None  # a FIFO would block
        d = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(d, dict):
        return None
    settings = d.get("settings")
    found = settings.get("setup") if isinstance(settings, dict) else d.get("setup")
    return found if isinstance(found, str) else None


def _pair(text: str, option: str, what: str, lo: int, hi: int) -> tuple[int, int]:
    """``AxB`` (e.g. 8x6) as two integers in [lo, hi], or a one-line error naming ``option``."""
    try:
        a, b = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise UserError(f"{option} {text!r}: expected {what}, e.g. 8x6") from None
    if not (lo <= a <= hi and lo <= b <= hi):
        raise UserError(f"{option} {text!r}: each must be in {lo}-{hi}")
    return a, b


def _stitches(text: str) -> tuple[int, int]:
    """``WALESxCOURSES`` as two integers in [1, 40]."""
    return _pair(text, "--stitches", "WALESxCOURSES", 1, 40)


def knit(
    params: Annotated[Path, typer.Argument(help=YARN_HELP)],
    out: Annotated[Path, typer.Option("-o", "--out", help="image to write (.png)")]
    = Path("patch.png"),
    pattern: Annotated[str, typer.Option(help="knit | purl | garter | rib (1x1)")] = "knit",
    stitches: Annotated[str, typer.Option(help="WALESxCOURSES")] = "8x6",
    size: Annotated[str, typer.Option(help="image WIDTHxHEIGHT in pixels")] = "1000x1000",
    spp: Annotated[int, typer.Option(min=1, help="samples per pixel")] = DEFAULT_RENDER_SPP,
    seed: Annotated[int, typer.Option(help="seed of the fiber generator (course k uses "
                                      "seed + k)")] = 0,
    render_seed: Annotated[int, typer.Option(help="seed of the path tracer's sampler")] = 0,
    variant: VariantOpt = None,
    force: ForceOpt = False,
) -> None:
    """Knit the yarn into a patch of stitches (ipm/knit.py: Omega loops after Peirce, the
    yarn swept along them) and render it in the scene's lights; writes ``<out>.json``
    beside the image with everything needed to render it again."""
    from ipm.io import write_text
    from ipm.knit import faces
    from ipm.params import YarnParams
    from ipm.render.patch import knit_and_render
    from ipm.render.renderer import Renderer, save_png

    p = YarnParams.load(params)
    wales, courses = _stitches(stitches)
    faces(pattern, 1, 1)  # an unknown pattern fails before any work
    width, height = _pair(size, "--size", "WIDTHxHEIGHT in pixels", 16, 8000)
    check_output(out)
    if out.suffix.lower() != ".png":
        raise UserError(f"{out}: ipm knit writes PNG images; give a .png name")
    check_not_inputs([out, out.with_suffix(".json")], [params], force)
    image, record, patch = knit_and_render(Renderer(variant), p, pattern, (wales, courses),
                                           (width, height), spp, seed, render_seed)
    save_png(out, image)
    write_text(out.with_suffix(".json"), json.dumps(record, indent=2) + "\n")
    typer.echo(f"{pattern} {wales}x{courses}, {patch.fibers.num_fibers} fibers, "
               f"{width}x{height} px at {record['pixel_size_mm']:.4g} mm/px -> {out}", err=True)


def doctor() -> None:
    """Report what rendering and training need (Mitsuba variants, libLLVM, torch device,
    threads) and how to fix what is missing."""
    from ipm.render.doctor import checks

    failed = 0
    for c in checks():
        failed += c.required and not c.ok
        mark = "ok " if c.ok else ("BAD" if c.required else "-- ")
        typer.echo(f"{mark} {c.name:20s} {c.detail}")
        if c.fix and not c.ok:
            typer.echo(f"    fix: {c.fix}")
    typer.echo("everything needed works" if not failed else f"{failed} problem(s); see fix lines")


def generate(
    out: Annotated[Path, typer.Option("--out", "-o", help="dataset folder (created; a rerun "
                                      "with the same settings completes it)")],
    count: Annotated[int, typer.Option(min=1, help="number of samples")] = 2000,
    seed: Annotated[int, typer.Option(help="master seed: sample i depends only on (seed, "
                                      "split, i)")] = 0,
    split: Annotated[str, typer.Option(help="split name recorded per sample (train, val)")]
    = "train",
    scale: Annotated[float | None, typer.Option(help="resolution (1 = 2000 x 600 px); "
                                                "default 0.25")] = None,
    spp: Annotated[str | None, typer.Option(help="samples per pixel, default 6; a range "
                                            "like 4-24 draws each sample's count "
                                            "log-uniformly (seeded), for nets robust to the "
                                            "noise level")] = None,
    workers: Annotated[int | None, typer.Option(min=1, help="render processes; default: one "
                                                "per core")] = None,
    photometric: Annotated[bool, typer.Option(help="vary exposure, white balance, yarn shift "
                                              "and rotation and sensor noise per sample "
                                              "(seeded, recorded in the manifest)")] = True,
    vary_look: Annotated[bool, typer.Option("--vary-look", help="also vary the lamps' and "
                                            "the backdrop's strength, the soft boxes' "
                                            "places, defocus, vignetting, tone curve and "
                                            "JPEG compression per sample, so that nets do "
                                            "not learn one look")] = False,
    vary_material: Annotated[bool, typer.Option("--vary-material", help="also vary how much "
                                                "light a fiber stops (lit from behind) and the "
                                                "room's "
                                                "fill light per sample, so that nets do not "
                                                "learn one fiber material")] = False,
    view: Annotated[tuple[int, int] | None, typer.Option(help="render only a WIDTH HEIGHT "
                                                         "px window at the scale's pitch, "
                                                         "centred on the yarn: detail "
                                                         "data for fine-pitch nets (with "
                                                         "--scale 1, 0.01 mm per px)")]
    = None,
    variant: VariantOpt = None,
    setup: SetupOpt = DEFAULT_SETUP,
    card: CardOpt = None,
    ray: Annotated[str | None, typer.Option(help=RAY_HELP)] = None,
    yarns: Annotated[str, typer.Option(help="the kind of yarns drawn: knitting (the paper's "
                                       "sampler) or fine (spun yarns 0.15-0.6 mm thick, as "
                                       "a microscope sees them)")] = "knitting",
) -> None:
    """Make the synthetic dataset: guided-prior yarns rendered in THE scene of one capture
    setup, with ``manifest.jsonl`` (one JSON object per sample) and ``images/``."""
    from ipm.progress import progress_bar
    from ipm.render.dataset import (
        DEFAULT_SCALE,
        DEFAULT_SPP,
        GenerateOptions,
        generate_dataset,
        spp_range,
    )
    from ipm.render.photometric import NO_VARIATION, PhotometricRanges
    from ipm.render.scene import setup_options

    spp_min, spp_max = spp_range(spp) if spp is not None else (DEFAULT_SPP, None)
    if (vary_look or vary_material) and not photometric:
        flag = "--vary-look" if vary_look else "--vary-material"
        raise UserError(f"{flag} varies the photometric capture; drop --no-photometric")
    opts = GenerateOptions(count=count, seed=seed, split=split,
                           scale=DEFAULT_SCALE if scale is None else scale,
                           spp=spp_min, spp_max=spp_max,
                           photometric=(PhotometricRanges(look=vary_look, material=vary_material)
                                        if photometric
                                        else NO_VARIATION),
                           scene=setup_options(setup, card), view=view, yarns=yarns)
    with progress_bar("{task.fields[rate]}") as bar:
        task = bar.add_task(f"{split} -> {out}", total=count, rate="")
        start: list[tuple[float, int]] = []

        def progress(done: int, total: int) -> None:
            import time

            now = time.monotonic()
            start.append((now, done)) if not start else None
            t0, d0 = start[0]
            rate = (done - d0) / (now - t0) * 3600 if now > t0 and done > d0 else 0.0
            bar.update(task, completed=done, rate=f"{rate:,.0f} img/h" if rate else "")

        records = generate_dataset(out, opts, workers=workers, variant=variant,
                                   progress=progress, ray=ray)
    extra = sum(r.index >= count for r in records)
    typer.echo(f"{len(records)} samples in {out}" + (f" ({extra} beyond --count {count}, from "
               "an earlier run, kept)" if extra else ""), err=True)
