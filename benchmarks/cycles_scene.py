"""THE scene rebuilt in Blender Cycles, the paper's renderer, to time it beside ipm's renders.

Runs inside Blender's Python (``pip install bpy`` in its own environment: bpy pins its own
numpy), not in ipm's; :mod:`ipm.benchmarks.blender_compare` writes its input and reads its
output.  Input: an ``.npz`` with the yarn's fibers in world mm (``points`` (V, 3),
``offsets`` (F+1,), ``radius`` (F,)), its linear ``color`` and the scene's numbers
(``frame`` (width, height) in px, ``frame_mm`` width in mm, the soft boxes, room light and
backdrop of :func:`ipm.render.scene.scene_dict`).  The fibers are Blender hair curves with,
by default, the paper's Principled Hair BSDF (direct colouring with the yarn's colour), or
``--material principled``, ipm's fiber BSDF; the light sources, camera and backdrop are
those of ipm's scene.  Cycles runs with its defaults (adaptive sampling, 12 bounces unless
``--bounces``) on the CPU with ``--threads``, no denoiser (the noise is what is measured).
Output per ``--seeds`` entry: a 16-bit sRGB PNG, its values as ``.npy`` (H, W, 3) float32,
and on stdout a JSON line with the render's wall time (scene sync, BVH build and path
tracing).

    python cycles_scene.py yarn.npz OUT_PREFIX --samples 64 --seeds 1 2 --threads 2
        [--material hair|principled] [--bounces N]
"""

from __future__ import annotations

import argparse
import json
import math
import time

import bpy
import numpy as np
from mathutils import Vector


def fiber_material(data: dict, material: str) -> bpy.types.Material:
    """``hair``: the paper's Principled Hair BSDF (Chiang), coloured directly.
    ``principled``: ipm's fiber BSDF (:func:`ipm.render.scene.fiber_bsdf`)."""
    mat = bpy.data.materials.new("fibers")
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    color = (*[float(c) for c in data["color"]], 1.0)
    if material == "principled":
        bsdf = nodes["Principled BSDF"]
        bsdf.inputs["Base Color"].default_value = color
        bsdf.inputs["Roughness"].default_value = float(data["roughness"])
        bsdf.inputs["Specular IOR Level"].default_value = 0.4
        bsdf.inputs["Sheen Weight"].default_value = float(data["sheen"])
        return mat
    nodes.remove(nodes["Principled BSDF"])
    bsdf = nodes.new("ShaderNodeBsdfHairPrincipled")
    bsdf.parametrization = "COLOR"
    bsdf.inputs["Color"].default_value = color
    mat.node_tree.links.new(bsdf.outputs[0], nodes["Material Output"].inputs["Surface"])
    return mat


def build(data: dict, samples: int, threads: int, material: str, bounces: int | None
          ) -> bpy.types.Scene:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    if bounces is not None:
        scene.cycles.max_bounces = bounces
    scene.render.threads_mode = "FIXED"
    scene.render.threads = threads
    width, height = (int(v) for v in data["frame"])
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.dither_intensity = 0.0
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_depth = "16"
    scene.view_settings.view_transform = "Standard"

    cam_data = bpy.data.cameras.new("camera")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = float(data["frame_mm"])
    cam_data.clip_end = 1000.0
    camera = bpy.data.objects.new("camera", cam_data)
    camera.location = (0.0, 0.0, float(data["camera_distance"]))
    scene.collection.objects.link(camera)
    scene.camera = camera

    for i, (x, y, z, size, radiance) in enumerate(data["soft_boxes"]):
        name = f"soft_box_{i}"
        light = bpy.data.lights.new(name, "AREA")
        light.shape, light.size = "SQUARE", float(size)
        light.energy = float(radiance) * math.pi * float(size) ** 2  # W of a Lambertian square
        obj = bpy.data.objects.new(name, light)
        obj.location = (x, y, z)
        obj.rotation_euler = (-Vector((x, y, z))).to_track_quat("-Z", "Y").to_euler()
        scene.collection.objects.link(obj)

    world = bpy.data.worlds.new("room")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = \
        (*[float(data["room_light"])] * 3, 1.0)
    scene.world = world

    bpy.ops.mesh.primitive_plane_add(size=400.0, location=(0, 0, -float(data["backdrop_depth"])))
    card = bpy.context.object
    card_mat = bpy.data.materials.new("card")
    card_mat.use_nodes = True
    card_mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = \
        (*[float(data["backdrop"])] * 3, 1.0)
    card_mat.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = 1.0
    card.data.materials.append(card_mat)

    add_yarn(scene, data, fiber_material(data, material))
    return scene


def add_yarn(scene: bpy.types.Scene, data: dict, material: bpy.types.Material) -> None:
    """The fibers (``points``, ``offsets``, ``radius`` of the npz) as Blender hair curves."""
    offsets = data["offsets"].astype(np.int64)
    curves = bpy.data.hair_curves.new("yarn")
    curves.add_curves(np.diff(offsets).tolist())
    curves.position_data.foreach_set("vector", data["points"].astype(np.float32).ravel())
    radius = np.repeat(data["radius"], np.diff(offsets)).astype(np.float32)
    curves.attributes.new("radius", "FLOAT", "POINT").data.foreach_set("value", radius)
    curves.materials.append(material)
    scene.collection.objects.link(bpy.data.objects.new("yarn", curves))


def srgb_pixels(path: str) -> np.ndarray:
    """(H, W, 3) float32 sRGB values of a 16-bit PNG, top row first, at full precision
    (Pillow, on ipm's side, reads 16-bit colour at 8 bits)."""
    image = bpy.data.images.load(path)
    image.colorspace_settings.name = "Non-Color"  # the stored sRGB codes, not linearised
    w, h = image.size
    pixels = np.empty(w * h * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return pixels.reshape(h, w, 4)[::-1, :, :3].copy()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("npz")
    ap.add_argument("out_prefix")
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--material", choices=("hair", "principled"), default="hair")
    ap.add_argument("--bounces", type=int, default=None, help="default: Cycles' (12)")
    args = ap.parse_args()
    data = dict(np.load(args.npz))
    scene = build(data, args.samples, args.threads, args.material, args.bounces)
    scene.cycles.samples = 1  # warm-up: the first render of a process loads Cycles' kernels
    scene.render.filepath = f"{args.out_prefix}_warmup.png"
    bpy.ops.render.render(write_still=True)
    scene.cycles.samples = args.samples
    for seed in args.seeds:
        scene.cycles.seed = seed
        scene.render.filepath = f"{args.out_prefix}_s{seed}.png"
        t0 = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        seconds = time.perf_counter() - t0
        np.save(f"{args.out_prefix}_s{seed}.npy", srgb_pixels(scene.render.filepath))
        print(json.dumps({"seed": seed, "samples": args.samples, "seconds": seconds,
                          "image": scene.render.filepath}), flush=True)


if __name__ == "__main__":
    main()
