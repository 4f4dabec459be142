"""How far flyaways stand out of the yarn, for every preset: each flyaway's largest distance
from the yarn axis minus the core's 95th-percentile radius (:func:`ipm.measure.flyaway_reach`),
median and 95th percentile over 3 fiber seeds, hairs and loops apart, and the loop arch
heights ``0.1 d`` the parameters ask for.  The paper authors' own generator gives medians of
0.19-0.38 mm on golden, rose and red (issue 19); this report is ours beside it.

    python -m ipm.benchmarks.flyaway_reach --out benchmarks/results/flyaway_reach.md
"""

from __future__ import annotations

import argparse

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish
from ipm.fibers import FiberKind
from ipm.generator import LOOP_D_UNIT_MM, generate
from ipm.measure import core_radius, flyaway_reach
from ipm.presets import PRESET_NAMES, preset

COMMAND = "python -m ipm.benchmarks.flyaway_reach --out benchmarks/results/flyaway_reach.md"
SEEDS = (0, 1, 2)


def preset_row(name: str) -> str:
    p = preset(name)
    fibers = [generate(p, seed) for seed in SEEDS]
    every = np.concatenate([flyaway_reach(fs) for fs in fibers])
    hairs = np.concatenate([flyaway_reach(fs, FiberKind.HAIR) for fs in fibers])
    loops = np.concatenate([flyaway_reach(fs, FiberKind.LOOP) for fs in fibers])
    radius = np.median([core_radius(fs) for fs in fibers])
    return (f"| {name} | {radius:.2f} | {np.median(every):.2f} | {np.percentile(every, 95):.2f} | "
            f"{np.median(hairs):.2f} | {np.median(loops):.2f} | {loops.max():.2f} | "
            f"{LOOP_D_UNIT_MM * p.d_mean:.2f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    rows = ["| preset | core radius (mm) | reach median | reach p95 | hairs median | "
            "loops median | loops max | loop arch 0.1 d_mean |",
            "|---|---|---|---|---|---|---|---|"]
    rows += [preset_row(name) for name in PRESET_NAMES]
    text = (markdown_header("Flyaway reach (mm) of the 12 presets", COMMAND) + "\n"
            + "\n".join(rows) + "\n")
    publish(text, args.out)


if __name__ == "__main__":
    main()
