"""Datasets for the nets: labelled synthetic frames (``ipm generate``) and unlabelled real
photos, as random crops at the nets' input scale.

A dataset folder is read through :mod:`ipm.dataset` (its manifest names 8-bit sRGB PNGs of
the 2000 x 600 frame at ``scale``, their labels and pixel sizes).  Frames are brought to the
nets' pixel pitch once (kept in memory as uint8 when they fit, else re-read per access), and
each epoch draws a new random crop and exposure per image from a generator seeded by (seed,
epoch, index), so runs are reproducible and resumable and do not depend on the worker count.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

from ipm.dataset import PHOTO_SUFFIXES, Record, photo_files, read_manifest
from ipm.errors import UserError
from ipm.nets.tasks import Task
from ipm.photo import defocus, linear_to_srgb, srgb_to_linear

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


class Frames:
    """Images at one pixel pitch, as uint8 ``(H, W, 3)``; ``labels`` when synthetic."""

    def __init__(self, records: list[Record], scale: float, min_size: tuple[int, int],
                 invert: bool = False, max_height: int | None = None) -> None:
        self.records = records
        self.labels = (None if any(r.params is None for r in records)
                       else [r.params for r in records])
        self.scale, self.min_size = scale, min_size
        self.invert, self.max_height = invert, max_height
        first = self._load(0)
        self._cache: list[np.ndarray | None] | None = None
        if first.nbytes * len(records) <= CACHE_BYTES:
            self._cache = [first] + [None] * (len(records) - 1)

    @classmethod
    def synthetic(cls, folder: Path, scale: float, min_size: tuple[int, int]) -> Frames:
        return cls(read_manifest(folder), scale, min_size)

    @classmethod
    def real(cls, folder: Path, scale: float, min_size: tuple[int, int], pixel_size_mm: float,
             invert: bool, frame_height: int) -> Frames:
        """Unlabelled photos of ``folder``, cut to the frame's height around the centre row
        (the yarn runs through the centre, as in the synthetic frames)."""
        files = photo_files(folder)
        if not files:
            raise UserError(f"{folder} holds no photos ({', '.join(PHOTO_SUFFIXES)})")
        return cls([Record(f, pixel_size_mm) for f in files], scale, min_size, invert=invert,
                   max_height=frame_height)

    def __len__(self) -> int:
        return len(self.records)

    def _load(self, i: int) -> np.ndarray:
        photo = self.records[i].photo()
        img = (photo.inverted() if self.invert else photo).scene_view(self.scale, self.min_size)
        if self.max_height and img.shape[0] > self.max_height:
            top = (img.shape[0] - self.max_height) // 2
            img = img[top:top + self.max_height]
        if self.labels is None and img.shape[1] < self.min_size[1]:
            # a real photo narrower than the crop (a microscope's small view) is tiled along
            # the yarn: periodic, which keeps the twist's handedness (a mirror would flip it)
            img = np.pad(img, ((0, 0), (0, self.min_size[1] - img.shape[1]), (0, 0)),
                         mode="wrap")
        return np.round(img * 255).astype(np.uint8)

    def __getitem__(self, i: int) -> np.ndarray:
        if self._cache is None:
            return self._load(i)
        if self._cache[i] is None:
            self._cache[i] = self._load(i)
        return self._cache[i]


#: The ranges of :func:`jitter_look` (uniform): per-channel gains (white balance and the
#: fibers' hue), saturation (0: grey), a light offset (a brighter backdrop or fill),
#: Poisson-like noise (variance ``noise * x``; a path tracer's sparkle or a sensor's shot
#: noise) and a tone curve on the sRGB values.
LOOK_JITTER: dict[str, tuple[float, float]] = {
    "channel_gain": (0.6, 1.4), "saturation": (0.0, 1.5), "offset": (0.0, 0.08),
    "noise": (0.0, 0.03), "gamma": (0.7, 1.4)}


def jitter_look(linear: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Another look of the same yarn (:data:`LOOK_JITTER`), on a linear image ``(H, W, 3)``;
    returns linear light.  Why: nets trained on one scene learn its look (its card, lamps,
    colours and noise) and fail on another renderer's (``nets_accuracy`` on the Cycles set);
    varying the look at training time is cheaper than rendering it and teaches the nets to
    read the yarn's shape instead."""
    r = {k: rng.uniform(lo, hi, size=3 if k == "channel_gain" else None)
         for k, (lo, hi) in LOOK_JITTER.items()}
    out = linear * r["channel_gain"]
    grey = out.mean(axis=-1, keepdims=True)
    out = np.maximum(grey + (out - grey) * r["saturation"], 0) + r["offset"]
    out = out + np.sqrt(r["noise"] * out) * rng.standard_normal(out.shape).astype(np.float32)
    srgb = np.clip(linear_to_srgb(np.maximum(out, 0)), 0, 1) ** r["gamma"]
    return srgb_to_linear(srgb).astype(np.float32)


class Crops(Dataset):
    """``(x, y)`` pairs: x ``(3, H, W)`` in [-1, 1], a crop of frame i; y the task's label
    (or the index for unlabelled frames).  Training draws a random crop and exposure per
    (seed, epoch, i), with ``blur_px`` > 0 a Gaussian blur of sigma uniform in [0,
    blur_px] input pixels (:func:`ipm.photo.defocus`, in linear light), and with ``look``
    another look (:func:`jitter_look`); evaluation takes the centre crop at the rendered
    exposure, unblurred and as rendered."""

    def __init__(self, frames: Frames, crop: tuple[int, int], task: Task | None = None,
                 train: bool = True, seed: int = 0, exposure_ev: float = 0.5,
                 blur_px: float = 0.0, look: bool = False) -> None:
        self.frames, self.crop, self.task, self.train = frames, crop, task, train
        self.seed, self.exposure_ev, self.blur_px, self.epoch = seed, exposure_ev, blur_px, 0
        self.look = look
        self._targets = (None if task is None or frames.labels is None
                         else [task.target(p) for p in frames.labels])

    def set_epoch(self, epoch: int) -> None:
        self.epoch = epoch

    def __len__(self) -> int:
        return len(self.frames)

    def __getitem__(self, i: int) -> tuple[torch.Tensor, torch.Tensor]:
        img = self.frames[i]
        (ch, cw), (h, w) = self.crop, img.shape[:2]
        if w < cw:  # training batches need one crop size
            raise UserError(f"{self.frames.records[i].image}: {w} px wide at the nets' pitch, "
                            f"narrower than their training crop of {cw} px")
        ev, sigma = 0.0, 0.0
        if self.train:
            rng = np.random.default_rng([self.seed, self.epoch, i])
            top, left = int(rng.integers(0, h - ch + 1)), int(rng.integers(0, w - cw + 1))
            ev = float(rng.uniform(-self.exposure_ev, self.exposure_ev))
            # drawn last, and only when asked: runs without blur (or look) keep their crops
            sigma = float(rng.uniform(0, self.blur_px)) if self.blur_px > 0 else 0.0
        else:
            top, left = (h - ch) // 2, (w - cw) // 2
        patch = img[top:top + ch, left:left + cw]
        if self.look and self.train:
            linear = jitter_look(_LINEAR[patch], rng)
            x = exposed_input(defocus(linear, sigma) if sigma > 0 else linear, ev)
        elif sigma > 0:
            x = exposed_input(defocus(_LINEAR[patch], sigma), ev)
        else:
            x = exposure_lut(ev)[patch]
        x = torch.from_numpy(x.transpose(2, 0, 1).copy())
        y = torch.as_tensor(self._targets[i] if self._targets is not None else i)
        return x, y


def centre_crops(img: np.ndarray, crop: tuple[int, int], count: int) -> torch.Tensor:
    """``count`` crops ``(count, 3, H, W)`` of an ``(H', W', 3)`` sRGB image, centred
    vertically and evenly spaced along the yarn (the horizontal axis); an image narrower
    than the crop is one crop of its own width (the nets pool along the yarn)."""
    (ch, cw), (h, w) = crop, img.shape[:2]
    if h < ch:
        raise UserError(f"image of {w}x{h} px at the nets' pitch is lower than their input "
                        f"of {ch} rows (Photo.at_pitch pads it)")
    if w < cw:
        cw, count = w, 1
    top = (h - ch) // 2
    lefts = np.linspace(0, w - cw, count).round().astype(int) if count > 1 else [(w - cw) // 2]
    return torch.stack([to_input(img[top:top + ch, left:left + cw]) for left in lefts])

