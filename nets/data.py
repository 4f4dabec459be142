"""Datasets for the nets: labelled synthetic frames (``ipm generate``) and unlabelled real
photos, as random crops at the nets' input scale.

A dataset folder holds ``manifest.jsonl``: one JSON object per line with ``image`` (path
relative to the folder, an 8-bit sRGB PNG of the 2000 x 600 frame at ``scale``), ``params``
(flat :class:`~ipm.params.YarnParams`) and ``pixel_size_mm``.  Frames are brought to the
nets' pixel pitch once (kept in memory as uint8 when they fit, else re-read per access), and
each epoch draws a new random crop and exposure per image from a generator seeded by (seed,
epoch, index), so runs are reproducible and resumable and do not depend on the worker count.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

from ipm.errors import UserError
from ipm.frame import PIXEL_SIZE_MM
from ipm.nets.tasks import Task
from ipm.params import YarnParams
from ipm.photo import defocus, linear_to_srgb, load_photo, srgb_to_linear

MANIFEST = "manifest.jsonl"
PHOTO_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp")
#: Frames are cached in memory as uint8 up to this many bytes per dataset.
CACHE_BYTES = 6 * 2**30

_LINEAR = srgb_to_linear(np.arange(256, dtype=np.float32) / 255)


def exposed_input(linear: np.ndarray, ev: float) -> np.ndarray:
    """Net input in [-1, 1] of linear light scaled by 2**ev (a brighter or darker exposure
    of the same scene), sRGB-encoded like a photo."""
    return linear_to_srgb(linear * 2.0 ** ev) * 2 - 1


def exposure_lut(ev: float) -> np.ndarray:
    """(256,) float32 in [-1, 1]: 8-bit sRGB -> :func:`exposed_input`."""
    return exposed_input(_LINEAR, ev)


def to_input(img: np.ndarray) -> torch.Tensor:
    """``(H, W, 3)`` float sRGB in [0, 1] -> net input ``(3, H, W)`` in [-1, 1]."""
    return torch.from_numpy(np.ascontiguousarray(img.transpose(2, 0, 1))).float() * 2 - 1


@dataclass(frozen=True)
class Record:
    """One labelled sample; ``seed`` is its fiber seed (None where a manifest has none)."""

    image: Path
    params: YarnParams
    pixel_size_mm: float
    seed: int | None = None


def read_manifest(folder: Path) -> list[Record]:
    """The records of a dataset folder; a bad folder or line is a one-line UserError."""
    path = Path(folder) / MANIFEST
    if not path.is_file():
        raise UserError(f"{folder} is not a dataset: {MANIFEST} not found "
                        "(make one with `ipm generate`)")
    records = []
    for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if not line.strip():
            continue
        try:
            d = json.loads(line)
            seed = d.get("seed")
            records.append(Record(Path(folder) / d["image"], YarnParams.from_dict(d["params"]),
                                  float(d.get("pixel_size_mm", PIXEL_SIZE_MM)),
                                  None if seed is None else int(seed)))
        except (json.JSONDecodeError, KeyError, TypeError, ValueError) as e:
            raise UserError(f"{path}:{i}: bad record ({e})") from None
    if not records:
        raise UserError(f"{path} lists no images")
    return records


class Frames:
    """Images at one pixel pitch, as uint8 ``(H, W, 3)``; ``labels`` when synthetic."""

    def __init__(self, files: list[Path], pixel_sizes: list[float], scale: float,
                 min_size: tuple[int, int], labels: list[YarnParams] | None = None,
                 invert: bool = False, max_height: int | None = None) -> None:
        self.files, self.pixel_sizes, self.labels = files, pixel_sizes, labels
        self.scale, self.min_size = scale, min_size
        self.invert, self.max_height = invert, max_height
        first = self._load(0)
        self._cache: list[np.ndarray | None] | None = None
        if first.nbytes * len(files) <= CACHE_BYTES:
            self._cache = [first] + [None] * (len(files) - 1)

    @classmethod
    def synthetic(cls, folder: Path, scale: float, min_size: tuple[int, int]) -> Frames:
        recs = read_manifest(folder)
        return cls([r.image for r in recs], [r.pixel_size_mm for r in recs], scale, min_size,
                   labels=[r.params for r in recs])

    @classmethod
    def real(cls, folder: Path, scale: float, min_size: tuple[int, int], pixel_size_mm: float,
             invert: bool, frame_height: int) -> Frames:
        """Unlabelled photos of ``folder``, cut to the frame's height around the centre row
        (the yarn runs through the centre, as in the synthetic frames)."""
        files = sorted(p for p in Path(folder).iterdir() if p.suffix.lower() in PHOTO_SUFFIXES)
        if not files:
            raise UserError(f"{folder} holds no photos ({', '.join(PHOTO_SUFFIXES)})")
        return cls(files, [pixel_size_mm] * len(files), scale, min_size, invert=invert,
                   max_height=frame_height)

    def __len__(self) -> int:
        return len(self.files)

    def _load(self, i: int) -> np.ndarray:
        img = load_photo(self.files[i], self.pixel_sizes[i], self.scale, self.min_size)
        if self.invert:
            img = 1 - img
        if self.max_height and img.shape[0] > self.max_height:
            top = (img.shape[0] - self.max_height) // 2
            img = img[top:top + self.max_height]
        return np.round(img * 255).astype(np.uint8)

    def __getitem__(self, i: int) -> np.ndarray:
        if self._cache is None:
            return self._load(i)
        if self._cache[i] is None:
            self._cache[i] = self._load(i)
        return self._cache[i]


class Crops(Dataset):
    """``(x, y)`` pairs: x ``(3, H, W)`` in [-1, 1], a crop of frame i; y the task's label
    (or the index for unlabelled frames).  Training draws a random crop and exposure per
    (seed, epoch, i), and with ``blur_px`` > 0 a Gaussian blur of sigma uniform in [0,
    blur_px] input pixels (:func:`ipm.photo.defocus`, in linear light); evaluation takes the
    centre crop at the rendered exposure, unblurred."""

    def __init__(self, frames: Frames, crop: tuple[int, int], task: Task | None = None,
                 train: bool = True, seed: int = 0, exposure_ev: float = 0.5,
                 blur_px: float = 0.0) -> None:
        self.frames, self.crop, self.task, self.train = frames, crop, task, train
        self.seed, self.exposure_ev, self.blur_px, self.epoch = seed, exposure_ev, blur_px, 0
        self._targets = (None if task is None or frames.labels is None
                         else [task.target(p) for p in frames.labels])

    def set_epoch(self, epoch: int) -> None:
        self.epoch = epoch

    def __len__(self) -> int:
        return len(self.frames)

    def __getitem__(self, i: int) -> tuple[torch.Tensor, torch.Tensor]:
        img = self.frames[i]
        (ch, cw), (h, w) = self.crop, img.shape[:2]
        ev, sigma = 0.0, 0.0
        if self.train:
            rng = np.random.default_rng([self.seed, self.epoch, i])
            top, left = int(rng.integers(0, h - ch + 1)), int(rng.integers(0, w - cw + 1))
            ev = float(rng.uniform(-self.exposure_ev, self.exposure_ev))
            # drawn last, and only when asked: runs without blur keep their crops
            sigma = float(rng.uniform(0, self.blur_px)) if self.blur_px > 0 else 0.0
        else:
            top, left = (h - ch) // 2, (w - cw) // 2
        patch = img[top:top + ch, left:left + cw]
        if sigma > 0:
            x = exposed_input(defocus(_LINEAR[patch], sigma), ev)
        else:
            x = exposure_lut(ev)[patch]
        x = torch.from_numpy(x.transpose(2, 0, 1).copy())
        y = torch.as_tensor(self._targets[i] if self._targets is not None else i)
        return x, y


def centre_crops(img: np.ndarray, crop: tuple[int, int], count: int) -> torch.Tensor:
    """``count`` crops ``(count, 3, H, W)`` of an ``(H', W', 3)`` sRGB image, centred
    vertically and evenly spaced along the yarn (the horizontal axis)."""
    (ch, cw), (h, w) = crop, img.shape[:2]
    if h < ch or w < cw:
        raise UserError(f"image of {w}x{h} px at the nets' pitch is smaller than their "
                        f"input of {cw}x{ch} px")
    top = (h - ch) // 2
    lefts = np.linspace(0, w - cw, count).round().astype(int) if count > 1 else [(w - cw) // 2]
    return torch.stack([to_input(img[top:top + ch, left:left + cw]) for left in lefts])

