"""ipm's renders beside Blender Cycles, the paper's renderer, on this machine: time and noise
of the same yarns in the same scene at 800x240 (scale 0.4), both on all cores.

Cycles runs in Blender's own Python (``python3 -m venv /opt/bpyenv && /opt/bpyenv/bin/pip
install bpy``; pass its interpreter as ``--blender-python``), scene in
:mod:`ipm.benchmarks.cycles_scene`, twice: as the paper rendered (Principled Hair BSDF,
Cycles' default 12 bounces) and with ipm's material and path depth (principled BSDF, one
indirect bounce), so that the renderer's share of the speed-up shows apart from the
material's.  ipm renders its scene as shipped.

Noise, two ways.  Noise level: ``std(a - b) / sqrt(2)`` of two renders with other sampler
seeds after a high-pass (image minus its 3x3 box blur), sRGB values in [0, 1], no
quantisation.  Detail SNR: the fiber detail both renders share, ``sqrt(cov(hp(a),
hp(b)))``, over that noise; it does not depend on how bright or contrasted each renderer
makes the yarn.  The verdict gives ipm's fewest samples per pixel that match Cycles at 64
samples by either measure, and the time at which ipm's measure equals Cycles', interpolated
between the two sample counts around it (log time against log measure: noise falls and SNR
rises about as a power of the samples): once for the yarns together (median times, mean
measures, as the table) and once yarn by yarn, each yarn's ipm time matched to that yarn's
Cycles measure (a dense yarn is noisier and slower in both renderers, so pooling matches
the pooled noise, which the dense yarns dominate, against a median time).

    python -m ipm.benchmarks.blender_compare --blender-python /opt/bpyenv/bin/python
        [--yarns 6] [--figure /tmp/cycles_vs_ipm.png]
        [--out benchmarks/results/blender_compare.md]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish
from ipm.benchmarks.render_speed import highpass
from ipm.generator import generate
from ipm.photo import linear_to_srgb, write_png
from ipm.prior import GuidedPrior
from ipm.render import scene as S
from ipm.render.renderer import Renderer, world_curves

COMMAND = ("python -m ipm.benchmarks.blender_compare --blender-python /opt/bpyenv/bin/python "
           "--out benchmarks/results/blender_compare.md")
SCALE = 0.4
CYCLES_SAMPLES = 64
#: Sample counts the multijitter sampler takes as they are (products of two near-equal
#: integers), finer where ipm's noise crosses Cycles'.
IPM_SPP = (4, 8, 12, 16, 20, 25, 30, 36, 64)
SEEDS = (1, 2)
IPM = "ipm (Mitsuba llvm_ad_rgb)"
#: Columns of a :class:`Rows` entry after the times.
SNR, NOISE = 1, 2
#: Cycles configurations: (fiber material, bounces; None = Cycles' default of 12).
CYCLES = {"Cycles, the paper's Principled Hair BSDF, default bounces": ("hair", None),
          "Cycles, ipm's principled BSDF, 1 bounce (ipm's path depth 3)": ("principled", 1)}


def detail_snr(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """(detail SNR, noise) of two renders of the same yarn with other sampler seeds."""
    ha, hb = highpass(a), highpass(b)
    detail = np.sqrt(max(float(np.mean((ha - ha.mean()) * (hb - hb.mean()))), 0.0))
    noise = float(np.std(ha - hb) / np.sqrt(2))
    return detail / noise, noise


def scene_npz(path: Path, params, seed: int) -> int:
    """Write the yarn and THE scene's numbers for :mod:`ipm.benchmarks.cycles_scene`;
    returns the yarn's fiber count."""
    fibers = generate(params, seed)
    points, _ = world_curves(fibers, S.yarn_to_world())
    opts = S.DEFAULT_OPTIONS
    width, height = S.frame_size(SCALE)
    np.savez(path, points=points[:, :3], offsets=fibers.offsets, radius=fibers.round_radii(),
             color=np.array(params.color), frame=np.array([width, height]),
             frame_mm=width * S.pixel_size_mm(SCALE), camera_distance=S.CAMERA_DISTANCE_MM,
             soft_boxes=np.array([[*centre, side, radiance]
                                  for _, centre, side, radiance in S.soft_boxes(opts)]),
             room_light=opts.room_light, backdrop=opts.backdrop, roughness=opts.roughness,
             sheen=opts.sheen, backdrop_depth=S.BACKDROP_DEPTH_MM)
    return len(fibers.offsets) - 1


def cycles(blender_python: str, npz: Path, config: tuple[str, int | None], tmp: Path,
           threads: int) -> tuple[list[float], list[np.ndarray]]:
    material, bounces = config
    prefix = tmp / f"{npz.stem}-{material}"
    extra = ["--bounces", str(bounces)] if bounces is not None else []
    script = Path(__file__).with_name("cycles_scene.py")
    r = subprocess.run([blender_python, str(script), str(npz), str(prefix),
                        "--samples", str(CYCLES_SAMPLES), "--seeds", *map(str, SEEDS),
                        "--threads", str(threads), "--material", material, *extra],
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"Blender failed (exit {r.returncode}): {r.stderr.strip()[-500:]}")
    rows = [json.loads(line) for line in r.stdout.splitlines() if line.startswith("{")]
    return ([row["seconds"] for row in rows],
            [np.load(f"{prefix}_s{s}.npy") for s in SEEDS])


def interpolated_time(times: list[float], values: list[float], target: float,
                      rising: bool) -> float | None:
    """The time at which a measure over ipm's sample-count grid reaches ``target``, log-log
    interpolated between the two grid points around it; None outside the grid."""
    points = list(zip(times, values, strict=True))
    for (t0, v0), (t1, v1) in zip(points, points[1:], strict=False):
        if (v0 < target <= v1) if rising else (v0 > target >= v1):
            f = (np.log(target) - np.log(v0)) / (np.log(v1) - np.log(v0))
            return float(np.exp(np.log(t0) + f * (np.log(t1) - np.log(t0))))
    return None


class Rows(dict):
    """name -> one (times, detail SNR, noise) per yarn, in the order of the yarns."""

    def add(self, name: str, seconds: list[float], images: list[np.ndarray]) -> None:
        self.setdefault(name, []).append((seconds, *detail_snr(*images)))

    def seconds(self, name: str, yarn: int | None = None) -> float:
        """Median render time of ``name``: of one yarn, or over all yarns' renders."""
        runs = self[name] if yarn is None else [self[name][yarn]]
        return float(np.median([t for seconds, _, _ in runs for t in seconds]))

    def measure(self, name: str, column: int, yarn: int | None = None) -> float:
        """Detail SNR or noise (``column`` :data:`SNR`, :data:`NOISE`) of ``name``: of one
        yarn, or the yarns' mean."""
        runs = self[name] if yarn is None else [self[name][yarn]]
        return float(np.mean([run[column] for run in runs]))


def verdict(rows: Rows, label: str, column: int, yarn: int | None = None
            ) -> tuple[int | None, float, float | None]:
    """ipm's fewest samples per pixel of the grid that match the Cycles row ``label`` by
    the measure ``column`` (:data:`SNR` or :data:`NOISE`), ipm's time there, and ipm's time
    interpolated to exactly Cycles' measure; of one ``yarn`` or of the yarns together
    (median times, mean measures)."""
    rising = column == SNR
    target = rows.measure(label, column, yarn)
    ipm = [rows.measure(f"{IPM} {spp}", column, yarn) for spp in IPM_SPP]
    times = [rows.seconds(f"{IPM} {spp}", yarn) for spp in IPM_SPP]
    reached = [v >= target if rising else v <= target for v in ipm]
    if not any(reached):
        return None, float("nan"), None
    i = reached.index(True)
    return IPM_SPP[i], times[i], interpolated_time(times, ipm, target, rising)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blender-python", required=True,
                    help="a Python with bpy installed (Blender as a module)")
    ap.add_argument("--yarns", type=int, default=6, help="first draws of the guided prior")
    ap.add_argument("--figure", default=None, help="PNG of the first yarn's renders")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    threads = os.cpu_count() or 1
    yarns = GuidedPrior().sample_many(args.yarns, seed=0)
    renderer = Renderer()
    renderer.render(yarns[0], 0, SCALE, 1)  # kernels compile once per process and scale
    rows, shown, fibers = Rows(), [], []
    with tempfile.TemporaryDirectory(prefix="ipm-blender-") as tmp:
        for k, p in enumerate(yarns):
            npz = Path(tmp) / f"yarn{k}.npz"
            fibers.append(scene_npz(npz, p, k))
            for label, config in CYCLES.items():
                seconds, images = cycles(args.blender_python, npz, config, Path(tmp), threads)
                rows.add(label, seconds, images)
                shown += [(f"{label}, {CYCLES_SAMPLES} spp", images[0])] if k == 0 else []
            for spp in IPM_SPP:
                images, seconds = [], []
                for s in SEEDS:
                    t0 = time.perf_counter()
                    img = renderer.render(p, k, SCALE, spp, render_seed=s)
                    seconds.append(time.perf_counter() - t0)
                    images.append(linear_to_srgb(img))
                rows.add(f"{IPM} {spp}", seconds, images)
                shown += [(f"{IPM}, {spp} spp", images[0])] if k == 0 and spp in (8, 64) else []
    if args.figure:
        write_png(args.figure, np.round(np.clip(np.concatenate([im for _, im in shown]), 0, 1)
                                        * 255).astype(np.uint8))
    publish(report(rows, fibers, threads), args.out)


def yarn_by_yarn(rows: Rows, label: str, what: str, column: int, fibers: list[int]) -> str:
    """A verdict line: ipm's speed-up over the Cycles row ``label`` at equal ``what``, yarn
    by yarn (each yarn's ipm time interpolated to its own Cycles measure), and the median.  A
    yarn whose measure ipm beats already at the grid's fewest samples counts as at least the
    speed-up there."""
    ups = []  # per yarn: None (not reached on the grid) or (speed-up, is a lower bound)
    for k in range(len(fibers)):
        spp, t, t_i = verdict(rows, label, column, k)
        t_c = rows.seconds(label, k)
        ups.append(None if spp is None else (t_c / t_i, False) if t_i else (t_c / t, True))
    reached = [u for u in ups if u]
    if not reached:
        return f"- {label}, equal {what}: no yarn's {what} is reached on ipm's grid."
    values = [v for v, _ in reached]
    bound = "at least " if any(b for _, b in reached) else ""
    each = ", ".join(f"{k} ({n} fibers): " + ("not reached" if u is None else
                                              f"{'≥' if u[1] else ''}{u[0]:.1f}x")
                     for k, (n, u) in enumerate(zip(fibers, ups, strict=True)))
    return (f"- {label}, equal {what}: median {bound}**{np.median(values):.1f}x** over "
            f"{len(reached)} of {len(fibers)} yarns ({min(values):.1f}-{max(values):.1f}x); "
            f"per yarn {each}.")


def report(rows: Rows, fibers: list[int], threads: int) -> str:
    table = ["| renderer | samples per pixel | median time (s) | detail SNR | noise (sRGB) |",
             "|---|---|---|---|---|"]
    for name in rows:
        label, spp = (name, CYCLES_SAMPLES) if name in CYCLES else name.rsplit(" ", 1)
        table.append(f"| {label} | {spp} | {rows.seconds(name):.2f} | "
                     f"{rows.measure(name, SNR):.2f} | {rows.measure(name, NOISE):.4f} |")
    together, per_yarn = [], []
    for label in CYCLES:
        t_c = rows.seconds(label)
        for what, column in (("detail SNR", SNR), ("noise level", NOISE)):
            spp, t, t_i = verdict(rows, label, column)
            per_yarn.append(yarn_by_yarn(rows, label, what, column, fibers))
            if spp is None:
                together.append(f"- {label} ({t_c:.1f} s): no sample count of ipm's grid "
                                f"reaches its {what}.")
                continue
            together.append(f"- {label} ({t_c:.1f} s), equal {what}: ipm at {spp} spp, "
                            f"{t:.2f} s, **{t_c / t:.0f}x** faster" + (
                                f"; interpolated to exactly its {what}: {t_i:.2f} s, "
                                f"{t_c / t_i:.1f}x." if t_i else "."))
    return (markdown_header("ipm beside Blender Cycles", COMMAND, "mitsuba", "drjit") + "\n"
            + f"{len(fibers)} yarns (the guided prior's first draws, seed 0; {min(fibers)}-"
            f"{max(fibers)} fibers), 800x240 px (0.025 mm per pixel), {threads} threads each; "
            "times per render (medians) include the scene update and BVH build; SNR and noise "
            "averaged over the yarns.\n\n" + "\n".join(table)
            + f"\n\nipm at the fewest samples per pixel that match Cycles at {CYCLES_SAMPLES}, "
            "the yarns together (median time, mean measure):\n\n" + "\n".join(together)
            + "\n\nThe same, yarn by yarn (each yarn's ipm time interpolated to that yarn's "
            "Cycles measure, against that yarn's Cycles time):\n\n" + "\n".join(per_yarn)
            + "\n")


if __name__ == "__main__":
    main()
