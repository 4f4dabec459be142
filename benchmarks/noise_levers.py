"""What changes to THE scene's sampling would buy at equal noise: the levers left towards the
"20x faster than Cycles at similar noise" target of :mod:`ipm.benchmarks.blender_compare`,
and the measurement behind the scene's light sampling weights.

Same yarns, resolution (800x240) and noise measure as ``blender_compare`` (high-pass noise of
two renders with other sampler seeds, sRGB).  Each lever renders at two sample counts; the
time ipm would need for the noise of Cycles in the paper's setup follows from noise^2 x time
being constant (noise falls as 1 / sqrt(samples)), and the speed-up is Cycles' measured
time over it.  Levers, none of which changes the expected image:

* the integrator: Mitsuba's ``path`` (the scene's before ``ipm_path``) or the scene's
  ``ipm_path`` (:mod:`ipm.render.integrator`, each lamp chosen by its reach at every vertex);
* how ``path``'s next-event estimation picks the lights: with equal probability (Mitsuba's
  default, the scene's before 2026-12), by each lamp's share of the light, or by the scene's
  :data:`~ipm.render.scene.LIGHT_WEIGHTS` (the room light rarely);
* the ``orthogonal`` and ``ldsampler`` pixel samplers (they round the sample count up to a
  prime square and a power of two: the table gives the counts they used).

    python -m ipm.benchmarks.noise_levers [--out benchmarks/results/noise_levers.md]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from ipm.benchmarks.blender_compare import SCALE, SEEDS, detail_snr
from ipm.benchmarks.machine import markdown_header, publish
from ipm.generator import generate
from ipm.photo import linear_to_srgb
from ipm.prior import GuidedPrior
from ipm.render import scene as S
from ipm.render.scene import SceneOptions
from ipm.render.variant import mitsuba

COMMAND = "python -m ipm.benchmarks.noise_levers --out benchmarks/results/noise_levers.md"
#: Cycles, the paper's Principled Hair BSDF, 64 samples, on this benchmark's two yarns (the
#: first two of blender_compare's; its run of commit db0b077, before it took six)
CYCLES_SECONDS, CYCLES_NOISE = 33.91, 0.0141
#: Each lamp's sampling weight by its share of the light: its radiance share times its solid
#: angle seen from the yarn (the soft boxes' sides and distances are equal), the room light
#: by its pi sr of cosine-weighted sky against a soft box's ~0.26 sr.
POWER_WEIGHTS = {"key_left": 1.0, "key_right": 0.6, "room": 0.4}
PATH = SceneOptions(integrator="path")
#: label: (scene options, light weights replacing the scene's)
LEVERS = {"path, equal light choice (the scene before 2026-12)":
          (SceneOptions(integrator="path", light_sampling="uniform"), None),
          "path, light weights by power": (PATH, POWER_WEIGHTS),
          "path, the scene's light weights (the scene before ipm_path)": (PATH, None),
          "path, orthogonal sampler": (SceneOptions(integrator="path", sampler="orthogonal"),
                                       None),
          "path, ldsampler": (SceneOptions(integrator="path", sampler="ldsampler"), None),
          "as shipped: ipm_path, lamps chosen by reach (multijitter)": (S.DEFAULT_OPTIONS, None),
          "ipm_path, orthogonal sampler": (SceneOptions(sampler="orthogonal"), None)}
SPP = (16, 36)
#: The light weights tried for the scene's, with ``path``, at SWEEP_SPP.
WEIGHT_SWEEP = [{"key_left": 1.0, "key_right": right, "room": room}
                for right, room in ((0.6, 0.4), (0.6, 0.2), (0.6, 0.1), (0.6, 0.05), (0.6, 0.02),
                                    (0.4, 0.05), (0.8, 0.05), (1.0, 0.05))]
SWEEP_SPP = 25


def lever_scene(mi, fibers, color, opts: SceneOptions, weights: dict[str, float] | None,
                tmp: Path):
    curves = tmp / "curves.txt"
    curves.write_text(fibers.mitsuba_curve_text())
    d = S.scene_dict(SCALE, 1, str(curves), color, opts)
    for name, w in (weights or {}).items():
        (d[name]["emitter"] if "emitter" in d[name] else d[name])["sampling_weight"] = w
    return mi.load_dict(d, parallel=False, optimize=False)


def measure(mi, yarns, opts: SceneOptions, weights: dict[str, float] | None,
            counts: tuple[int, ...], tmp: Path) -> dict[int, tuple[float, float, int]]:
    """Per sample count: (median render seconds, mean noise over the yarns, the count the
    sampler used)."""
    seconds = {spp: [] for spp in counts}
    noises = {spp: [] for spp in counts}
    used = dict.fromkeys(counts)
    for k, p in enumerate(yarns):
        scene = lever_scene(mi, generate(p, k), p.color, opts, weights, tmp)
        mi.render(scene, spp=1)  # kernels compile
        for spp in counts:
            images = []
            for s in SEEDS:
                t0 = time.perf_counter()
                img = mi.render(scene, spp=spp, seed=s)
                images.append(linear_to_srgb(np.array(img, dtype=np.float32)[..., :3]))
                seconds[spp].append(time.perf_counter() - t0)
            used[spp] = scene.sensors()[0].sampler().sample_count()
            noises[spp].append(detail_snr(*images)[1])
    return {spp: (float(np.median(seconds[spp])), float(np.mean(noises[spp])), used[spp])
            for spp in counts}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--yarns", type=int, default=2)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    mi = mitsuba(None)
    yarns = GuidedPrior().sample_many(args.yarns, seed=0)
    levers = ["| lever | samples asked (used) | median time (s) | noise (sRGB) | time at "
              "Cycles' noise (s) | speed-up over Cycles |", "|---|---|---|---|---|---|"]
    weights = ["| key_left | key_right | room | noise (sRGB) |", "|---|---|---|---|"]
    with tempfile.TemporaryDirectory(prefix="ipm-levers-") as tmp:
        for label, (opts, w) in LEVERS.items():
            for spp, (t, noise, used) in measure(mi, yarns, opts, w, SPP, Path(tmp)).items():
                at_cycles = t * (noise / CYCLES_NOISE) ** 2
                levers.append(f"| {label} | {spp} ({used}) | {t:.2f} | {noise:.4f} | "
                              f"{at_cycles:.2f} | {CYCLES_SECONDS / at_cycles:.1f}x |")
                print(levers[-1], flush=True)
        for w in WEIGHT_SWEEP:
            (_, noise, _), = measure(mi, yarns, PATH, w, (SWEEP_SPP,),
                                     Path(tmp)).values()
            weights.append(f"| {w['key_left']} | {w['key_right']} | {w['room']} | "
                           f"{noise:.4f} |")
            print(weights[-1], flush=True)
    text = (markdown_header("Sampling levers at equal noise", COMMAND, "numpy", "mitsuba")
            + f"\n{args.yarns} yarns (the guided prior's first draws, seed 0), 800x240 px, "
            "all cores; the render call only (no scene update), median over yarns and "
            f"seeds; Cycles: {CYCLES_SECONDS} s at noise {CYCLES_NOISE} "
            "(blender_compare on these two yarns, commit db0b077).\n\n" + "\n".join(levers)
            + f"\n\n## path's light sampling weights at {SWEEP_SPP} spp (multijitter)\n\n"
            "The noise of the same renders with other weights for the lights; the scene's "
            f"are {S.LIGHT_WEIGHTS}.\n\n" + "\n".join(weights) + "\n")
    publish(text, args.out)


if __name__ == "__main__":
    main()
