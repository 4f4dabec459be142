"""The ``ipm`` command.  Each sub-command lives beside the code it drives and is registered
here; a :class:`~ipm.errors.UserError` becomes one line on stderr and exit status 2."""

from __future__ import annotations

import sys
from enum import Enum
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ipm.errors import UserError
from ipm.io import check_not_inputs, check_output, write_text
from ipm.params import YARN_HELP
from ipm.photo import CALIBRATION_HELP, PIXEL_SIZE_HELP
from ipm.render.commands import ForceOpt, PhotoSetupOpt
from ipm.setups import AUTO_SETUP

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  rich_markup_mode=None,
                  help="Fiber-level procedural yarn models from one macro photo.")


def _version(value: bool) -> None:
    if value:
        from importlib.metadata import PackageNotFoundError, version

        try:
            typer.echo(f"ipm {version('ipm')}")
        except PackageNotFoundError:
            typer.echo("ipm (not installed: run from a source tree)")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True,
                                          help="print ipm's version and exit")] = False,
) -> None:
    """Fiber-level procedural yarn models from one macro photo."""


@app.command()
def sample(
    out: Annotated[Path | None, typer.Option("-o", "--out", help="JSON file to write; "
                                             "stdout if omitted")] = None,
    seed: Annotated[int, typer.Option(help="seed of the guided sampler")] = 0,
    preset: Annotated[str | None, typer.Option(help="one of the paper's 12 real yarns "
                                               "(see `ipm presets`) instead of a random draw")]
    = None,
) -> None:
    """Write the parameters of a plausible random yarn (the paper's guided sampler), or of a
    preset, as a flat JSON object keyed by the paper's symbols."""
    from ipm.presets import preset as get_preset
    from ipm.prior import GuidedPrior

    _emit(get_preset(preset) if preset else GuidedPrior().sample(np.random.default_rng(seed)),
          out)


def _emit(params, out: Path | None, inputs: tuple[Path, ...] = (), force: bool = False
          ) -> None:
    """Yarn parameters as JSON to ``out``, or to stdout without one; never over one of
    ``inputs`` unless ``force``."""
    if out is None:
        typer.echo(params.to_json())
        return
    check_output(out)
    check_not_inputs([out], list(inputs), force)
    write_text(out, params.to_json() + "\n")


@app.command()
def presets() -> None:
    """List the paper's 12 real yarns."""
    from ipm.presets import PRESET_NAMES, preset

    for name in PRESET_NAMES:
        p = preset(name)
        typer.echo(f"{name:11s} n={p.n} m={p.m:3d} R_ply={p.R_ply:.3f} alpha_ply={p.alpha_ply:6.3f}"
                   f" alpha={p.alpha:6.3f} g={p.g}")


class CurveFormat(str, Enum):
    npz = "npz"
    mitsuba = "mitsuba"
    usd = "usd"
    ply = "ply"


#: The suffixes each curve format is written with (the first is its usual one).
CURVE_SUFFIXES = {CurveFormat.npz: (".npz",), CurveFormat.mitsuba: (".txt",),
                  CurveFormat.usd: (".usda", ".usd", ".usdc"), CurveFormat.ply: (".ply",)}


def curve_format(out: Path, given: CurveFormat | None) -> CurveFormat:
    """The format ``ipm curves`` writes ``out`` in: ``given``, or the one of its suffix; a
    suffix of another format than ``given`` (or one USD cannot write), or an unknown suffix
    without ``given``, is a one-line error."""
    suffix = out.suffix.lower()
    of_suffix = next((f for f, sfx in CURVE_SUFFIXES.items() if suffix in sfx), None)
    if given is None:
        if of_suffix is None:
            known = ", ".join(s for sfx in CURVE_SUFFIXES.values() for s in sfx)
            raise UserError(f"{out}: cannot tell the format from its suffix; name it {known}, "
                            "or give --format")
        return of_suffix
    if of_suffix not in (given, None) or (given is CurveFormat.usd and of_suffix is None):
        written = " or ".join(CURVE_SUFFIXES[given])
        raise UserError(f"{out}: --format {given.value} writes {written} files, not "
                        f"{suffix or 'a name without a suffix'}; change the suffix or drop "
                        "--format")
    return given


@app.command()
def curves(
    params: Annotated[Path, typer.Argument(help=YARN_HELP)],
    out: Annotated[Path, typer.Option("-o", "--out", help="file to write")],
    seed: Annotated[int, typer.Option(help="seed of the fiber generator")] = 0,
    format: Annotated[CurveFormat | None, typer.Option(help="npz: arrays (points, offsets, "
                                                       "radii, kind, ply); mitsuba: a "
                                                       "linearcurve file (.txt); usd: a "
                                                       "BasisCurves prim (.usda text, .usd/"
                                                       ".usdc binary); ply: polylines; "
                                                       "default: by the suffix of --out")]
    = None,
    knit: Annotated[str | None, typer.Option(help="the fibers of a knitted patch of this "
                                             "pattern (knit, purl, garter, rib) instead of "
                                             "a straight yarn")] = None,
    stitches: Annotated[str, typer.Option(help="with --knit: WALESxCOURSES")] = "8x6",
    force: ForceOpt = False,
) -> None:
    """Generate the yarn's fibers (mm; a straight yarn along z, or with --knit a patch in
    the xy plane, knit face towards +z) and write them."""
    from ipm.generator import generate
    from ipm.params import YarnParams

    p = YarnParams.load(params)
    check_output(out)
    check_not_inputs([out], [params], force)
    format = curve_format(out, format)
    if knit is None:
        fs = generate(p, seed)
    else:
        from ipm.knit import knit_patch
        from ipm.render.commands import _stitches

        fs = knit_patch(p, knit, *_stitches(stitches), seed).fibers
    {CurveFormat.npz: fs.save_npz, CurveFormat.mitsuba: fs.save_mitsuba,
     CurveFormat.usd: fs.save_usd, CurveFormat.ply: fs.save_ply}[format](out)
    typer.echo(f"{fs.num_fibers} fibers, {len(fs.points)} vertices -> {out}", err=True)


@app.command()
def edit(
    params: Annotated[Path, typer.Argument(help=YARN_HELP)],
    set_: Annotated[list[str], typer.Option("--set", help="NAME=VALUE or NAME=*FACTOR, e.g. "
                                            "alpha_ply=*0.5 (repeat for several)")],
    out: Annotated[Path | None, typer.Option("-o", "--out", help="JSON file to write; "
                                             "stdout if omitted")] = None,
    force: ForceOpt = False,
) -> None:
    """Make a new yarn from one: set or scale parameters (each result must stay inside its
    interval), as the paper's editing figure (twist changed, flyaways doubled)."""
    from ipm.edit import apply_edits
    from ipm.params import YarnParams

    _emit(apply_edits(YarnParams.load(params), set_), out, (params,), force)


@app.command()
def calibrate(
    ruler: Annotated[Path, typer.Argument(help="photo of a millimetre scale, taken with the "
                                          "same camera, lens and distance as the yarn")],
    out: Annotated[Path | None, typer.Option("-o", "--out", help="calibration file to write "
                                             "(JSON, for `ipm fit --calibration`)")] = None,
    tick_mm: Annotated[float, typer.Option(help="distance between the scale's finest ticks "
                                           "(mm)")] = 1.0,
    force: ForceOpt = False,
) -> None:
    """Measure the pixel size (mm per pixel) of a capture setup from a photo of a ruler:
    every length ipm reports comes from it."""
    from ipm.calibrate import calibrate as measure
    from ipm.photo import read_image

    if not (tick_mm > 0 and np.isfinite(tick_mm)):
        raise UserError(f"--tick-mm must be a positive number, got {tick_mm}")
    if out is not None:
        check_output(out)
        check_not_inputs([out], [ruler], force)
    cal = measure(read_image(ruler).mean(axis=2), str(ruler), tick_mm)
    typer.echo(f"{cal.pixel_size_mm:.6g} mm per pixel ({cal.tick_period_px:.2f} px per "
               f"{tick_mm:g} mm, scale at {cal.angle_deg:.1f} deg)")
    if out is not None:
        write_text(out, cal.to_json() + "\n")


@app.command()
def measure(
    photos: Annotated[list[Path], typer.Argument(help="photos of yarns, or folders of them")],
    out: Annotated[Path | None, typer.Option("-o", "--out", help="folder (created) for "
                                             "each photo's <name>.json and <name>.png (the "
                                             "measures drawn over the photo), and for "
                                             "several photos measures.csv and measures.png")]
    = None,
    pixel_size: Annotated[float | None, typer.Option(help=PIXEL_SIZE_HELP)] = None,
    calibration: Annotated[Path | None, typer.Option(help=CALIBRATION_HELP)] = None,
    setup: PhotoSetupOpt = AUTO_SETUP,
    plies: Annotated[int | None, typer.Option(min=1, help="the yarn's ply count, if known: "
                                              "turns the ply period into turns per metre")]
    = None,
    force: ForceOpt = False,
) -> None:
    """Measure yarn photos as a textile lab reports them, without the nets: diameter and its
    CV along the yarn, ply twist (turns per metre with --plies, S or Z), hairiness (Uster's
    H, Zweigle-type counts per distance) and the hairs' lengths (docs/measure.md).  Every
    photo that can be read is measured; each that cannot is listed (exit 1)."""
    from ipm.dataset import photo_files
    from ipm.io import prepare_folder
    from ipm.photo import Photo, pixel_size_of
    from ipm.setups import setup_of

    files = [f for p in photos for f in (photo_files(p) if p.is_dir() else [p])]
    if not files:
        raise UserError(f"{', '.join(map(str, photos))} holds no photos")
    several = len(files) > 1
    if out is not None:
        if out.exists() and not out.is_dir():
            raise UserError(f"--out {out} is a file; give a folder")
        stems = {}
        for f in files:
            if f.stem in stems:
                raise UserError(f"two photos share a name, {stems[f.stem]} and {f}: their "
                                f"files would collide in {out}; rename one")
            stems[f.stem] = f
        targets = [out / f"{f.stem}{sfx}" for f in files for sfx in (".json", ".png")]
        sidecars = [f.with_suffix(".json") for f in files]
        check_not_inputs(targets + [out / "measures.csv", out / "measures.png"],
                         [*files, *sidecars], force)
        prepare_folder(out)
    done, failed = [], []
    for i, file in enumerate(files):
        try:
            size = pixel_size_of(file, pixel_size, calibration)
            photo, note = Photo.read(file, size).with_setup(setup)
            photo, turned = photo.upright()
            photo.check_view()
            from ipm.textile.image import analyse  # scipy: after the photo's checks

            gray = photo.image.mean(axis=2)
            m, drawing = analyse(gray, size, setup_of(photo.setup).light_behind, plies)
        except UserError as e:
            message = str(e)
            named = message if message.startswith(str(file)) else f"{file}: {message}"
            typer.echo(f"error: {named}", err=True)
            failed.append(file)
            continue
        for n in (note, turned):
            if n and not several:
                typer.echo(n, err=True)
        if several:
            typer.echo(f"[{i + 1}/{len(files)}] {file.name}: diameter {m.diameter_mm:.3f} mm "
                       f"(CV {m.diameter_cv_pct:.1f}%), H {m.hairiness_h:.3g}, twist "
                       f"{m.twist_direction or '?'}")
        else:
            typer.echo("\n".join(m.summary()))
        if out is not None:
            from ipm.photo import write_png
            from ipm.textile.report import overlay, write_json

            write_json(out / f"{file.stem}.json", m)
            write_png(out / f"{file.stem}.png", overlay(gray, m, drawing))
            done.append((file, m))
    if out is not None and several and done:
        from ipm.textile.report import row, write_csv, write_plots

        write_csv(out / "measures.csv", [row(f.name, m) for f, m in done])
        write_plots(out / "measures.png", [f.stem for f, _ in done], [m for _, m in done])
    if failed:
        typer.echo(f"{len(failed)} of {len(files)} photos failed", err=True)
        raise typer.Exit(1)


# render/
from ipm.render import commands as render_commands  # noqa: E402  (mitsuba loads lazily)

app.command("render")(render_commands.render)
app.command("generate")(render_commands.generate)
app.command("doctor")(render_commands.doctor)
app.command("knit")(render_commands.knit)


# nets/
from ipm.nets import commands as nets_commands  # noqa: E402  (torch is imported lazily inside)

app.command("train")(nets_commands.train)
app.command("predict")(nets_commands.predict)
app.command("saliency")(nets_commands.saliency)

# refine/
from ipm.refine import commands as refine_commands  # noqa: E402

app.command("fit")(refine_commands.fit)
app.command("compare")(refine_commands.compare)

# benchmarks/
from ipm.benchmarks import commands as bench_commands  # noqa: E402

app.command("bench")(bench_commands.bench)


class Interrupted(Exception):
    """Ctrl-C or a SIGTERM (its number the argument), raised from the signal handler: not a
    KeyboardInterrupt, which the command line library would turn into a silent exit."""


def main() -> None:
    """Run the command line: a :class:`UserError` is one line and exit 2, Ctrl-C (SIGINT) one
    line and exit 130, SIGTERM the same with exit 143 (what was written stays: every output
    is written atomically)."""
    import signal
    import warnings

    def interrupt(*_args) -> None:
        raise Interrupted

    def terminate(*_args) -> None:
        raise Interrupted(signal.SIGTERM)

    def one_line(message, *_args, **_kwargs) -> None:
        typer.echo(f"warning: {message}", err=True)

    signal.signal(signal.SIGINT, interrupt)
    signal.signal(signal.SIGTERM, terminate)
    warnings.showwarning = one_line
    try:
        app()
    except UserError as e:
        typer.echo(f"error: {e}", err=True)
        sys.exit(2)
    except (Interrupted, KeyboardInterrupt) as e:
        typer.echo("interrupted; the files written so far are complete and kept", err=True)
        sys.exit(128 + (signal.SIGTERM if e.args == (signal.SIGTERM,) else signal.SIGINT))
