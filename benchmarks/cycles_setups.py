"""Two capture setups in Blender Cycles that are NOT ipm's scene, for the cross-renderer test
sets (:mod:`ipm.benchmarks.cycles_testset` writes the input and reads the output).

Runs inside Blender's Python (``bash scripts/install_blender.sh``).  Everything but the
fibers differs from ipm's scene: a perspective camera (100 mm lens at 300 mm, its sensor
sized to the frame), the paper's Principled Hair BSDF (Chiang) coloured directly, Cycles'
own sampling, 8-bit sRGB output, and per sample (values drawn on ipm's side, in the npz):

* ``frontlit``: one large diffused lamp above and in front (direction, size, power) and a
  weak fill from below, a matte card behind (grey level and tint), a dim room;
* ``backlit``: a bright emissive panel behind the yarn (level), a very dim front fill; the
  yarn is a dark, partly translucent silhouette; the image is stored in grayscale.

Both: the camera rolls by a small angle, focuses a little before or behind the yarn (thin
lens, f-number drawn: defocus) and the exposure varies.

    python cycles_setups.py batch.json   # a list of {"npz": ..., "png": ...}
"""

from __future__ import annotations

import json
import math
import sys
import time

import bpy
import numpy as np
from cycles_scene import add_yarn  # beside this script, in Blender's Python
from mathutils import Vector

LENS_MM = 100.0
DISTANCE_MM = 300.0


def area_light(scene, name: str, location, size: float, power: float, target=(0, 0, 0)):
    light = bpy.data.lights.new(name, "AREA")
    light.shape, light.size, light.energy = "SQUARE", size, power
    obj = bpy.data.objects.new(name, light)
    obj.location = location
    obj.rotation_euler = (Vector(target) - Vector(location)).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(obj)


def plane(name: str, size: float, z: float, color, emission: float = 0.0):
    bpy.ops.mesh.primitive_plane_add(size=size, location=(0, 0, z))
    obj = bpy.context.object
    obj.name = name
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.9
    if emission > 0:
        bsdf.inputs["Emission Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        bsdf.inputs["Emission Strength"].default_value = emission
    obj.data.materials.append(mat)


def build(d: dict) -> bpy.types.Scene:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = int(d["samples"])
    scene.cycles.seed = int(d["seed"])
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 4
    scene.render.threads_mode = "FIXED"
    scene.render.threads = int(d["threads"])
    width, height = (int(v) for v in d["frame"])
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "BW" if str(d["setup"]) == "backlit" else "RGB"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.exposure = float(d["exposure"])

    cam = bpy.data.cameras.new("camera")
    cam.lens = LENS_MM
    cam.sensor_fit = "HORIZONTAL"
    cam.sensor_width = float(d["frame_mm"]) * LENS_MM / DISTANCE_MM
    cam.dof.use_dof = True
    cam.dof.focus_distance = DISTANCE_MM + float(d["focus_offset_mm"])
    cam.dof.aperture_fstop = float(d["fstop"])
    camera = bpy.data.objects.new("camera", cam)
    camera.location = (0.0, 0.0, DISTANCE_MM)
    camera.rotation_euler = (0.0, 0.0, math.radians(float(d["roll_deg"])))
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.unit_settings.scale_length = 0.001  # scene units are mm

    world = bpy.data.worlds.new("room")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = \
        (*[float(d["room"])] * 3, 1.0)
    scene.world = world
    if str(d["setup"]) == "backlit":
        plane("panel", 400.0, -40.0, (1.0, 1.0, 1.0), emission=float(d["panel"]))
        area_light(scene, "fill", (0.0, -60.0, 250.0), 150.0, float(d["fill"]))
    else:
        az = math.radians(float(d["lamp_azimuth_deg"]))
        el = math.radians(float(d["lamp_elevation_deg"]))
        r = 220.0
        area_light(scene, "lamp", (r * math.cos(el) * math.sin(az), r * math.sin(el),
                                   r * math.cos(el) * math.cos(az)),
                   float(d["lamp_size"]), float(d["lamp_power"]))
        area_light(scene, "fill", (-80.0, -120.0, 180.0), 60.0, 0.15 * float(d["lamp_power"]))
        plane("card", 400.0, -40.0, tuple(float(c) for c in d["card"]))

    mat = bpy.data.materials.new("fibers")
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.remove(nodes["Principled BSDF"])
    hair = nodes.new("ShaderNodeBsdfHairPrincipled")
    hair.parametrization = "COLOR"
    hair.inputs["Color"].default_value = (*[float(c) for c in d["color"]], 1.0)
    hair.inputs["Roughness"].default_value = float(d["roughness"])
    mat.node_tree.links.new(hair.outputs[0], nodes["Material Output"].inputs["Surface"])
    add_yarn(scene, d, mat)
    return scene


def main() -> None:
    for job in json.loads(open(sys.argv[1]).read()):
        scene = build(dict(np.load(job["npz"])))
        scene.render.filepath = job["png"]
        t0 = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        print(json.dumps({"png": job["png"], "seconds": time.perf_counter() - t0}), flush=True)


if __name__ == "__main__":
    main()
