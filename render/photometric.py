"""Photometric variation that real captures have, as explicit, seeded, recorded options.

A :class:`PhotometricRanges` says how much variation a dataset gets; ``draw(rng)`` picks one
:class:`Photometric` per sample, which the manifest records (``to_dict``) so that a sample can
be re-rendered bit for bit.  The yarn's shift and rotation act on the geometry (the renderer
places the fibers with them); the lights' strength and places and the backdrop on the scene
(through ``mi.traverse``, :func:`ipm.render.scene.scaled_options`); exposure, white balance,
defocus, vignetting and sensor noise on the linear image (:func:`apply_to_image`); a camera's tone
curve and JPEG compression on the encoded 8-bit image (:func:`encode`).  The later
variations (lights, backdrop, defocus, vignetting, tone, JPEG) are off unless a dataset asks
for them (``ipm generate --vary-look``), and the fibers' material (how much light a fiber
stops, the room's fill light: ``--vary-material``) unless it asks for that, so datasets made
before them stay as they were.
"""

from __future__ import annotations

import io
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from ipm.errors import UserError
from ipm.photo import defocus, linear_to_srgb


@dataclass(frozen=True)
class Photometric:
    """One capture's deviations from the nominal scene.

    exposure_stops: image gain 2**stops.  white_balance: (3,) per-channel gains (mean 1).
    shift_mm: (dx, dy) of the yarn in the image plane (x right, y up).  rotation_deg: of the
    yarn about the view direction.  noise: (a, b) of Poisson-Gaussian sensor noise, variance
    a * x + b on the linear image x.  noise_seed: seed of that noise.  light_gain,
    backdrop_gain: the lamps' and the card's strength (:func:`ipm.render.scene.scaled_options`).
    fiber_opacity: the share of the light a fiber stops, lit from behind (0: the scene's
    own, :attr:`ipm.render.scene.SceneOptions.opacity`).  room_gain: the room's fill light.
    lamp_turn_deg, lamp_tilt_deg, fill_share: where the soft boxes in front stand and how
    strong the second is (:func:`ipm.render.scene.soft_boxes`; fill_share 0: the scene's own).
    """

    exposure_stops: float = 0.0
    white_balance: tuple[float, float, float] = (1.0, 1.0, 1.0)
    shift_mm: tuple[float, float] = (0.0, 0.0)
    rotation_deg: float = 0.0
    noise: tuple[float, float] = (0.0, 0.0)
    noise_seed: int = 0
    light_gain: float = 1.0
    backdrop_gain: float = 1.0
    blur_mm: float = 0.0
    vignetting: float = 0.0
    gamma: float = 1.0
    jpeg_quality: int = 0
    fiber_opacity: float = 0.0
    room_gain: float = 1.0
    lamp_turn_deg: float = 0.0
    lamp_tilt_deg: float = 0.0
    fill_share: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Photometric:
        try:
            return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})
        except TypeError as e:
            raise UserError(f"invalid photometric record {d!r}: {e}") from None


NOMINAL = Photometric()


@dataclass(frozen=True)
class PhotometricRanges:
    """Half-widths of uniform draws around the nominal capture (0 disables a variation).

    exposure_stops: +-stops.  white_balance: +-relative gain of red and blue against green.
    shift_mm: +-mm in x and y.  rotation_deg: +-degrees.  noise_a, noise_b: upper bounds of
    the Poisson (gain) and Gaussian (read) noise terms, drawn in [0, bound].  look: whether
    to vary the rest as :data:`LOOK` and :data:`LAMPS` say (lights, backdrop, defocus,
    vignetting, tone, JPEG; the lamps' places in front).  material: whether to vary the
    fibers' material as :data:`MATERIAL` says.
    """

    exposure_stops: float = 0.3
    white_balance: float = 0.06
    shift_mm: tuple[float, float] = field(default=(0.5, 0.15))
    rotation_deg: float = 1.5
    noise_a: float = 2e-3
    noise_b: float = 1e-5
    look: bool = False
    material: bool = False

    def __post_init__(self) -> None:
        values = {"exposure_stops": self.exposure_stops, "white_balance": self.white_balance,
                  "shift_mm": max(self.shift_mm), "rotation_deg": self.rotation_deg,
                  "noise_a": self.noise_a, "noise_b": self.noise_b}
        for name, v in values.items():
            if not 0 <= v < 1e3:
                raise UserError(f"photometric range {name} must be >= 0, got {v}")
        if self.white_balance >= 1:
            raise UserError(f"white_balance range must be < 1, got {self.white_balance}")

    def draw(self, rng: np.random.Generator) -> Photometric:
        u = rng.uniform(-1.0, 1.0, size=6)
        wb_r, wb_b = 1 + self.white_balance * u[1], 1 + self.white_balance * u[2]
        gains = np.array([wb_r, 1.0, wb_b]) * 3 / (wb_r + 1 + wb_b)
        noise = rng.uniform(0.0, 1.0, size=2) * (self.noise_a, self.noise_b)
        drawn = Photometric(
            exposure_stops=float(self.exposure_stops * u[0]),
            white_balance=tuple(float(g) for g in gains),
            shift_mm=(float(self.shift_mm[0] * u[3]), float(self.shift_mm[1] * u[4])),
            rotation_deg=float(self.rotation_deg * u[5]),
            noise=(float(noise[0]), float(noise[1])),
            noise_seed=int(rng.integers(0, 2**31 - 1)))
        if self.look:  # drawn after the rest, which stays as it was without it
            look = {k: _uniform(rng, lo, hi, log=k in LOG_LOOK) for k, (lo, hi) in LOOK.items()}
            look["jpeg_quality"] = int(round(look["jpeg_quality"])) if rng.random() < 0.5 else 0
            drawn = replace(drawn, **look)
        if self.material:  # drawn after the look, likewise
            drawn = replace(drawn, **{k: _uniform(rng, lo, hi, log=True)
                                      for k, (lo, hi) in MATERIAL.items()})
        if self.look:  # the lamps' places last, so the material's draws stay as they were
            drawn = replace(drawn, **{k: _uniform(rng, lo, hi) for k, (lo, hi) in LAMPS.items()})
        return drawn


def _uniform(rng: np.random.Generator, lo: float, hi: float, log: bool = False) -> float:
    """One draw in [lo, hi], uniform or (``log``) log-uniform; either takes one number of
    ``rng``'s stream."""
    if log:
        return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
    return float(rng.uniform(lo, hi))


NO_VARIATION = PhotometricRanges(0.0, 0.0, (0.0, 0.0), 0.0, 0.0, 0.0)
#: The ranges of the look's variations (uniform but :data:`LOG_LOOK`'s; JPEG on half of the
#: images).  The card (lamps in front) from near-black velvet to white paper (albedo
#: 0.009-1 around the scene's 0.03), since users photograph yarn over any of them; it was
#: 0.3-3 times the scene's before the nets lit in front were trained on a varied look, 0.3-10
#: (up to a mid-grey card) before they read every photo on the scene's card
#: (:meth:`ipm.photo.Photo.scene_view`; benchmarks/results/card_sweep.md).
LOOK: dict[str, tuple[float, float]] = {
    "light_gain": (0.6, 1.6), "backdrop_gain": (0.3, 33.0), "blur_mm": (0.0, 0.04),
    "vignetting": (0.0, 0.3), "gamma": (0.8, 1.25), "jpeg_quality": (60, 95)}
LOG_LOOK = frozenset({"backdrop_gain"})
#: Where the soft boxes in front stand (uniform): both turned about the view direction and
#: raised or lowered from the scene's 44 degrees above the image plane, and the second
#: lamp's strength as a share of the first's.  Why: a copy stand's lamps stand anywhere
#: around the yarn, and where the light comes from decides which side of each ply is lit
#: and so how its boundaries look (benchmarks/README.md, "Photos ipm did not make").
LAMPS: dict[str, tuple[float, float]] = {"lamp_turn_deg": (-90.0, 90.0),
                                         "lamp_tilt_deg": (-25.0, 25.0),
                                         "fill_share": (0.1, 1.0)}
#: The ranges of the material's variations (log-uniform).  Why: a renderer or a real fiber
#: that lets light through otherwise than the scene's fibers (opacity 0.5) shows another
#: grey core and other ply boundaries, and nets trained on the one opacity read Blender
#: Cycles' translucent hair as fewer plies (the Cycles pages of benchmarks/results, before
#: and after, in the model card of the nets lit from behind); a fill light in front greys
#: the silhouette too.
MATERIAL: dict[str, tuple[float, float]] = {"fiber_opacity": (0.25, 0.9),
                                           "room_gain": (0.3, 4.0)}


def apply_to_image(image: np.ndarray, ph: Photometric, pixel_size_mm: float = 0.04
                   ) -> np.ndarray:
    """Exposure, white balance, defocus (``pixel_size_mm`` converts it to pixels),
    vignetting and sensor noise on a linear image (H, W, 3) -> float32 copy."""
    out = image * (2.0 ** ph.exposure_stops * np.asarray(ph.white_balance))
    if ph.blur_mm > 0:
        out = defocus(out, ph.blur_mm / pixel_size_mm)
    if ph.vignetting > 0:
        h, w = out.shape[:2]
        y, x = np.mgrid[0:h, 0:w]
        r2 = ((x - (w - 1) / 2) ** 2 + (y - (h - 1) / 2) ** 2) / ((w / 2) ** 2 + (h / 2) ** 2)
        out = out * (1 - ph.vignetting * r2)[..., None]
    a, b = ph.noise
    if a > 0 or b > 0:
        rng = np.random.default_rng(ph.noise_seed)
        out = out + np.sqrt(a * np.maximum(out, 0) + b) * rng.standard_normal(out.shape)
    return np.maximum(out, 0).astype(np.float32)


def encode(image: np.ndarray, ph: Photometric) -> np.ndarray:
    """A linear image (H, W, 3) as the camera writes it: 8-bit sRGB, its tone curve
    (``gamma``) and, if asked, a JPEG round trip."""
    srgb = np.clip(linear_to_srgb(image), 0, 1) ** ph.gamma
    out = np.round(srgb * 255).astype(np.uint8)
    if ph.jpeg_quality:
        from PIL import Image

        buf = io.BytesIO()
        Image.fromarray(out).save(buf, format="JPEG", quality=ph.jpeg_quality)
        out = np.asarray(Image.open(io.BytesIO(buf.getvalue())).convert("RGB"))
    return out
