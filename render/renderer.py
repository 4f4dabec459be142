"""Render procedural yarns in THE scene, keeping compiled kernels across images.

Mitsuba compiles a kernel per scene and resolution; a new seed, sample count or new curve
buffers do not recompile.  A :class:`Renderer` therefore loads one scene per ``scale`` in
its process and, per image, swaps the yarn's curve buffers (``yarn.control_points``,
``yarn.segment_indices``, ``yarn.control_point_count``: world space) and fiber colour
through ``mi.traverse``.
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ipm.fibers import FiberSet
from ipm.frame import YARN_LENGTH_MM, pixel_size_mm
from ipm.generator import generate
from ipm.params import YarnParams
from ipm.photo import linear_to_srgb, srgb_to_linear, write_png
from ipm.render.photometric import NOMINAL, Photometric, apply_to_image
from ipm.render.scene import (
    DEFAULT_OPTIONS,
    Frame,
    SceneOptions,
    albedo_parameter,
    fiber_albedo,
    frame_size,
    look_parameters,
    scaled_options,
    scene_dict,
    yarn_to_world,
)
from ipm.render.variant import mitsuba
from ipm.setups import setup_of

#: Bytes per fiber vertex a render takes beyond the fibers: :func:`world_curves`' float64
#: work arrays and float32 buffers, their copies in Dr.Jit, and the curves' BVH.
RENDER_BYTES_PER_VERTEX = 120
#: Dr.Jit counts a render's samples (pixels x samples per pixel) in 32 bits: at 2^32 or more
#: it crashed the process, so such a render is refused (:func:`check_sample_count`).
MAX_SAMPLES = 2 ** 32
#: A two-vertex fiber: the curve file the scenes are loaded with before any swap.
_PLACEHOLDER_CURVE = "0 0 -1 0.01\n0 0 1 0.01\n"


def check_sample_count(width: int, height: int, spp: int) -> None:
    """Refuse, in one line, a render of :data:`MAX_SAMPLES` samples or more (the sampler
    may round ``spp`` up to a product of two near-equal integers: counted so)."""
    side = math.ceil(math.sqrt(spp))
    if width * height * side * math.ceil(spp / side) >= MAX_SAMPLES:
        from ipm.errors import UserError

        most = (MAX_SAMPLES - 1) // (width * height)
        most = max(most - 2 * math.isqrt(most) - 1, 0)  # room for the sampler's rounding
        raise UserError(f"{width}x{height} px at {spp} samples per pixel is "
                        f"{width * height * spp:,} samples, more than the renderer can take "
                        f"(under 2^32); lower --spp (to {most:,} or less here) or the image "
                        "size")


def world_curves(fibers: FiberSet, to_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mitsuba ``linearcurve`` buffers of a fiber set placed by ``to_world`` (4, 4).

    Returns control points (V, 4) float32 (x, y, z, radius) in world mm, and segment indices
    (S,) uint32: the first control point of every segment (all but each fiber's last).
    """
    xyz = fibers.points.astype(np.float64) @ to_world[:3, :3].T + to_world[:3, 3]
    radius = np.repeat(fibers.round_radii(), np.diff(fibers.offsets))
    points = np.column_stack([xyz, radius]).astype(np.float32)
    last = np.zeros(len(points), dtype=bool)
    last[fibers.offsets[1:] - 1] = True
    return points, np.flatnonzero(~last).astype(np.uint32)


class Renderer:
    """Renders yarns in THE scene; one per process (kernels are compiled once per scale):
    ``Renderer().render(preset("rose"), seed=0, scale=0.25, spp=4)`` is a (150, 500, 3)
    float32 linear-light image."""

    def __init__(self, variant: str | None = None, options: SceneOptions = DEFAULT_OPTIONS,
                 threads: int | None = None) -> None:
        self.mi = mitsuba(variant)
        self.options = options
        self._scenes: dict[float, tuple[object, object]] = {}
        if threads is not None:
            import drjit as dr

            dr.set_thread_count(threads)

    @property
    def variant(self) -> str:
        return self.mi.variant()

    def settings(self, scale: float, spp: int, render_seed: int) -> dict:
        """What a saved image records about how it was rendered (JSON-ready)."""
        width, height = frame_size(scale)
        return {"scale": scale, "spp": spp, "render_seed": render_seed, "width": width,
                "height": height, "pixel_size_mm": pixel_size_mm(scale),
                "setup": self.options.setup, "variant": self.variant, "scene": asdict(self.options)}

    def _load(self, scale: float, curve_text: str, color: tuple[float, float, float],
              to_world: np.ndarray | None = None, frame: Frame | None = None,
              options: SceneOptions | None = None) -> object:
        with tempfile.TemporaryDirectory(prefix="ipm-scene-") as tmp:
            curves = Path(tmp, "curves.txt")
            curves.write_text(curve_text)
            # optimize=False, parallel=False: the shapes in the dict's order.  Mitsuba's
            # merging of similar objects put the two soft boxes in an order that changed from
            # process to process, and with them swapped the emitter sampling gives the same
            # random numbers to the other lamp: about one process in eight rendered every
            # image with other noise (benchmarks/determinism.py)
            return self.mi.load_dict(scene_dict(scale, 1, str(curves), color,
                                                options or self.options, to_world, frame),
                                     parallel=False, optimize=False)

    def _scene(self, scale: float, frame: Frame | None = None) -> tuple[object, object]:
        key = (scale, frame)
        if key not in self._scenes:
            scene = self._load(scale, _PLACEHOLDER_CURVE, (0.5, 0.5, 0.5), frame=frame)
            # One render of the new scene before any image: on some CPUs (an AMD EPYC) the
            # first render of a loaded scene differed from every later one with the same
            # settings in the last bit of many pixels; after it, all agree
            # (tests/test_render.py::test_same_settings_same_image).
            self.mi.render(scene, spp=1, seed=0)
            self._scenes[key] = (scene, self.mi.traverse(scene))
        return self._scenes[key]

    def sample_count(self, scale: float, spp: int, frame: Frame | None = None) -> int:
        """The samples per pixel the scene's sampler takes when asked for ``spp``: multijitter
        rounds up to a product of two near-equal integers (7 -> 8, 13 -> 15), orthogonal to a
        prime square.  Rendering with the count this returns logs no rounding warning.  Asked
        of the scene that renders ``frame`` (a view), so that no other scene is loaded."""
        sampler = self._scene(scale, frame)[0].sensors()[0].sampler()
        logger = self.mi.Thread.thread().logger()
        level = logger.log_level()
        logger.set_log_level(self.mi.LogLevel.Error)
        try:
            sampler.set_sample_count(spp)  # every render sets its own count again
        finally:
            logger.set_log_level(level)
        return int(sampler.sample_count())

    def render_fibers(self, fibers: FiberSet, color: tuple[float, float, float], scale: float,
                      spp: int, render_seed: int = 0, to_world: np.ndarray | None = None,
                      frame: Frame | None = None, look: Photometric = NOMINAL
                      ) -> np.ndarray:
        """Linear RGB image (H, W, 3) float32 of ``fibers`` (generator frame) with albedo
        ``color``, placed by ``to_world`` (default: :func:`yarn_to_world` centred), in the
        yarn frame at ``scale`` or in ``frame``, its lamps, card, fiber opacity and room light
        as the capture ``look`` says (:func:`ipm.render.scene.scaled_options`; the image
        variations of ``look`` are :meth:`render`'s)."""
        if spp < 1:
            raise ValueError(f"spp must be >= 1, got {spp}")
        width, height = (frame.width, frame.height) if frame is not None else frame_size(scale)
        check_sample_count(width, height, spp)
        to_world = yarn_to_world() if to_world is None else to_world
        options = scaled_options(self.options, look)
        if self.variant.startswith("scalar"):
            # no kernels to keep, and scalar buffers cannot change size: load the yarn anew
            scene = self._load(scale, fibers.mitsuba_curve_text(), color, to_world, frame,
                               options)
        else:
            scene, params = self._scene(scale, frame)
            points, segments = world_curves(fibers, to_world)
            params["yarn.control_points"] = self.mi.Float(points.ravel())
            params["yarn.segment_indices"] = self.mi.UInt32(segments)
            params["yarn.control_point_count"] = len(points)
            params[albedo_parameter(self.options)] = self.mi.Color3f(
                *fiber_albedo(color, self.options))
            for key, value in look_parameters(options).items():  # every time: scenes are kept
                params[key] = type(params[key])(value)  # a grey colour, a float, a transform
            params.update()
        image = self.mi.render(scene, spp=spp, seed=render_seed)
        return np.array(image, dtype=np.float32)[..., :3]

    def render(self, params: YarnParams, seed: int, scale: float, spp: int,
               render_seed: int = 0, photometric: Photometric = NOMINAL,
               frame: Frame | None = None, length: float = YARN_LENGTH_MM) -> np.ndarray:
        """Linear RGB image (H, W, 3) float32 of the yarn ``generate(params, seed, length)``,
        with the capture variation ``photometric`` applied (geometry and image), in the yarn
        frame at ``scale`` or in ``frame`` (a photo's smaller field of view at its own
        pitch); in a grey setup (:attr:`ipm.setups.CaptureSetup.grey`, a monochrome sensor)
        the channels' mean in all three."""
        to_world = yarn_to_world(photometric.shift_mm, photometric.rotation_deg)
        image = self.render_fibers(generate(params, seed, length), params.color, scale, spp,
                                   render_seed, to_world, frame, look=photometric)
        if photometric != NOMINAL:
            pitch = frame.pixel_size_mm if frame is not None else pixel_size_mm(scale)
            image = apply_to_image(image, photometric, pitch)
        if setup_of(self.options.setup).grey:
            image = np.repeat(image.mean(axis=-1, keepdims=True), 3, axis=-1)
        return image


def to_srgb8(image: np.ndarray) -> np.ndarray:
    """Linear RGB (H, W, 3) float -> 8-bit sRGB (H, W, 3) uint8 (the sRGB curve, clipped)."""
    return np.round(linear_to_srgb(image) * 255.0).astype(np.uint8)


def srgb8_to_linear(image: np.ndarray) -> np.ndarray:
    """8-bit sRGB (H, W, 3) uint8 -> linear RGB float32 in [0, 1]."""
    return srgb_to_linear(image.astype(np.float32) / 255.0)


def save_png(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write a linear image (H, W, 3) float as an 8-bit sRGB RGB PNG, atomically."""
    write_png(path, to_srgb8(image))
