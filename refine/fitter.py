"""One photo's fit as ``ipm fit`` writes it: the nets' reading, the fit
(:func:`ipm.refine.fit.fit`), the renders shown in the photo's capture, ``compare.png``, the
textile block and ``params.json``, returned as files and terminal lines.  The same code fits
one photo (``ipm fit PHOTO``) and runs in every worker of a folder's fit
(:mod:`ipm.refine.batch`), whose driver writes what it returns: a photo's ``params.json`` is
the same whichever way it was fitted.  How long a fit took is the run's, not the photo's:
``run.json`` beside it."""

from __future__ import annotations

import json
import os
import socket
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from ipm.errors import UserError
from ipm.refine.plan import FitConfig
from ipm.setups import AUTO_SETUP

#: Every file a fit may write into its folder, in the order written: params.json last,
#: so a folder with it holds a whole fit; a fit removes those of an earlier fit it does
#: not write again.
FIT_FILES = ("neural.png", "refined.png", "knit.png", "knit.json", "compare.png",
             "params.json", "run.json")
PARAMS = "params.json"
RUN = "run.json"


@dataclass(frozen=True)
class FitJob:
    """What a fit of a photo is asked beside the photo: ``refine`` (the search), ``knit``
    (a patch of that pattern), ``invert`` (a negative), ``setup`` (a capture setup, or
    ``auto``) and the fit's ``config``."""

    refine: bool = False
    knit: str | None = None
    invert: bool = False
    setup: str = AUTO_SETUP
    config: FitConfig = field(default_factory=FitConfig)


@dataclass
class FitOutput:
    """A fit's files (name to bytes, in :data:`FIT_FILES` order) and its terminal lines
    (notes, warnings, the summary)."""

    files: dict[str, bytes]
    lines: list[str]

    def write(self, folder: Path) -> None:
        """Write the files into ``folder`` (made if needed), each atomically and
        ``params.json`` last, and remove those of an earlier fit not written now."""
        from ipm.io import prepare_folder, write_bytes

        prepare_folder(folder)
        for name in FIT_FILES:
            if name in self.files:
                write_bytes(folder / name, self.files[name])
            else:
                (folder / name).unlink(missing_ok=True)


class Fitter:
    """What fits photos holds: the nets (``models``, the shipped ones if None; bytes of
    :func:`ipm.nets.store.pack_ensemble` on a machine without the folder) and a renderer
    per capture setup, made on first use; ``threads`` for torch and Dr.Jit (None: their
    defaults, every core)."""

    def __init__(self, models: Path | bytes | None = None, variant: str | None = None,
                 threads: int | None = None) -> None:
        if isinstance(models, bytes):
            import atexit
            import shutil

            from ipm.nets.store import unpack_ensemble

            models = unpack_ensemble(models)
            atexit.register(shutil.rmtree, models, ignore_errors=True)
        self.models, self.variant, self.threads = models, variant, threads
        self._nets: dict[str, object] = {}
        self._renderers: dict[str, object] = {}
        if threads is not None:
            import torch

            torch.set_num_threads(threads)

    def nets(self, setup: str):
        from ipm.nets.ensemble import Ensemble

        if setup not in self._nets:
            self._nets[setup] = Ensemble.load(self.models, setup=setup)
        return self._nets[setup]

    def renderer(self, setup: str):
        from ipm.render.renderer import Renderer
        from ipm.render.scene import setup_options

        if setup not in self._renderers:
            self._renderers[setup] = Renderer(self.variant, setup_options(setup), self.threads)
        return self._renderers[setup]

    def fit_file(self, name: str, data: bytes, pixel_size: float, job: FitJob) -> dict:
        """A worker's task: the fit of the photo file ``name`` (its bytes ``data``) as
        ``{"files", "lines", "seconds", "worker"}``, or ``{"error": one line, "worker"}``
        for a photo that cannot be fitted (any other exception too: one photo's failure
        must not end a folder's run)."""
        t0 = time.perf_counter()
        worker = {"host": socket.gethostname(), "pid": os.getpid()}
        if "ray" in sys.modules and sys.modules["ray"].is_initialized():  # a Ray actor's node
            worker["node"] = sys.modules["ray"].get_runtime_context().get_node_id()[:12]
        try:
            out = self.fit(read_shot(name, pixel_size, job, data), job)
        except UserError as e:
            return {"error": str(e), "worker": worker}
        except Exception as e:  # noqa: BLE001  (a bug: said, and the other photos go on)
            return {"error": f"{name}: internal error ({type(e).__name__}: {e}); please report "
                             "it", "worker": worker}
        return {"files": out.files, "lines": out.lines,
                "seconds": time.perf_counter() - t0, "worker": worker}

    def fit(self, read: Shot, job: FitJob,
            bar: Callable[[int], Callable[[int, float, float], None]] | None = None,
            say: Callable[[str], None] | None = None) -> FitOutput:
        """Fit the photo ``read`` (:func:`read_shot`); ``bar(total)``: a progress callback
        ``(evaluation, loss, best)`` for the fit's renders, or None; ``say``: called with
        each terminal line as it comes (else they are only returned)."""
        from ipm.photo import png_bytes
        from ipm.refine.capture import card_warning
        from ipm.refine.display import (
            compare_image,
            display_renders,
            summary_lines,
            textile_block,
            textile_lines,
        )
        from ipm.refine.fit import fit

        config, refine, knit = job.config, job.refine, job.knit
        shot, chosen = read.photo, read.chosen
        pixel_size = shot.pixel_size_mm
        lines: list[str] = []

        def tell(line: str) -> None:
            lines.append(line)
            if say:
                say(line)

        for line in read.lines:
            tell(line)
        try:
            ensemble = self.nets(shot.setup)
        except UserError as e:  # (nets of another setup: say how the photo was read)
            raise UserError(f"{e}; {chosen}" if chosen else str(e)) from None
        neural = ensemble.predict(shot)
        if chosen:
            tell(f"note: {chosen}")
        renderer = self.renderer(shot.setup)
        total = config.budget * len(config.stage_params(shot.setup)) * config.ply_counts
        result = fit(shot, neural, renderer, config, refine,
                     on_eval=bar(total) if bar else None,
                     sigma=ensemble.sigma(pixel_size) if config.prior else None,
                     count_prior=ensemble.ply_count_probabilities(shot),
                     readings=ensemble.readings,
                     detail=ensemble.detail_readings(pixel_size))
        if w := ensemble.upsampling_warning(pixel_size):
            result.warnings.insert(0, w)
        shown, neural_img, refined_img, capture = display_renders(renderer, shot, result, config)
        if w := card_warning(capture, shot.setup):
            result.warnings.append(w)
        for w in result.warnings:
            tell(f"warning: {w}")
        files = {"neural.png": png_bytes(neural_img)}
        panels, labels = [shown, neural_img], ["photo", f"neural  loss {result.loss_neural:.4f}"]
        if refine:
            files["refined.png"] = png_bytes(refined_img)
            panels.append(refined_img)
            labels.append(f"refined  loss {result.loss_refined:.4f}"
                          + ("" if result.improved else "  (no improvement: neural kept)"))
        fitted = result.refined if refine else result.neural
        if knit is not None:
            image, record = knit_panel(renderer, fitted, knit, panels[0].shape[1])
            files |= {"knit.png": png_bytes(image),
                      "knit.json": (json.dumps(record, indent=2)).encode()}
            panels.append(image)
            labels.append(f"{knit} patch of the {'refined' if refine else 'neural'} yarn")
        files["compare.png"] = png_bytes(compare_image(panels, labels))
        shown_in = {"exposure_stops": round(capture.exposure_stops, 3),  # the renders' look,
                    "backdrop_gain": round(capture.backdrop_gain, 3),  # not the yarn's
                    "blur_mm": round(capture.blur_mm, 5)}
        textile = textile_block(shot, fitted, refined_img if refine else neural_img, config)
        params = {**result.to_dict(pixel_size, shot.setup),
                  "photo": {"file": Path(shot.name).name, "sha256": read.sha256},
                  "capture": shown_in, "textile": textile}
        files[PARAMS] = json.dumps(params, indent=2).encode()
        for line in summary_lines(result) + textile_lines(textile) + [
                f"loss neural {result.loss_neural:.4f} -> refined {result.loss_refined:.4f} "
                f"({result.seconds:.0f} s)"]:
            tell(line)
        files[RUN] = (json.dumps({"fit_seconds": round(result.seconds, 2)}) + "\n").encode()
        return FitOutput(files, lines)


@dataclass(frozen=True)
class Shot:
    """A photo as a fit reads it (:func:`read_shot`): ``photo`` (upright, of its setup,
    inverted if asked), its file's ``sha256``, ``chosen`` (how its setup was told, or
    None) and ``lines``, notes for the terminal."""

    photo: object
    sha256: str | None
    chosen: str | None
    lines: tuple[str, ...]


def read_shot(name: str, pixel_size: float, job: FitJob, data: bytes | None = None) -> Shot:
    """The photo file ``name`` (or its bytes ``data``) read at ``pixel_size`` as the fit of
    ``job`` sees it."""
    import hashlib

    from ipm.io import content_hash
    from ipm.photo import Photo

    photo, note = Photo.read(name, pixel_size, data=data).upright()
    photo, chosen = photo.with_setup(job.setup)
    if job.invert:
        photo = photo.inverted()
    sha = hashlib.sha256(data).hexdigest() if data is not None else content_hash(name)
    return Shot(photo, sha, chosen, (f"note: {note}",) if note else ())


def knit_panel(renderer, params, pattern: str, width: int):
    """``(image, record)``: ``params`` knitted into an 8 x 6 patch of ``pattern``, ``width``
    px wide and half as high, and its sidecar record."""
    from ipm.photo import linear_to_srgb
    from ipm.render.patch import knit_and_render

    linear, record, _ = knit_and_render(renderer, params, pattern, (8, 6), (width, width // 2),
                                        spp=16)
    return linear_to_srgb(linear), record
