"""``ipm train``, ``ipm predict``, ``ipm saliency``.  torch is imported inside the commands,
so ``import ipm`` and ``ipm --help`` stay light."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ipm.errors import UserError
from ipm.photo import CALIBRATION_HELP, PIXEL_SIZE_HELP
from ipm.render.commands import ForceOpt, PhotoSetupOpt, SetupOpt
from ipm.setups import AUTO_SETUP, DEFAULT_SETUP, INVERT_HELP

_MODELS_HELP = ("folder with ensemble.json (an `ipm train --out`); default: the models "
                "shipped for --setup")


def train(
    data: Annotated[Path, typer.Option(help="training set (`ipm generate --out`)")],
    val: Annotated[Path, typer.Option(help="validation set, other seeds")],
    out: Annotated[Path, typer.Option(help="run folder; an existing run is resumed")],
    preset: Annotated[str, typer.Option(help="ensemble | reg | reg-ae | reg-latent | "
                                        "reg-ae-latent")] = "ensemble",
    real: Annotated[Path | None, typer.Option(help="unlabelled real photos for L_recon / "
                                              "L_latent")] = None,
    nets: Annotated[str | None, typer.Option(help="comma-separated subset of the preset's "
                                             "nets, e.g. alpha,R_ply")] = None,
    paper: Annotated[bool, typer.Option("--paper", help="the paper's configuration: ResNet "
                                        "width 1 at 1200x584, 1000 epochs, lr 1e-4 (GPU)")]
    = False,
    encoder: Annotated[str | None, typer.Option(help="resnet18 | resnet34 | convnext")] = None,
    width: Annotated[float | None, typer.Option(help="channel width multiplier (1 = paper)")]
    = None,
    input_scale: Annotated[float | None, typer.Option(help="input resolution relative to the "
                                                      "paper's 1200x584 crop")] = None,
    crop: Annotated[tuple[int, int] | None, typer.Option(help="input HEIGHT WIDTH in px "
                                                         "instead of the paper's crop at "
                                                         "--input-scale: a detail net on "
                                                         "`ipm generate --view` data")]
    = None,
    epochs: Annotated[int | None, typer.Option()] = None,
    batch_size: Annotated[int | None, typer.Option(help="global batch (split over torchrun "
                                                   "processes)")] = None,
    lr: Annotated[float | None, typer.Option(help="Adam learning rate")] = None,
    schedule: Annotated[str | None, typer.Option(help="cosine | constant (learning rate over "
                                                 "the epochs)")] = None,
    lambda_recon: Annotated[float | None, typer.Option()] = None,
    lambda_latent: Annotated[float | None, typer.Option()] = None,
    steps_per_epoch: Annotated[int | None, typer.Option(help="cap steps per epoch (smoke "
                                                        "tests)")] = None,
    seed: Annotated[int | None, typer.Option()] = None,
    device: Annotated[str | None, typer.Option(help="cpu | cuda | cuda:N")] = None,
    workers: Annotated[int | None, typer.Option(help="data loader processes")] = None,
    real_pixel_size: Annotated[float | None, typer.Option(help="pixel size of the --real "
                                                          "photos in mm")] = None,
    real_invert: Annotated[bool, typer.Option("--real-invert", help="invert the --real "
                                              "photos (dark yarn on light)")] = False,
    blur: Annotated[float | None, typer.Option(help="blur each training crop by a Gaussian of "
                                               "sigma uniform in [0, BLUR] input pixels "
                                               "(a photo's defocus; 0 = off)")] = None,
    look: Annotated[bool, typer.Option("--look", help="give each training crop another look: "
                                       "colour, saturation, backdrop, noise, tone "
                                       "(nets.data.LOOK_JITTER), so the nets read the yarn, "
                                       "not one scene's look")] = False,
    init: Annotated[Path | None, typer.Option(help="start each net from the trained net of "
                                              "the same name in this folder (fine-tuning; "
                                              "e.g. the shipped models)")] = None,
    setup: SetupOpt = DEFAULT_SETUP,
) -> None:
    """Train the nets of a preset on a synthetic dataset (resumable; torchrun for DDP).  The
    nets are for photos of one capture setup, that of the renders (--setup; recorded in
    ensemble.json, and checked against the datasets' manifests)."""
    from ipm.nets.config import TrainConfig
    from ipm.nets.train import train as run

    given = dict(encoder=encoder, width=width, input_scale=input_scale, epochs=epochs,
                 batch_size=batch_size, lr=lr, schedule=schedule, lambda_recon=lambda_recon,
                 lambda_latent=lambda_latent, steps_per_epoch=steps_per_epoch, seed=seed,
                 device=device, workers=workers, real_pixel_size=real_pixel_size, init=init,
                 blur_px=blur, crop=crop)
    options = {k: v for k, v in given.items() if v is not None} | ({"look": True} if look else {})
    options.update(data=data, val=val, out=out, preset=preset, real=real, setup=setup,
                   real_invert=real_invert,
                   nets=tuple(n.strip() for n in nets.split(",") if n.strip()) if nets else ())
    cfg = TrainConfig.paper(**options) if paper else TrainConfig(**options)
    run(cfg, log=lambda line: typer.echo(line, err=True))
    typer.echo(f"models -> {cfg.out}", err=True)


def predict(
    photos: Annotated[list[Path], typer.Argument(help="photos of yarns running horizontally, "
                                                 "or folders of them")],
    out: Annotated[Path | None, typer.Option("-o", "--out", help="JSON file to write; for "
                                             "several photos a folder (created), one "
                                             "`<photo name>.json` each")] = None,
    pixel_size: Annotated[float | None, typer.Option(help=PIXEL_SIZE_HELP)] = None,
    calibration: Annotated[Path | None, typer.Option(help=CALIBRATION_HELP)] = None,
    models: Annotated[Path | None, typer.Option(help=_MODELS_HELP)] = None,
    crops: Annotated[int, typer.Option(help="crops along the yarn to average")] = 3,
    invert: Annotated[bool, typer.Option("--invert", help=INVERT_HELP)] = False,
    device: Annotated[str, typer.Option(help="cpu | cuda")] = "cpu",
    setup: PhotoSetupOpt = AUTO_SETUP,
    force: ForceOpt = False,
) -> None:
    """Infer the yarn parameters from photos with the neural ensemble, in one process.  One
    photo: prints the parameters and writes them to --out as flat JSON (the form `ipm
    curves` reads); several photos or a folder: one JSON per photo in the folder --out,
    every photo that can be read done, each that cannot listed (exit 1)."""
    from ipm.dataset import photo_files
    from ipm.io import check_not_inputs, check_output, prepare_folder
    from ipm.nets.config import PredictConfig

    files = [f for p in photos for f in (photo_files(p) if p.is_dir() else [p])]
    if not files:
        raise UserError(f"{', '.join(map(str, photos))} holds no photos")
    cfg = PredictConfig(tuple(files), models, crops, invert, device, setup)
    single = len(photos) == 1 and not photos[0].is_dir()
    if single:
        targets = [out]
        if out is not None:
            check_output(out)
    else:
        if out is None:
            raise UserError("several photos: give --out FOLDER for their JSON files")
        targets = [out / f"{f.stem}.json" for f in files]
        seen: dict[Path, Path] = {}
        for f, t in zip(files, targets, strict=True):
            if t in seen:
                raise UserError(f"two photos share a name, {seen[t]} and {f}: their JSON files "
                                f"would collide in {out}; rename one")
            seen[t] = f
    sidecars = [f.with_suffix(".json") for f in files if _is_file(f.with_suffix(".json"))]
    check_not_inputs([t for t in targets if t is not None], [*files, *sidecars], force)
    if single:
        _predict_one(cfg, files[0], targets[0], pixel_size, calibration, {}, set(), True)
        return
    made = not out.exists()
    prepare_folder(out)
    ensembles: dict[str, object] = {}
    warned: set[float] = set()
    failed = []
    try:
        for file, target in zip(cfg.photos, targets, strict=True):
            try:
                _predict_one(cfg, file, target, pixel_size, calibration, ensembles, warned,
                             False)
            except UserError as e:
                if isinstance(e, ModelsError):
                    raise
                message = str(e)
                named = message if message.startswith(str(file)) else f"{file}: {message}"
                typer.echo(f"error: {named}", err=True)
                failed.append(file)
    finally:
        if made and out.is_dir() and not any(out.iterdir()):
            out.rmdir()  # nothing written: no empty folder left behind
    if failed:
        typer.echo(f"{len(failed)} of {len(files)} photos failed; the others' JSON files are "
                   f"in {out}", err=True)
        raise typer.Exit(1)


class ModelsError(UserError):
    """The models cannot be loaded: the same for every photo, so a folder run stops."""


def _is_file(path: Path) -> bool:
    try:
        return path.is_file()
    except OSError:
        return False


def _predict_one(cfg, file: Path, target: Path | None, pixel_size, calibration,
                 ensembles: dict, warned: set, single: bool) -> None:
    """``ipm predict`` of one photo: read at its pixel size, set upright, read as of its
    setup (told and said for ``auto``), predicted; the JSON to stdout (one photo) and to
    ``target``.  ``ensembles`` keeps the nets loaded per setup."""
    from ipm.io import write_text
    from ipm.photo import Photo, pixel_size_of

    size = pixel_size_of(file, pixel_size, calibration)
    shot, note = Photo.read(file, size).upright()
    shot, chosen = shot.with_setup(cfg.setup)
    if note:
        typer.echo(f"note: {note}", err=True)
    if shot.setup not in ensembles:
        try:
            ensembles[shot.setup] = _load(cfg.models, cfg.device, shot.setup)
        except UserError as e:  # (nets of another setup: say how the photo was read)
            raise ModelsError(f"{e}; {chosen}" if chosen else str(e)) from None
    ensemble = ensembles[shot.setup]
    params = ensemble.predict(shot.inverted() if cfg.invert else shot, cfg.crops)
    if chosen:  # once the photo is read: a refused photo needs no note
        typer.echo(f"note: {chosen}", err=True)
    warning = ensemble.upsampling_warning(size)
    if warning and size not in warned:  # after the photo: a size that fails it needs none
        typer.echo(f"warning: {warning}", err=True)
        warned.add(size)
    if single:
        typer.echo(params.to_json())
    else:
        typer.echo(f"{file} -> {target}", err=True)
    if target is not None:
        write_text(target, params.to_json() + "\n")


def saliency(
    photo: Annotated[Path, typer.Argument(help="photo of a yarn running horizontally")],
    param: Annotated[str, typer.Option(help="parameter (e.g. alpha_ply) or net (e.g. "
                                       "flyaways) to explain")],
    out: Annotated[Path, typer.Option("-o", "--out", help="PNG to write (the photo's size)")],
    pixel_size: Annotated[float | None, typer.Option(help=PIXEL_SIZE_HELP)] = None,
    calibration: Annotated[Path | None, typer.Option(help=CALIBRATION_HELP)] = None,
    models: Annotated[Path | None, typer.Option(help=_MODELS_HELP)] = None,
    invert: Annotated[bool, typer.Option("--invert", help="invert the photo first")] = False,
) -> None:
    """The paper's saliency map: per pixel, max over colour channels of |d mean prediction
    / d pixel| of the net that predicts PARAM (white = most influence)."""
    import numpy as np
    from PIL import Image

    from ipm.io import atomic_path, check_not_inputs, check_output
    from ipm.nets.config import SaliencyConfig
    from ipm.photo import Photo, pixel_size_of

    check_output(out)
    check_not_inputs([out], [photo])
    cfg = SaliencyConfig(photo, param, models, pixel_size_of(photo, pixel_size, calibration),
                         invert)
    from ipm.nets.data import to_input  # torch: after the checks, which are one line
    from ipm.nets.saliency import net_for, to_image
    from ipm.nets.saliency import saliency as saliency_map

    shot = Photo.read(cfg.photo, cfg.pixel_size)
    net, columns = net_for(_load(cfg.models, "cpu"), cfg.param, cfg.pixel_size)
    scaled = (shot.inverted() if cfg.invert else shot).at_pitch(net.config.input_scale,
                                                                (32, 32))
    s = saliency_map(net, to_input(scaled)[None], columns)[0].numpy()
    full = np.asarray(Image.fromarray(s.astype(np.float32), mode="F").resize(
        (shot.image.shape[1], shot.image.shape[0]), Image.Resampling.BILINEAR))
    with atomic_path(out) as tmp:
        Image.fromarray(to_image(full), mode="L").save(tmp, format="PNG")
    typer.echo(f"saliency of {param} -> {out}", err=True)


def _load(models: Path | None, device: str, setup: str | None = None):
    from ipm.nets.ensemble import Ensemble

    return Ensemble.load(models, device, setup)
