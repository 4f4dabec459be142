"""The synthetic dataset (paper section "Yarn dataset"): guided-prior yarns rendered in THE
scene, with a manifest the nets read.

A dataset (``DIR`` made by ``ipm generate``; the manifest's contract is :mod:`ipm.dataset`):

* ``DIR/images/NNNNNN.png``: 8-bit sRGB RGB PNG of the 2000 x 600 frame times ``scale``,
  or of a detail ``view`` (width x height px at that scale's pitch, centred on the yarn).
* ``DIR/manifest.jsonl``: a :class:`~ipm.dataset.Record` per line, sorted by ``index`` when
  a run ends; beside the core fields each line records ``render_seed``, ``split``,
  ``scale``, ``spp`` (the count this sample's render took), ``width``, ``height``,
  ``photometric`` (the applied :class:`~ipm.render.photometric.Photometric`) and
  ``variant``.
* ``DIR/dataset.json``: the settings of the run; a rerun with other settings is refused.

Sample ``i`` depends only on (seed, split, i): its parameters, fiber seed, render seed,
capture variation and (with ``spp_max``) sample count come from ``SeedSequence([seed,
crc32(split), i])``, so its bytes do not depend on the worker that made it or on the
order.  Images are written atomically before their manifest line, and a rerun keeps the
lines whose image exists, drops a torn last line and renders what is missing: killed at any
moment and rerun, a folder ends with exactly ``count`` samples.
"""

from __future__ import annotations

import json
import os
import zlib
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ipm.dataset import MANIFEST, Record, manifest_line, read_manifest, write_manifest
from ipm.errors import UserError
from ipm.frame import pixel_size_mm
from ipm.io import write_text
from ipm.params import YarnParams
from ipm.prior import GuidedPrior
from ipm.render.photometric import Photometric, PhotometricRanges
from ipm.render.scene import DEFAULT_OPTIONS, Frame, SceneOptions, frame_size
from ipm.setups import DEFAULT_SETUP

SETTINGS = "dataset.json"
IMAGES = "images"

#: Defaults chosen by measurement (benchmarks/results/render_speed.md): scale 0.25 (500 x 150
#: px) is the input scale of the default nets, so their data needs no resampling; 6 spp of
#: the scene's stratified sampler bring the render noise below the fiber contrast.  The
#: shipped nets were trained on ``--spp 4-24`` (several noise levels).  The thinnest fibers
#: are 0.3 px at scale 0.25: scale 0.5 keeps them at 0.6 px, for nets trained at a higher
#: input scale (``--scale 0.5``).
DEFAULT_SCALE = 0.25
DEFAULT_SPP = 6


def spp_range(text: str) -> tuple[int, int | None]:
    """``"6"`` -> (6, None); ``"4-24"`` -> (4, 24): the CLI's ``--spp``."""
    lo, sep, hi = text.partition("-")
    try:
        spp, spp_max = int(lo), (int(hi) if sep else None)
    except ValueError:
        raise UserError(f"spp must be a count like 6 or a range like 4-24, got {text!r}") \
            from None
    return spp, spp_max


#: Settings added after datasets were made without them, and the value they had implicitly.
_ADDED_LATER = {"scene": {"setup": DEFAULT_SETUP, "panel": 0.6, "opacity": 0.5},
                "photometric": {"look": False, "material": False}}


@dataclass(frozen=True)
class GenerateOptions:
    """One dataset: ``count`` samples of ``split`` from master ``seed``.

    spp_max: when given, each sample's sample count is drawn log-uniformly from the integers
    ``spp .. spp_max`` (seeded per sample; the sampler may round it up), so that a dataset
    holds renders of several noise levels and nets trained on it do not learn one noise level
    (photos are cleaner than the default 6 spp, and finer photos averaged down to the nets'
    pitch cleaner still).
    """

    count: int
    seed: int = 0
    split: str = "train"
    scale: float = DEFAULT_SCALE
    spp: int = DEFAULT_SPP
    spp_max: int | None = None
    photometric: PhotometricRanges = field(default_factory=PhotometricRanges)
    scene: SceneOptions = DEFAULT_OPTIONS
    view: tuple[int, int] | None = None
    yarns: str = "knitting"

    def __post_init__(self) -> None:
        GuidedPrior(yarns=self.yarns)  # a one-line error for an unknown kind
        if self.count < 1:
            raise UserError(f"count must be >= 1, got {self.count}")
        if self.spp < 1:
            raise UserError(f"spp must be >= 1, got {self.spp}")
        if self.spp_max is not None and self.spp_max < self.spp:
            raise UserError(f"the spp range {self.spp}-{self.spp_max} is empty")
        if not self.split or not self.split.replace("_", "").replace("-", "").isalnum():
            raise UserError(f"split must be a simple name like train or val, got {self.split!r}")
        frame_size(self.scale)
        if self.view is not None and not all(32 <= v <= 4000 for v in self.view):
            raise UserError(f"a view is 32 to 4000 px on a side, got {self.view[0]} x "
                            f"{self.view[1]}")

    @property
    def frame(self) -> Frame | None:
        """The rendered view: the yarn frame at ``scale`` (None), or with ``view`` = (width,
        height) a window of that many pixels at the scale's pitch, centred on the yarn --
        a detail view for nets that need fine pixels (the fibers' slant, ``alpha``) at a
        fraction of the full frame's cost."""
        if self.view is None:
            return None
        return Frame(self.view[0], self.view[1], pixel_size_mm(self.scale))

    def settings(self) -> dict[str, Any]:
        """Everything a sample's bytes depend on (``count`` aside): JSON-ready.  Settings
        added later are recorded only when they differ from what was implicit before them
        (:data:`_ADDED_LATER`), so that a dataset made before them still resumes."""
        d = asdict(self)
        del d["count"]
        if self.spp_max is None:  # as recorded before sample-count ranges existed
            del d["spp_max"]
        if self.view is None:  # as recorded before detail views existed
            del d["view"]
        if self.yarns == "knitting":  # as recorded before other kinds of yarn existed
            del d["yarns"]
        for group, implicit in _ADDED_LATER.items():
            for k, v in implicit.items():
                if d[group].get(k) == v:
                    del d[group][k]
        return json.loads(json.dumps(d))


@dataclass(frozen=True)
class SampleSeeds:
    params_rng: np.random.Generator
    fiber_seed: int
    render_seed: int
    photometric_rng: np.random.Generator
    spp_rng: np.random.Generator


def sample_seeds(seed: int, split: str, index: int) -> SampleSeeds:
    """Independent streams of sample ``index``, from (seed, split, index) only.  (A child of
    a SeedSequence depends on its position only, so the stream added last, ``spp_rng``, left
    the others, and the datasets made before it, unchanged.)"""
    ss = np.random.SeedSequence([seed, zlib.crc32(split.encode()), index])
    p, f, r, ph, n = ss.spawn(5)
    return SampleSeeds(np.random.default_rng(p), int(f.generate_state(1)[0]),
                       int(r.generate_state(1)[0]), np.random.default_rng(ph),
                       np.random.default_rng(n))


@dataclass(frozen=True)
class SamplePlan:
    """Everything sample ``index`` is made of."""

    params: YarnParams
    fiber_seed: int
    render_seed: int
    photometric: Photometric
    spp: int


def sample_plan(opts: GenerateOptions, index: int) -> SamplePlan:
    """The plan of sample ``index``; the count is the one asked of the sampler, which may
    round it up (:meth:`ipm.render.renderer.Renderer.sample_count`)."""
    s = sample_seeds(opts.seed, opts.split, index)
    spp = opts.spp
    if opts.spp_max is not None:
        u = s.spp_rng.uniform(np.log(opts.spp), np.log(opts.spp_max + 1))
        spp = min(int(np.exp(u)), opts.spp_max)
    params = GuidedPrior(yarns=opts.yarns).sample(s.params_rng)
    return SamplePlan(params, s.fiber_seed, s.render_seed,
                      opts.photometric.draw(s.photometric_rng), spp)


def image_name(index: int) -> str:
    return f"{IMAGES}/{index:06d}.png"


# -- workers ---------------------------------------------------------------------------------
class SampleMaker:
    """What a worker of ``ipm generate`` holds (:class:`ipm.workers.Workers`): one
    :class:`Renderer`, samples rendered in turn."""

    def __init__(self, variant: str | None, scene: SceneOptions, threads: int | None) -> None:
        from ipm.render.renderer import Renderer

        self.renderer = Renderer(variant, scene, threads=threads)

    def make(self, folder: str, opts: GenerateOptions, index: int) -> Record:
        """Render sample ``index`` into ``folder`` (atomically) and return its manifest
        record."""
        from ipm.photo import write_png
        from ipm.render.photometric import encode

        plan = sample_plan(opts, index)
        spp = self.renderer.sample_count(opts.scale, plan.spp, opts.frame)
        image = self.renderer.render(plan.params, plan.fiber_seed, opts.scale, spp,
                                     plan.render_seed, plan.photometric, opts.frame)
        write_png(Path(folder, image_name(index)), encode(image, plan.photometric))
        height, width = image.shape[:2]
        return Record(Path(folder, image_name(index)), pixel_size_mm(opts.scale), plan.params,
                      plan.fiber_seed, setup=opts.scene.setup, index=index, info={
                          "split": opts.split, "render_seed": plan.render_seed,
                          "scale": opts.scale, "spp": spp, "width": width, "height": height,
                          "photometric": plan.photometric.to_dict(),
                          "variant": self.renderer.variant})


# -- folder state ----------------------------------------------------------------------------
def _prepare(folder: Path, opts: GenerateOptions) -> dict[int, Record]:
    """Check or create the folder and return the valid samples already there; rewrites the
    manifest without torn or duplicate lines.  Samples beyond ``opts.count`` (an earlier,
    larger run) are kept: a rerun with a smaller count never deletes what was made."""
    if folder.exists() and not folder.is_dir():
        raise UserError(f"{folder} exists and is not a folder")
    if not folder.exists():  # its missing parents too, as `mkdir -p`
        try:
            folder.mkdir(parents=True)
        except OSError:
            raise UserError(f"cannot create {folder}: {folder.parent} is missing or not "
                            "writable") from None
    if not os.access(folder, os.W_OK):
        raise UserError(f"output folder {folder} is not writable")
    settings_path = folder / SETTINGS
    if settings_path.is_file():
        try:
            previous = json.loads(settings_path.read_text(encoding="utf-8"))
        except json.JSONDecodeError:
            raise UserError(f"{settings_path} is not valid JSON; is this an ipm dataset?") \
                from None
        if previous != opts.settings():
            changed = sorted(k for k in {*previous, *opts.settings()}
                             if previous.get(k) != opts.settings().get(k))
            raise UserError(f"{folder} holds a dataset made with other settings "
                            f"({', '.join(changed)}); rerun with the same settings to resume, "
                            "or choose another --out")
    elif any(p for p in folder.iterdir() if not p.name.startswith(".")):
        raise UserError(f"{folder} is not empty and holds no {SETTINGS}; "
                        "choose an empty or new folder")
    else:
        write_text(settings_path, json.dumps(opts.settings(), indent=2) + "\n")
    (folder / IMAGES).mkdir(exist_ok=True)
    done: dict[int, Record] = {}
    if (folder / MANIFEST).is_file():  # the samples whose image was written
        done = {r.index: r for r in read_manifest(folder, allow_empty=True)
                if r.image.is_file()}
    write_manifest(folder, list(done.values()))
    return done


# -- the run ---------------------------------------------------------------------------------
Progress = Callable[[int, int], None]


def generate_dataset(folder: str | os.PathLike, opts: GenerateOptions, workers: int | None = None,
                     variant: str | None = None, progress: Progress | None = None,
                     ray: str | None = None) -> list[Record]:
    """Make (or complete) the dataset in ``folder`` with workers (:class:`ipm.workers.Workers`).

    workers: how many (default: one per core; one is this process), each with its own
    :class:`Renderer` and cores / workers render threads.  progress: called as
    ``progress(done, count)``.
    ray: a Ray address ("auto", "local", ``host:port``) to render on Ray actors instead;
    the samples are the same bytes either way.  Returns the records by index.
    """
    folder = Path(folder)
    if workers is not None and workers < 1:
        raise UserError(f"workers must be >= 1, got {workers}")
    from ipm.render.variant import requested_variant

    requested_variant(variant)  # an unknown variant fails before anything is written
    done = _prepare(folder, opts)
    todo = [i for i in range(opts.count) if i not in done]
    if progress:
        progress(opts.count - len(todo), opts.count)
    if todo:
        from ipm.workers import Workers

        made = 0
        count = min(workers or (len(todo) if ray else os.cpu_count() or 1), len(todo))
        with (Workers(SampleMaker, (variant, opts.scene), count, ray) as pool,
              open(folder / MANIFEST, "a", encoding="utf-8") as manifest):
            tasks = ((i, (str(folder), opts, i)) for i in todo)
            for _, rec in pool.run("make", tasks):
                manifest.write(manifest_line(folder, rec))
                manifest.flush()
                done[rec.index] = rec
                made += 1
                if progress:
                    progress(opts.count - len(todo) + made, opts.count)
    write_manifest(folder, list(done.values()))
    return [done[i] for i in sorted(done)]
