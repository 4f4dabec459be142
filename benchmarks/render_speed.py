"""Render speed, noise and fiber detail of THE scene (llvm_ad_rgb, CPU), and ``ipm generate``
throughput on all cores.  The comparison with the paper's renderer, Blender Cycles, on the
same yarns and scene is :mod:`ipm.benchmarks.blender_compare`.

Yarns: the first 4 draws of the guided prior (seed 0), so that flyaway-heavy and thin
yarns are both in.  Times are medians over repeats after one warm-up render per scale
(kernels compile once per process and scale; that cost is reported separately).

Noise and detail, in 8-bit sRGB levels (what the nets see): noise = std of the difference of
two renders with other sampler seeds / sqrt(2); detail = std of the high-pass (image minus a
3x3 box blur) of a 256 spp reference at the same scale, i.e. the contrast of fiber-sized
structure; SNR = detail / high-pass noise.

    python -m ipm.benchmarks.render_speed [--out benchmarks/results/render_speed.md]
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from dataclasses import replace

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish
from ipm.prior import GuidedPrior
from ipm.render.dataset import DEFAULT_SCALE, DEFAULT_SPP, GenerateOptions, generate_dataset
from ipm.render.renderer import Renderer, to_srgb8
from ipm.render.scene import DEFAULT_OPTIONS

COMMAND = "python -m ipm.benchmarks.render_speed --out benchmarks/results/render_speed.md"
YARNS = GuidedPrior().sample_many(4, seed=0)
GRID = [(0.25, 4), (0.25, 6), (0.25, 8), (0.25, 16), (0.4, 4), (0.4, 8), (0.4, 16), (0.5, 4),
        (0.5, 8), (0.5, 16), (1.0, 4), (1.0, 8)]
SAMPLER_GRID = [(0.25, 6), (0.25, 8), (0.4, 16), (0.4, 64)]


def median_time(renderer: Renderer, scale: float, spp: int, repeats: int) -> float:
    renderer.render(YARNS[0], 0, scale, spp)  # warm-up: kernels for this scale
    times = []
    for i in range(repeats):
        p = YARNS[i % len(YARNS)]
        t0 = time.perf_counter()
        renderer.render(p, i, scale, spp, render_seed=i)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def highpass(img: np.ndarray) -> np.ndarray:
    x = img.astype(np.float64)
    pad = np.pad(x, ((1, 1), (1, 1), (0, 0)), mode="edge")
    blur = sum(pad[i:i + x.shape[0], j:j + x.shape[1]] for i in range(3) for j in range(3)) / 9
    return x - blur


def noise_and_detail(renderer: Renderer, scale: float, spp: int) -> tuple[float, float, float]:
    noise, hp_noise, detail = [], [], []
    for k, p in enumerate(YARNS[:2]):
        ref = to_srgb8(renderer.render(p, k, scale, 256, render_seed=999))
        a = to_srgb8(renderer.render(p, k, scale, spp, render_seed=1)).astype(np.float64)
        b = to_srgb8(renderer.render(p, k, scale, spp, render_seed=2)).astype(np.float64)
        noise.append(np.std(a - b) / np.sqrt(2))
        hp_noise.append(np.std(highpass(a) - highpass(b)) / np.sqrt(2))
        detail.append(np.std(highpass(ref)))
    return float(np.mean(noise)), float(np.mean(detail)), float(np.mean(detail) /
                                                                  np.mean(hp_noise))


def compile_time(scale: float) -> float:
    r = Renderer()
    t0 = time.perf_counter()
    r.render(YARNS[0], 0, scale, 1)
    return time.perf_counter() - t0


def generate_throughput(count: int, workers: int) -> tuple[float, float]:
    """(images per hour, seconds) of ``ipm generate`` at the default scale and spp."""
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        generate_dataset(f"{tmp}/ds", GenerateOptions(count=count, seed=0), workers=workers)
        dt = time.perf_counter() - t0
    return 3600 * count / dt, dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default=None)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--generate-count", type=int, default=40)
    args = ap.parse_args()
    cores = os.cpu_count() or 1
    out = [markdown_header("Render speed", COMMAND, "mitsuba", "drjit"), ""]
    out.append(f"Kernel compilation, first render at a new scale (0.5): "
               f"{compile_time(0.5):.2f} s (once per process and scale).\n")

    r = Renderer()
    out += ["## Time, noise and detail per image (one process, all cores)", "",
            "| scale | size (px) | spp | median time (s) | noise (8-bit levels) | "
            "fiber detail | detail SNR |", "|---|---|---|---|---|---|---|"]
    for scale, spp in GRID:
        t = median_time(r, scale, spp, args.repeats if scale < 1 else 3)
        noise, detail, snr = noise_and_detail(r, scale, spp) if scale < 1 else (np.nan,) * 3
        w, h = round(2000 * scale), round(600 * scale)
        mark = " **(default)**" if (scale, spp) == (DEFAULT_SCALE, DEFAULT_SPP) else ""
        out.append(f"| {scale}{mark} | {w}x{h} | {spp} | {t:.2f} | {noise:.1f} | {detail:.1f} | "
                   f"{snr:.1f} |")

    out += ["", "## The scene's stratified samples (multijitter) beside independent ones", "",
            "| sampler | scale | spp | median time (s) | noise (8-bit levels) | detail SNR |",
            "|---|---|---|---|---|---|"]
    for sampler in ("multijitter", "independent"):
        rs = r if sampler == DEFAULT_OPTIONS.sampler else \
            Renderer(options=replace(DEFAULT_OPTIONS, sampler=sampler))
        for scale, spp in SAMPLER_GRID:
            t = median_time(rs, scale, spp, args.repeats)
            noise, _, snr = noise_and_detail(rs, scale, spp)
            out.append(f"| {sampler} | {scale} | {spp} | {t:.2f} | {noise:.1f} | {snr:.1f} |")

    out += ["", f"## `ipm generate` at the default scale {DEFAULT_SCALE} and {DEFAULT_SPP} spp "
            f"({args.generate_count} images)", "",
            "| workers x threads | images / hour | 2000 images take |", "|---|---|---|"]
    for workers in sorted({1, cores}):
        rate, _ = generate_throughput(args.generate_count, workers)
        out.append(f"| {workers} x {max(1, cores // workers)} | {rate:,.0f} | "
                   f"{2000 / rate * 60:.0f} min |")
    self_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    child_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    out += ["", f"Peak memory (max RSS): this process, which rendered every scale up to full "
            f"resolution: {self_mb:,.0f} MB; largest `ipm generate` worker: {child_mb:,.0f} MB."]
    text = "\n".join(out) + "\n"
    publish(text, args.out)


if __name__ == "__main__":
    main()
