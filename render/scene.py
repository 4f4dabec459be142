"""THE scene: a 1:1 macro photo of a yarn in a simple lab capture, as a ``mi.load_dict`` dict.

Dataset generation, the nets' training crops and every render of the refine loop call
:func:`scene_dict` with a resolution ``scale``, a sample count and one :class:`SceneOptions`,
so they all see the same camera, lights, backdrop and fiber material.  Two capture setups
share the camera and the yarn; :mod:`ipm.setups` says which one a name is:

* lamps in front: the paper's set-up, a colour macro photo under two soft boxes in front of
  the yarn over a dark card (the rest of this docstring);
* a light behind (``light_behind``): transmitted light, as in hairiness testers and
  microscope rigs (the photos in ``../shared/real-yarns``): a bright diffuse panel behind
  the yarn, which stands out as
  a dark grey, partly translucent silhouette.  Each fiber stops a share ``opacity`` of the
  light that meets it (Mitsuba's ``mask`` over a grey diffuse BSDF, so overlapping fibers
  darken the core as cotton's translucent fibers do) and reflects a little of the panel's
  and the room's light; grey, since such photos are.  Mitsuba's ``path`` renders it, with
  the panel seen by camera rays and paths long enough to pass a ply's fibers.

World frame (mm): image right = +x, image up = +y, the camera looks down -z.  The yarn lies
along x through the origin (generator axis z -> world x, generator x -> world y, generator
y -> world z: a cyclic permutation, so a rotation).

* Camera: orthographic.  A 90 mm macro lens at 1:1 sees the yarn at ~30 cm through a ~3 cm
  aperture, so perspective across the yarn's few mm of depth changes the magnification by
  about 1 %; an orthographic view makes the pixel pitch exact everywhere
  (:data:`ipm.frame.PIXEL_SIZE_MM` / ``scale``) and so an image tells absolute sizes.
* Light: two soft boxes above-left and above-right in front of the yarn (the usual two-lamp
  copy stand; a varied look turns and tilts them, :func:`soft_boxes`) and a dim uniform
  room light; the backdrop is a matte dark-grey card far enough behind the yarn (50 mm)
  that no flyaway crosses it and out of the lights' specular path.
* Fibers: Mitsuba's ``principled`` BSDF with the yarn's albedo as base colour, a rough
  specular lobe and sheen (the soft grazing highlight of textile fibers).  Mitsuba's
  ``hair`` BSDF (Chiang et al. 2016, behind the Blender shader the paper used) was slower
  (it needs a deeper path for light through fibers), noisier (glints) and dark and
  desaturated under these lights; ``principled`` reproduces the yarn's colour.
* Pixels integrate their footprint with a box filter, like a sensor pixel (a Gaussian
  reconstruction filter's scattered splats cost several times the render time).  Sample
  positions are stratified (Mitsuba's ``multijitter`` sampler): a fiber thinner than a pixel
  makes coverage a large part of the noise, and stratified positions estimate it better
  than independent ones (benchmarks/results/render_speed.md).
* Next-event estimation (``ipm_path``, :mod:`ipm.render.integrator`) samples at every
  vertex one soft box, chosen by how much of it is above the surface's horizon times its
  share of the light (:data:`LIGHT_WEIGHTS`), and leaves the room light to the BSDF's
  samples: less noise than Mitsuba's ``path`` in about the same time.  With ``path``
  (``SceneOptions(integrator="path")``) the lights are picked by :data:`LIGHT_WEIGHTS`, not
  with Mitsuba's equal probability (benchmarks/results/noise_levers.md).
* Cross-sections: Mitsuba's curves are round; each fiber gets the radius sqrt(t_x t_y) of
  the circle with its ellipse's area (:meth:`ipm.FiberSet.round_radii`), so the fiber
  volume, and with it how much a ply of ``m`` fibers fills, is kept.  Seen from random
  directions an ellipse's silhouette is on average perimeter / pi wide, which is 2.4 %
  (thin class, t_x/t_y = 1.43), 6.5 % (thick class, 1.8) and at most 16 % (the sampler's
  t_x/t_y = 2.5) wider than 2 sqrt(t_x t_y): at the dataset's 0.02 mm pixels that is 0.02,
  0.09 and at most 0.2 px per fiber.  What is lost is the highlight change the paper shows
  in its cross-section figure (a-c).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from ipm.errors import UserError
from ipm.frame import FRAME_HEIGHT_PX, FRAME_WIDTH_PX, pixel_size_mm
from ipm.render.integrator import PLUGIN, register
from ipm.setups import DEFAULT_SETUP, setup_of

if TYPE_CHECKING:
    from ipm.render.photometric import Photometric

#: Generator frame (x, y, z) -> world frame: the yarn axis z becomes the image horizontal.
GENERATOR_TO_WORLD = np.array([[0, 0, 1], [1, 0, 0], [0, 1, 0]], dtype=np.float64)
BACKDROP_DEPTH_MM = 50.0
CAMERA_DISTANCE_MM = 300.0
SAMPLERS = ("multijitter", "independent", "stratified", "ldsampler", "orthogonal")
#: The soft boxes where the scene stands them: name, centre (mm), side (mm).  The first
#: shines with ``key_light``, the second with ``fill_share`` of it (:class:`SceneOptions`);
#: :func:`soft_boxes` turns and tilts them as a capture's look says.
SOFT_BOXES = (("key_left", (-200.0, 50.0, 200.0), 150.0),
              ("key_right", (200.0, -30.0, 200.0), 150.0))
#: How often ``path``'s next-event estimation picks each light, relative to each other
#: (Mitsuba picks them with equal probability unless told): the soft boxes by their radiance
#: share; the room light rarely, because Mitsuba samples a constant emitter's directions over
#: the whole sphere (half of them below the fiber's surface) while the BSDF's own samples
#: find it well and multiple importance sampling weighs them in.  The expected image is the
#: same, the noise lower (benchmarks/results/noise_levers.md).  ``ipm_path`` weighs the soft
#: boxes' reach by these and never light-samples the room.
LIGHT_WEIGHTS = {"key_left": 1.0, "key_right": 0.6, "room": 0.05}
LIGHT_SAMPLING = ("weighted", "uniform")
#: :mod:`ipm.render.integrator`'s lamp choice by reach, or Mitsuba's ``path`` (the scene's
#: integrator before ``ipm_path``, and the one scalar variants use).
INTEGRATORS = (PLUGIN, "path")



@dataclass(frozen=True)
class SceneOptions:
    """What stays fixed across a dataset: the capture setup, fiber material, lights, depth.

    setup: a name of :data:`ipm.setups.SETUPS` (module doc).  roughness, sheen: of the
    fibers' principled BSDF (lamps in front).  backdrop: albedo of the grey card (lamps in
    front).  key_light: radiance of the left soft box, fill_share the right one's as a share
    of it, lamp_turn and lamp_tilt (degrees) how far both are turned about the view
    direction and raised from where :data:`SOFT_BOXES` stands them (:func:`soft_boxes`).
    panel: radiance of the light panel behind the yarn (light behind).  opacity: share of
    the light a fiber stops (light behind).  room_light: uniform fill radiance.  max_depth:
    path length (3 = one bounce between fibers; a light behind: enough to pass through a
    ply).  sampler: Mitsuba's pixel sampler (see the module doc).  light_sampling: the
    lamps' ``sampling_weight`` (:data:`LIGHT_WEIGHTS` or all equal).  integrator: see
    :data:`INTEGRATORS` (a light behind: ``path``, whose camera rays see the panel).
    """

    setup: str = DEFAULT_SETUP
    roughness: float = 0.5
    sheen: float = 0.5
    backdrop: float = 0.03
    key_light: float = 5.0
    fill_share: float = 0.6
    lamp_turn: float = 0.0
    lamp_tilt: float = 0.0
    panel: float = 0.6
    opacity: float = 0.5
    room_light: float = 0.15
    max_depth: int = 3
    sampler: str = "multijitter"
    light_sampling: str = "weighted"
    integrator: str = PLUGIN

    def __post_init__(self) -> None:
        if setup_of(self.setup).light_behind and self.integrator != "path":
            raise UserError(f"the {self.setup} setup renders with integrator 'path' (its "
                            f"camera rays must see the panel), not {self.integrator!r}")
        if not 0 < self.opacity <= 1:
            raise UserError(f"fiber opacity must be in (0, 1], got {self.opacity}")
        if self.sampler not in SAMPLERS:
            raise UserError(f"unknown sampler {self.sampler!r}; one of {', '.join(SAMPLERS)}")
        if self.light_sampling not in LIGHT_SAMPLING:
            raise UserError(f"unknown light sampling {self.light_sampling!r}; one of "
                            f"{', '.join(LIGHT_SAMPLING)}")
        if self.integrator not in INTEGRATORS:
            raise UserError(f"unknown integrator {self.integrator!r}; one of "
                            f"{', '.join(INTEGRATORS)}")
        if not 0.01 <= self.roughness <= 1:
            raise UserError(f"roughness must be in [0.01, 1], got {self.roughness}")
        if not 0 <= self.sheen <= 1:
            raise UserError(f"sheen must be in [0, 1], got {self.sheen}")
        if not 0 < self.fill_share <= 1:
            raise UserError(f"fill_share must be in (0, 1], got {self.fill_share}")
        if not 0 <= self.backdrop <= 1:
            raise UserError(f"backdrop albedo must be in [0, 1], got {self.backdrop}")
        if self.max_depth < 2:
            raise UserError(f"max_depth must be >= 2, got {self.max_depth}")


DEFAULT_OPTIONS = SceneOptions()


def lit_from_behind(opts: SceneOptions) -> bool:
    """Whether ``opts``' setup lights the yarn from behind (:mod:`ipm.setups`)."""
    return setup_of(opts.setup).light_behind


def scaled_options(opts: SceneOptions, look: Photometric) -> SceneOptions:
    """``opts`` as a capture ``look`` sees it: its lamps (soft boxes or panel) ``light_gain``
    and its card's albedo ``backdrop_gain`` times as strong, its room light ``room_gain``
    times, its fibers' opacity ``fiber_opacity`` and its second lamp's ``fill_share`` (0: as
    they are), its soft boxes turned and tilted by ``lamp_turn_deg`` and ``lamp_tilt_deg``."""
    return replace(opts, key_light=opts.key_light * look.light_gain,
                   panel=opts.panel * look.light_gain,
                   backdrop=min(1.0, opts.backdrop * look.backdrop_gain),
                   room_light=opts.room_light * look.room_gain,
                   opacity=look.fiber_opacity if look.fiber_opacity > 0 else opts.opacity,
                   fill_share=look.fill_share if look.fill_share > 0 else opts.fill_share,
                   lamp_turn=opts.lamp_turn + look.lamp_turn_deg,
                   lamp_tilt=opts.lamp_tilt + look.lamp_tilt_deg)


def soft_boxes(opts: SceneOptions) -> list[tuple[str, tuple[float, float, float], float, float]]:
    """The soft boxes in front as ``opts`` stands them: (name, centre (mm), side (mm),
    radiance).  Each centre keeps its distance from the yarn; its azimuth about the view
    direction turns by ``lamp_turn`` and its elevation above the image plane by
    ``lamp_tilt`` (kept within 5-85 degrees); unturned and untilted, the centres are
    :data:`SOFT_BOXES`' exactly."""
    out = []
    for (name, centre, side), share in zip(SOFT_BOXES, (1.0, opts.fill_share), strict=True):
        if opts.lamp_turn or opts.lamp_tilt:
            x, y, z = centre
            dist, across = math.sqrt(x * x + y * y + z * z), math.hypot(x, y)
            elevation = min(max(math.atan2(z, across) + math.radians(opts.lamp_tilt),
                                math.radians(5)), math.radians(85))
            azimuth = math.atan2(y, x) + math.radians(opts.lamp_turn)
            centre = (dist * math.cos(elevation) * math.cos(azimuth),
                      dist * math.cos(elevation) * math.sin(azimuth), dist * math.sin(elevation))
        out.append((name, centre, side, share * opts.key_light))
    return out


def look_parameters(opts: SceneOptions) -> dict[str, Any]:
    """The ``mi.traverse`` keys and values of ``opts``' lamps (strength and, in front, place),
    card, room light and (light behind) fiber opacity, so that a loaded scene takes another
    :func:`scaled_options` without loading anew."""
    room = {"room.radiance.value": opts.room_light}
    if lit_from_behind(opts):
        return {"panel.emitter.radiance.value": opts.panel,
                "yarn.bsdf.opacity.value": opts.opacity, **room}
    lamps = {}
    for name, centre, side, radiance in soft_boxes(opts):
        lamps[f"{name}.emitter.radiance.value"] = radiance
        lamps[f"{name}.to_world"] = _soft_box_to_world(centre, side)
    return {"backdrop.bsdf.reflectance.value": opts.backdrop, **lamps, **room}


def setup_options(name: str, card: float | None = None) -> SceneOptions:
    """The scene of capture setup ``name`` (:data:`ipm.setups.SETUPS`; one line naming the
    choices if unknown); ``--setup NAME`` picks one in every command.  ``card``: the card's
    albedo behind a yarn lit from the front (``--card``; refused for a light panel)."""
    opts = SceneOptions(setup=name, **setup_of(name).scene)
    if card is None:
        return opts
    if setup_of(name).light_behind:
        raise UserError(f"--card is the card behind a yarn lit from the front; the {name} "
                        "setup's background is its light panel")
    return replace(opts, backdrop=card)


@dataclass(frozen=True)
class Frame:
    """A view other than the yarn frame (a knitted patch, a photo's smaller field, a detail
    window for the nets): ``width`` x ``height`` pixels of ``pixel_size_mm`` each, centred on
    the world origin; camera, lights and card as ever."""

    width: int
    height: int
    pixel_size_mm: float


def frame_size(scale: float) -> tuple[int, int]:
    """(width, height) in pixels of the frame at ``scale`` (1 = 2000 x 600)."""
    if not 0.05 <= scale <= 2:
        raise UserError(f"scale must be in [0.05, 2], got {scale}")
    return round(FRAME_WIDTH_PX * scale), round(FRAME_HEIGHT_PX * scale)


def yarn_to_world(shift_mm: tuple[float, float] = (0.0, 0.0), rotation_deg: float = 0.0
                  ) -> np.ndarray:
    """(4, 4) transform of generator coordinates into the world: the axis permutation, a
    rotation about the view direction and a shift in the image plane (x right, y up)."""
    a = math.radians(rotation_deg)
    rot = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = rot @ GENERATOR_TO_WORLD
    m[:2, 3] = shift_mm
    return m


def fiber_albedo(color: tuple[float, float, float], opts: SceneOptions
                 ) -> tuple[float, float, float]:
    """The fibers' albedo in ``opts``' setup: the yarn's colour, or in a grey setup its
    luminance (Rec. 709 weights)."""
    if setup_of(opts.setup).grey:
        grey = 0.2126 * color[0] + 0.7152 * color[1] + 0.0722 * color[2]
        return (grey, grey, grey)
    return tuple(color)


def albedo_parameter(opts: SceneOptions) -> str:
    """The ``mi.traverse`` key of the fibers' albedo, swapped per yarn."""
    return ("yarn.bsdf.nested_bsdf.reflectance.value" if lit_from_behind(opts)
            else "yarn.bsdf.base_color.value")


def fiber_bsdf(color: tuple[float, float, float], opts: SceneOptions) -> dict[str, Any]:
    """The fibers' BSDF (:func:`albedo_parameter` is swapped per yarn through
    ``mi.traverse``): lamps in front a principled BSDF, a light behind a diffuse one that
    lets ``1 - opacity`` of the light through."""
    albedo = {"type": "rgb", "value": list(fiber_albedo(color, opts))}
    if lit_from_behind(opts):
        return {"type": "mask", "opacity": opts.opacity,
                "bsdf": {"type": "diffuse", "reflectance": albedo}}
    return {"type": "principled", "base_color": albedo,
            "roughness": opts.roughness, "specular": 0.4, "sheen": opts.sheen}


def _emitter(kind: str, name: str, radiance: float, opts: SceneOptions) -> dict[str, Any]:
    """Mitsuba emitter ``kind`` of ``radiance``, the light ``name``'s sampling weight as
    ``opts`` asks."""
    weight = LIGHT_WEIGHTS[name] if opts.light_sampling == "weighted" else 1.0
    return {"type": kind, "radiance": {"type": "rgb", "value": [radiance] * 3},
            "sampling_weight": weight}


def _soft_box_to_world(position: tuple[float, float, float], size_mm: float) -> Any:
    """The transform of a square lamp of side ``size_mm`` at ``position`` facing the yarn."""
    import mitsuba as mi

    t = mi.ScalarTransform4f().look_at(origin=list(position), target=[0, 0, 0], up=[0, 1, 0])
    return t @ mi.ScalarTransform4f().scale(size_mm / 2)


def _soft_box(name: str, position: tuple[float, float, float], size_mm: float,
              radiance: float, opts: SceneOptions) -> dict[str, Any]:
    return {"type": "rectangle", "to_world": _soft_box_to_world(position, size_mm),
            "emitter": _emitter("area", name, radiance, opts)}


def integrator_dict(mi: ModuleType, opts: SceneOptions) -> dict[str, Any]:
    """``opts.integrator`` for the variant set in ``mi``; scalar variants run ``path``.
    Emitters are hidden from camera rays but for a panel behind the yarn."""
    if opts.integrator == PLUGIN and not mi.variant().startswith("scalar"):
        register(mi)
        return {"type": PLUGIN, "max_depth": opts.max_depth}
    return {"type": "path", "max_depth": opts.max_depth,
            "hide_emitters": not lit_from_behind(opts)}


def _lights(opts: SceneOptions) -> dict[str, Any]:
    """The setup's backdrop and lights: the card under two soft boxes, or the panel."""
    import mitsuba as mi

    T = mi.ScalarTransform4f
    behind = T().translate([0, 0, -BACKDROP_DEPTH_MM]) @ T().scale(200)
    room = {"room": _emitter("constant", "room", opts.room_light, opts)}
    if lit_from_behind(opts):  # a rectangle faces +z, the camera
        return {"panel": {"type": "rectangle", "to_world": behind,
                          "emitter": {"type": "area",
                                      "radiance": {"type": "rgb", "value": [opts.panel] * 3}}},
                **room}
    return {"backdrop": {"type": "rectangle", "to_world": behind,
                         "bsdf": {"type": "diffuse",
                                  "reflectance": {"type": "rgb", "value": [opts.backdrop] * 3}}},
            **{name: _soft_box(name, centre, side, radiance, opts)
               for name, centre, side, radiance in soft_boxes(opts)},
            **room}


def scene_dict(scale: float, spp: int, curves: str, color: tuple[float, float, float],
               opts: SceneOptions = DEFAULT_OPTIONS,
               to_world: np.ndarray | None = None, frame: Frame | None = None
               ) -> dict[str, Any]:
    """The scene for :func:`mi.load_dict`, rendering at ``scale`` x (2000 x 600) px.

    curves: a Mitsuba ``linearcurve`` file (``x y z radius`` in generator coordinates, see
    :meth:`ipm.FiberSet.save_mitsuba`); the shape's id is ``yarn`` so that
    ``yarn.control_points`` (world space) can be swapped through ``mi.traverse``.
    color: linear RGB albedo of the fibers.  to_world: (4, 4) from :func:`yarn_to_world`.
    frame: another view than the yarn frame at ``scale`` (a knitted patch).
    Needs the Mitsuba variant set (:func:`ipm.render.variant.mitsuba`).
    """
    import mitsuba as mi

    if frame is None:
        width, height = frame_size(scale)
        half_width = width * pixel_size_mm(scale) / 2
    else:
        width, height, half_width = frame.width, frame.height, frame.width * frame.pixel_size_mm / 2
    T = mi.ScalarTransform4f
    camera = (T().look_at(origin=[0, 0, CAMERA_DISTANCE_MM], target=[0, 0, 0], up=[0, 1, 0])
              @ T().scale([half_width, half_width, 1]))
    matrix = yarn_to_world() if to_world is None else to_world
    return {
        "type": "scene",
        "integrator": integrator_dict(mi, opts),
        "sensor": {"type": "orthographic", "to_world": camera,
                   "sampler": {"type": opts.sampler, "sample_count": spp},
                   "film": {"type": "hdrfilm", "width": width, "height": height,
                            "pixel_format": "rgb", "rfilter": {"type": "box"}}},
        "yarn": {"type": "linearcurve", "filename": curves, "to_world": T(matrix.tolist()),
                 "bsdf": fiber_bsdf(color, opts)},
        **_lights(opts),
    }
