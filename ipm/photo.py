"""A photo of a yarn (:class:`Photo`): its image, the size of its pixels at the yarn, the
capture setup, and for a render its true parameters (Pillow + numpy only).

The nets and the refiner compare photos with renders of the scene, which has a fixed pixel
size at the yarn (:data:`ipm.frame.PIXEL_SIZE_MM` at full resolution, ``PIXEL_SIZE_MM /
scale`` at a resolution scale).  A photo of another magnification is resampled so that one
of its pixels covers the same millimetres as one pixel of the scene.

Values are **sRGB-encoded** (as stored in the file, like the 8-bit sRGB PNGs of the
dataset), float32 in [0, 1], shape ``(H, W, 3)``: the nets and the loss read sRGB, so a photo
keeps the file's values (a round trip through linear light would change them in the last
bits); :attr:`Photo.linear` gives linear light, and blurs happen there.
"""

from __future__ import annotations

import io
import os
import warnings
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from PIL import Image, ImageOps, UnidentifiedImageError

from ipm.errors import UserError
from ipm.frame import PIXEL_SIZE_MM, pitch_factor
from ipm.setups import AUTO_SETUP, DEFAULT_SETUP, lit, setup_of

if TYPE_CHECKING:
    from ipm.params import YarnParams

#: Photos above this many pixels are refused before decoding (a 100 MP camera is the limit).
MAX_PIXELS = 120_000_000


def read_image(path: str | os.PathLike, max_pixels: int = MAX_PIXELS,
               data: bytes | None = None) -> np.ndarray:
    """Decode any still image Pillow reads into ``(H, W, 3)`` float32 sRGB in [0, 1]; with
    ``data``, the file's bytes (a photo shipped to a worker), ``path`` only names it.

    8- and 16-bit (Pillow reads 16-bit colour at 8-bit precision, 16-bit grayscale in
    full), grayscale (replicated to three channels), palette, CMYK and alpha
    (composited over black, the colour of the scene's dark backdrop) are accepted; the EXIF
    orientation of camera files is applied.  Raises :class:`UserError` with one line for a
    missing, unreadable, non-image, truncated or absurdly large file.
    """
    from ipm.io import check_regular_file

    name = os.fspath(path)
    if data is None:
        check_regular_file(name, "an image")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            with Image.open(name if data is None else io.BytesIO(data)) as im:
                w, h = im.size
                if w * h > max_pixels:
                    raise UserError(f"{name}: {w}x{h} px is too large "
                                    f"(at most {max_pixels // 1_000_000} MP)")
                im.load()
                im = ImageOps.exif_transpose(im)
                return _to_rgb_float(im)
    except FileNotFoundError:
        raise UserError(f"{name}: no such file") from None
    except PermissionError:
        raise UserError(f"{name}: permission denied") from None
    except UnidentifiedImageError:
        raise UserError(f"{name} is not an image Pillow can read") from None
    except (Image.DecompressionBombError, Image.DecompressionBombWarning):
        raise UserError(f"{name} is too large to decode safely") from None
    except (OSError, SyntaxError, ValueError) as e:
        # Pillow reports truncated or corrupt data as OSError ("image file is truncated").
        if isinstance(e, UserError):
            raise
        raise UserError(f"{name}: cannot decode the image ({e})") from None


def _to_rgb_float(im: Image.Image) -> np.ndarray:
    if im.mode in ("I;16", "I;16B", "I;16L", "I;16N", "I"):
        # 16-bit grayscale; 32-bit "I" from 16-bit PNGs holds 0..65535.
        g = np.asarray(im, dtype=np.float32) / 65535.0
        return np.repeat(np.clip(g, 0, 1)[..., None], 3, axis=2)
    if im.mode == "F":
        g = np.asarray(im, dtype=np.float32)
        return np.repeat(np.clip(g, 0, 1)[..., None], 3, axis=2)
    has_alpha = im.mode in ("RGBA", "LA", "PA", "RGBa", "La") or (
        im.mode == "P" and "transparency" in im.info)
    if has_alpha:
        rgba = np.asarray(im.convert("RGBA"), dtype=np.float32) / 255.0
        return np.ascontiguousarray(rgba[..., :3] * rgba[..., 3:])
    return np.asarray(im.convert("RGB"), dtype=np.float32) / 255.0


#: A photo resampled to the scene's pitch may hold this many pixels (a 0.6 GB float image);
#: more means a pixel size typed in the wrong unit, refused before any allocation.
MAX_RESAMPLED_PIXELS = 50_000_000
#: What a macro or microscope photo of a yarn has per pixel (mm), for the messages.
PLAUSIBLE_PIXEL_MM = (0.001, 0.1)


#: A sidecar's pixel size outside this (mm) is refused: ten times beyond the plausible
#: range either way (a render at a low --scale has coarse pixels).
SIDECAR_PIXEL_MM = (PLAUSIBLE_PIXEL_MM[0] / 10, PLAUSIBLE_PIXEL_MM[1] * 10)

#: The commands' help for the two ways to give a photo's pixel size (:func:`pixel_size_of`).
PIXEL_SIZE_HELP = ("mm per photo pixel at the yarn; default: --calibration, or the ipm "
                   "sidecar `<photo>.json` (without any, the photo is refused)")
CALIBRATION_HELP = "pixel size from `ipm calibrate ruler.png -o FILE`"


def sidecar_pixel_size(path: str | os.PathLike) -> tuple[Path, float] | None:
    """(the sidecar, its pixel size) of a photo: the ``pixel_size_mm`` of the ipm sidecar
    beside it (``<photo>.json`` of ``ipm render``), or None without one.  A sidecar whose
    ``pixel_size_mm`` is not a positive number (``true`` is not 1 mm), or is far outside
    what a yarn photo has, is a one-line :class:`UserError` naming the sidecar."""
    import json
    import stat

    sidecar = Path(path).with_suffix(".json")
    try:
        if not stat.S_ISREG(os.stat(sidecar).st_mode):
            return None  # a FIFO would block
        value = json.loads(sidecar.read_text(encoding="utf-8"))["pixel_size_mm"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    lo, hi = SIDECAR_PIXEL_MM
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            np.isfinite(value) and value > 0):
        raise UserError(f"{sidecar}: pixel_size_mm must be a positive number of mm, got "
                        f"{json.dumps(value)}; fix the sidecar or give --pixel-size")
    if not lo <= value <= hi:
        raise UserError(f"{sidecar}: pixel_size_mm {value:g} is not a yarn photo's (about "
                        f"{PLAUSIBLE_PIXEL_MM[0]:g}-{PLAUSIBLE_PIXEL_MM[1]:g} mm); fix the "
                        "sidecar or give --pixel-size")
    return sidecar, float(value)


def pixel_size_of(path: str | os.PathLike, pixel_size_mm: float | None = None,
                  calibration: str | os.PathLike | None = None) -> float:
    """A photo's pixel size (mm): ``--pixel-size``, else the calibration file's (``ipm
    calibrate``), else its sidecar's (:func:`sidecar_pixel_size`); without any of them a
    one-line :class:`UserError`, since every length ipm reports follows from it (a photo
    that is not there is said to be missing first)."""
    if pixel_size_mm is not None and calibration is not None:
        raise UserError("give --pixel-size or --calibration, not both")
    if pixel_size_mm is not None:
        if not (np.isfinite(pixel_size_mm) and pixel_size_mm > 0):
            raise UserError(f"pixel size must be a positive number of mm, got {pixel_size_mm}")
        return float(pixel_size_mm)
    if calibration is not None:
        from ipm.calibrate import Calibration

        return Calibration.load(calibration).pixel_size_mm
    from ipm.io import check_regular_file

    check_regular_file(path, "an image")
    if found := sidecar_pixel_size(path):
        return found[1]
    raise UserError(f"{os.fspath(path)}: its pixel size is unknown; give --pixel-size MM, or "
                    "--calibration FILE from `ipm calibrate ruler.png -o FILE` (a photo of "
                    "a millimetre scale taken with the same setup)")


def to_scene_pitch(img: np.ndarray, pixel_size_mm: float, scale: float = 1.0) -> np.ndarray:
    """Resample ``(H, W, 3)`` so that one pixel covers ``PIXEL_SIZE_MM / scale`` mm.

    ``pixel_size_mm`` is the size of one photo pixel at the yarn.  Downsampling averages
    (box filter, no aliasing of fiber-scale detail); upsampling is bicubic.
    """
    if not (np.isfinite(pixel_size_mm) and pixel_size_mm > 0):
        raise UserError(f"pixel size must be a positive number of mm, got {pixel_size_mm}")
    if not (np.isfinite(scale) and scale > 0):
        raise UserError(f"scale must be positive, got {scale}")
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"expected an (H, W, 3) image, got shape {img.shape}")
    factor = pitch_factor(pixel_size_mm, scale)
    h, w = img.shape[:2]
    size = (max(1, round(w * factor)), max(1, round(h * factor)))
    if size[0] * size[1] > MAX_RESAMPLED_PIXELS:
        raise UserError(f"at {pixel_size_mm:g} mm per pixel this {w}x{h} px photo spans "
                        f"{w * pixel_size_mm:g} x {h * pixel_size_mm:g} mm, {size[0]}x{size[1]} "
                        f"px at the scene's pitch: is the pixel size in mm? (a yarn photo's "
                        f"is about {PLAUSIBLE_PIXEL_MM[0]:g}-{PLAUSIBLE_PIXEL_MM[1]:g} mm)")
    if size == (w, h):
        return img.astype(np.float32, copy=False)
    resample = Image.Resampling.BOX if factor < 1 else Image.Resampling.BICUBIC
    chans = [np.asarray(Image.fromarray(np.ascontiguousarray(img[..., c], np.float32), mode="F")
                        .resize(size, resample)) for c in range(3)]
    return np.clip(np.stack(chans, axis=2), 0, 1).astype(np.float32)


#: Below this contrast (the largest range of the row or column medians of the difference
#: from the border's level) a photo shows no yarn: a blank, a uniform or a noise image.
NO_YARN_CONTRAST = 0.02
#: The least a photo must show, (across, along the yarn) in mm at the yarn: a fine yarn's
#: core with some of its flyaways and a few of its ply periods.  Less is refused; more, if
#: still less than the nets' input, is padded across and pooled along (:meth:`Photo.at_pitch`).
MIN_VIEW_MM = (1.0, 3.0)


def yarn_layout(gray: np.ndarray) -> tuple[float, float]:
    """(contrast, orientation score) of a grayscale photo.  Contrast: see
    :data:`NO_YARN_CONTRAST`.  Score > 0 for a yarn running horizontally, < 0 vertically:
    the log of three ratios that a horizontal yarn makes large, each measured on its own
    rows and columns: vertical over horizontal gradient energy (a yarn's edges and fibers
    run along it), the range of the row medians over that of the column medians (a band
    across the frame), and width over height."""
    gy, gx = np.gradient(gray.astype(np.float64))
    border = np.concatenate([gray[0], gray[-1], gray[:, 0], gray[:, -1]])
    c = np.abs(gray - np.median(border))
    rows, cols = np.ptp(np.median(c, axis=1)), np.ptp(np.median(c, axis=0))
    eps = 1e-9
    score = (np.log(((gy ** 2).sum() + eps) / ((gx ** 2).sum() + eps))
             + np.log((rows + eps) / (cols + eps)) + np.log(gray.shape[1] / gray.shape[0]))
    return float(max(rows, cols)), float(score)


#: A border at least this bright (sRGB) with a yarn darker than it is a capture lit from
#: behind (a yarn lit in front is lighter than its dark card; real captures lit from behind
#: can be dim).
LIGHT_BORDER = 0.3
#: A yarn whose pixels differ this much between colour channels (sRGB, the median of the
#: largest minus the smallest) shows its colour: lit in front, whatever its card (a
#: silhouette on a light panel is grey).
COLOURED_YARN = 0.1


def detect_setup(image: np.ndarray) -> tuple[str, str]:
    """(setup, why) of an sRGB photo (H, W, 3): the setup lit from behind
    (:mod:`ipm.setups`) for a dark grey yarn on a light background (a light panel or a
    microscope's lamp), else the one lit in front (a light yarn on the dark card of the
    scene, or a coloured yarn on any card: :data:`COLOURED_YARN`).  The background is the
    median of the border; the yarn, the pixels that differ from it most."""
    gray = image.mean(axis=2)
    border = np.concatenate([gray[0], gray[-1], gray[:, 0], gray[:, -1]])
    background = float(np.median(border))
    diff = gray - background
    far = np.abs(diff) >= np.quantile(np.abs(diff), 0.9)
    darker = float(np.mean(diff[far])) < 0
    colour = float(np.median((image.max(axis=2) - image.min(axis=2))[far]))
    if background >= LIGHT_BORDER and darker and colour >= COLOURED_YARN:
        return lit(False), (f"a coloured yarn on a light card, level {background:.2f}, "
                            f"colour {colour:.2f}")
    if background >= LIGHT_BORDER and darker:
        return lit(True), f"a dark yarn on a light background, level {background:.2f}"
    return lit(False), (f"a {'dark' if darker else 'light'} yarn on a "
                        f"{'light' if background >= LIGHT_BORDER else 'dark'} background, "
                        f"level {background:.2f}")


@dataclass(frozen=True)
class Photo:
    """A yarn photo: ``image`` (H, W, 3) float32 sRGB in [0, 1], ``pixel_size_mm`` (one
    pixel at the yarn), ``setup`` (its capture setup, :mod:`ipm.setups`), ``truth`` (the
    parameters of a render) and ``name`` (its file, for messages)."""

    image: np.ndarray
    pixel_size_mm: float = PIXEL_SIZE_MM
    setup: str = DEFAULT_SETUP
    truth: YarnParams | None = None
    name: str = "the photo"

    @classmethod
    def read(cls, path: str | os.PathLike, pixel_size_mm: float = PIXEL_SIZE_MM,
             setup: str = DEFAULT_SETUP, truth: YarnParams | None = None,
             data: bytes | None = None) -> Photo:
        """Decode ``path``, or the bytes ``data`` of a file of that name
        (:func:`read_image`)."""
        return cls(read_image(path, data=data), pixel_size_mm, setup, truth, os.fspath(path))

    @property
    def linear(self) -> np.ndarray:
        """The image in linear light."""
        return srgb_to_linear(self.image)

    def at_pitch(self, scale: float = 1.0, min_size: tuple[int, int] | None = None
                 ) -> np.ndarray:
        """The image resampled to the scene's pixel pitch at ``scale``
        (:func:`to_scene_pitch`).  ``min_size`` = (H, W), the nets' input: a photo that
        shows too little is refused (:meth:`check_view`); one with fewer than H rows is
        padded above and below with its background (the median of its outer rows), as if
        the camera had seen more of the backdrop (flyaways that reach beyond it are lost);
        one narrower than W stays so (the nets pool along the yarn)."""
        img = to_scene_pitch(self.image, self.pixel_size_mm, scale)
        if min_size is None:
            return img
        self.check_view()
        missing = min_size[0] - img.shape[0]
        if missing > 0:
            edge = max(1, img.shape[0] // 10)
            background = np.median(np.concatenate([img[:edge], img[-edge:]]).reshape(-1, 3),
                                   axis=0).astype(img.dtype)
            above = missing // 2
            img = np.concatenate([np.broadcast_to(background, (above, img.shape[1], 3)), img,
                                  np.broadcast_to(background, (missing - above, img.shape[1], 3))])
        return img

    def check_view(self) -> None:
        """A one-line :class:`UserError` if the photo shows less than :data:`MIN_VIEW_MM`,
        saying how many photo pixels are needed at its pixel size."""
        h, w = self.image.shape[:2]
        seen = (h * self.pixel_size_mm, w * self.pixel_size_mm)
        if seen[0] < MIN_VIEW_MM[0] or seen[1] < MIN_VIEW_MM[1]:
            need_w, need_h = (int(np.ceil(v / self.pixel_size_mm)) for v in MIN_VIEW_MM[::-1])
            raise UserError(f"{self.name} ({w}x{h} px) is too small: at {self.pixel_size_mm:g}"
                            f" mm per pixel it shows {seen[1]:.3g} x {seen[0]:.3g} mm of yarn; "
                            f"ipm needs at least {MIN_VIEW_MM[1]:g} x {MIN_VIEW_MM[0]:g} mm "
                            f"({need_w}x{need_h} px)")

    def with_setup(self, setup: str) -> tuple[Photo, str | None]:
        """The photo read as of capture ``setup``; for ``auto`` the one
        :func:`detect_setup` tells, and a note saying which and why."""
        if setup != AUTO_SETUP:
            return replace(self, setup=setup), None
        chosen, why = detect_setup(self.image)
        other = lit(not setup_of(chosen).light_behind)
        return (replace(self, setup=chosen),
                f"{self.name}: read as {chosen} ({why}); --setup {other} to read it otherwise")

    def upright(self) -> tuple[Photo, str | None]:
        """The photo with its yarn horizontal, as the nets and the scene see it, and a note
        when it had to be turned (:func:`yarn_layout`); a photo with no yarn in it is a
        one-line :class:`UserError`."""
        contrast, score = yarn_layout(self.image.mean(axis=2))
        if contrast < NO_YARN_CONTRAST:
            raise UserError(f"{self.name}: no yarn found (the image is nearly uniform: contrast "
                            f"{contrast:.3f}, a yarn gives {NO_YARN_CONTRAST} or more)")
        if score < 0:
            return (replace(self, image=np.ascontiguousarray(np.rot90(self.image))),
                    f"{self.name}: the yarn runs vertically; turned by 90 degrees")
        return self, None

    def scene_view(self, scale: float = 1.0, min_size: tuple[int, int] | None = None
                  ) -> np.ndarray:
        """The image as the scene shows a yarn: at ``scale``'s pitch (:meth:`at_pitch`)
        and, lit from the front, with its card brought to the level of the scene's card
        (:func:`card_normalised`).  What the nets read, in training and in use: a yarn on
        a light card is read as on the card they were trained on.  (A fit renders on the
        photo's own card instead: :func:`ipm.refine.capture.search_card`.)"""
        return on_scene_card(self.at_pitch(scale, min_size), self.setup)

    def inverted(self) -> Photo:
        """The negative: a capture of a dark yarn on a light background made to look
        like the scene's light yarn on a dark card."""
        return replace(self, image=1 - self.image)

    def defocused(self, sigma_mm: float) -> Photo:
        """Blurred in linear light by a Gaussian of ``sigma_mm`` at the yarn
        (:func:`defocus`)."""
        if sigma_mm <= 0:
            return self
        return replace(self, image=linear_to_srgb(defocus(self.linear,
                                                          sigma_mm / self.pixel_size_mm)))


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """The sRGB transfer function, inverted (IEC 61966-2-1)."""
    x = np.asarray(x, dtype=np.float32)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4).astype(np.float32)


def _card_pixels(linear: np.ndarray) -> np.ndarray:
    """The pixels (N, 3) of the top and bottom twelfths of an image whose yarn runs left to
    right: the card, where flyaways are sparse."""
    edge = max(1, linear.shape[0] // 12)
    return np.concatenate([linear[:edge], linear[-edge:]]).reshape(-1, 3)


def card_factor(linear: np.ndarray, level: float) -> float:
    """How many times lighter than ``level`` (linear grey) the card shows in ``linear``
    (H, W, 3): its pixels' median (:func:`_card_pixels`)."""
    return float(np.median(_card_pixels(linear), axis=0).mean()) / level


def recarded(linear: np.ndarray, factor: float) -> np.ndarray:
    """``linear`` (H, W, 3) with its card's light divided by ``factor`` where the card shows:
    each pixel loses ``1 - a`` of the card's change, ``a`` the yarn's cover of it, taken as
    the pixel's distance from the card's colour (:func:`_card_pixels`' median) over the
    core's (the five rows about the row farthest from the card), both less twice the card's
    own noise (the median distance in those twelfths).  The yarn's own light, which does not
    come from the card, stays."""
    border = _card_pixels(linear)
    card = np.median(border, axis=0)
    noise = 2 * float(np.median(np.abs(border - card).sum(axis=-1)))
    dist = np.abs(linear - card).sum(axis=-1)
    row = int(np.argmax(np.median(dist, axis=1)))
    core = np.median(linear[max(0, row - 2):row + 3].reshape(-1, 3), axis=0)
    span = max(float(np.abs(core - card).sum()) - noise, 1e-6)
    cover = np.clip((dist - noise) / span, 0, 1)[..., None]
    return np.clip(linear - (1 - cover) * card * (1 - 1 / factor), 0, 1).astype(linear.dtype)


def card_normalised(image: np.ndarray, level: float) -> np.ndarray:
    """An sRGB photo (H, W, 3) of a yarn lit from the front with its card brought to
    ``level`` (linear grey), estimated from the photo itself (:func:`card_factor`,
    :func:`recarded`): a yarn on a white card as on the scene's dark one."""
    linear = srgb_to_linear(image)
    factor = card_factor(linear, level)
    if not np.isfinite(factor) or factor <= 0:
        return image
    return linear_to_srgb(recarded(linear, factor)).astype(image.dtype)


def on_scene_card(image: np.ndarray, setup: str) -> np.ndarray:
    """An sRGB image (H, W, 3) of capture ``setup`` with its card, lit from the front,
    brought to the scene's (:func:`card_normalised`); a light panel's as it is."""
    card = setup_of(setup).card_linear
    return image if card is None else card_normalised(image, card)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """The sRGB transfer function (IEC 61966-2-1); input clipped to [0, 1]."""
    x = np.clip(np.asarray(x, dtype=np.float32), 0, 1)
    return np.where(x <= 0.0031308, 12.92 * x,
                    1.055 * x ** (1 / 2.4) - 0.055).astype(np.float32)


def defocus(image: np.ndarray, sigma_px: float) -> np.ndarray:
    """A linear-light image (H, W, C) blurred by a Gaussian of ``sigma_px`` pixels: the
    defocus and lens blur a real capture has and a render does not (a yarn is mm deep, a
    1:1 macro lens's depth of field a fraction of that).  Blurs light, so pass linear
    values, not sRGB."""
    if sigma_px <= 0:
        return image
    from skimage.filters import gaussian

    return gaussian(image, sigma=sigma_px, channel_axis=-1, mode="nearest",
                    preserve_range=True).astype(np.float32)


def png_bytes(image: np.ndarray) -> bytes:
    """An sRGB image ((H, W, 3) float in [0, 1] or uint8) encoded as an RGB PNG."""
    if image.dtype != np.uint8:
        image = (np.clip(image, 0, 1) * 255).round().astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(image), "RGB").save(buf, format="PNG")
    return buf.getvalue()


def write_png(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write an sRGB image ((H, W, 3) float in [0, 1] or uint8) as an RGB PNG, atomically."""
    from ipm.io import write_bytes

    write_bytes(path, png_bytes(image))
