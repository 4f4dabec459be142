"""Time and peak memory of ``ipm knit`` for an 8 x 6 patch at 1000 x 1000 px, 16 spp, as a
fresh process on the machine's cores: median of ``--repeats`` runs (fiber generation,
sweep, scene load and render; Python start-up included).

    python -m ipm.benchmarks.knit_speed --out benchmarks/results/knit_speed.md
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ipm.benchmarks.machine import markdown_header, publish
from ipm.benchmarks.startup import DEFAULT_IPM
from ipm.knit import knit_patch
from ipm.params import YarnParams

COMMAND = "python -m ipm.benchmarks.knit_speed --out benchmarks/results/knit_speed.md"
PRESETS = ("golden", "rose", "pink_6ply")
MEASURED = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], "
            "stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL); "
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); sys.exit(r.returncode)")


def run(args: list[str]) -> tuple[float, float]:
    """(seconds, peak resident MB) of one fresh ``ipm`` process."""
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-c", MEASURED, DEFAULT_IPM, *args], capture_output=True,
                       text=True, check=True)
    return time.perf_counter() - t0, int(r.stdout.split()[-1]) / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    rows = ["| yarn | fibers in the patch | median time (s) | peak memory (MB) |",
            "|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as tmp:
        for name in PRESETS:
            params = Path(tmp, f"{name}.json")
            subprocess.run([DEFAULT_IPM, "sample", "--preset", name, "-o", str(params)],
                           check=True, capture_output=True)
            out = str(Path(tmp, f"{name}-patch.png"))  # its sidecar must not be the params
            runs = [run(["knit", str(params), "-o", out, "--stitches", "8x6", "--size",
                         "1000x1000", "--spp", "16"]) for _ in range(args.repeats)]
            sidecar = json.loads(Path(out).with_suffix(".json").read_text())
            count = knit_patch(YarnParams.from_dict(sidecar["params"]), "knit", 8, 6,
                               sidecar["seed"]).fibers.num_fibers
            rows.append(f"| {name} | {count} | {statistics.median(t for t, _ in runs):.1f} | "
                        f"{max(m for _, m in runs):.0f} |")
    text = (markdown_header("ipm knit: an 8 x 6 patch at 1000 x 1000 px, 16 spp", COMMAND)
            + f"\nMedian of {args.repeats} fresh processes; target under 60 s.\n\n"
            + "\n".join(rows) + "\n")
    publish(text, args.out)


if __name__ == "__main__":
    main()
