"""Fiber generation time of the largest yarn of the value intervals (n=6, m=200, g=300),
median of 5, on one core, beside the paper's Blender generator (6-12 s per yarn; the
paper's own generator run on a machine like ours: median 11.8 s).

    python -m ipm.benchmarks.generator_speed [--out benchmarks/results/generator_speed.md]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish
from ipm.generator import generate, levels_of, vertex_spacing
from ipm.presets import preset

COMMAND = "python -m ipm.benchmarks.generator_speed --out benchmarks/results/generator_speed.md"
PAPER_MEDIAN_S = 11.8

#: The largest yarn: every count at its maximum; the twist pitches are those of the
#: sampler's median yarn (-4.7 mm, 6.8 mm); a tighter fiber pitch adds vertices.
LARGEST = preset("pink_6ply").replace(n=6, m=200, g=300, alpha=-4.7, alpha_ply=6.8)
TIGHTEST = LARGEST.replace(alpha=-0.476)


def time_generate(params, repeats: int = 5) -> tuple[float, int]:
    times = []
    for seed in range(repeats):
        t0 = time.perf_counter()
        fs = generate(params, seed)
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), len(fs.points)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    rows = ["| yarn | vertex spacing (mm) | vertices | median of 5 (s) | vs paper (11.8 s) |",
            "|---|---|---|---|---|"]
    for name, p in (("n=6, m=200, g=300, alpha=-4.7", LARGEST),
                    ("same, tightest alpha=-0.476", TIGHTEST)):
        t, v = time_generate(p)
        rows.append(f"| {name} | {vertex_spacing(levels_of(p)):.3f} | {v} | {t:.3f} | "
                    f"{PAPER_MEDIAN_S / t:.0f}x faster |")
    text = markdown_header("Fiber generation speed", COMMAND) + "\n" + "\n".join(rows) + "\n"
    publish(text, args.out)


if __name__ == "__main__":
    main()
