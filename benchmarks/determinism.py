"""Do separate processes render the same bytes?  Pairs of processes start at the same moment
(as `ipm generate`'s workers do), each renders the same two yarns with the same seeds, and
the digests of their images are counted.  Run with the renderer as shipped (the scene
loaded with ``mi.load_dict(..., parallel=False, optimize=False)``, its shapes in the dict's
order) and with Mitsuba's default loading, side by side.

    python -m ipm.benchmarks.determinism [--pairs 10] [--out benchmarks/results/determinism.md]
"""

from __future__ import annotations

import argparse
import collections
import hashlib
import subprocess
import sys

from ipm.benchmarks.machine import markdown_header, publish

COMMAND = "python -m ipm.benchmarks.determinism --out benchmarks/results/determinism.md"
MODES = {"shipped": "shapes in the dict's order (as shipped)",
         "default": "Mitsuba's default (parallel, merging similar objects)"}


def render_digests(mode: str) -> str:
    """The digests of two renders in this process (what a child prints)."""
    from ipm.prior import GuidedPrior
    from ipm.render.renderer import Renderer

    r = Renderer()
    if mode == "default":
        load_dict = r.mi.load_dict
        r.mi.load_dict = lambda d, **ours: load_dict(d)
    return " ".join(hashlib.md5(r.render(p, k, 0.25, 8, render_seed=3).tobytes()).hexdigest()[:12]
                    for k, p in enumerate(GuidedPrior().sample_many(2, seed=0)))


def run_pairs(mode: str, pairs: int) -> collections.Counter:
    outcomes: collections.Counter = collections.Counter()
    child = [sys.executable, "-m", "ipm.benchmarks.determinism", "--child", mode]
    for _ in range(pairs):
        procs = [subprocess.Popen(child, stdout=subprocess.PIPE, text=True) for _ in range(2)]
        for p in procs:
            out, _ = p.communicate()
            if p.returncode != 0:
                raise SystemExit(f"a render process failed (exit {p.returncode})")
            outcomes[out.strip()] += 1
    return outcomes


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=10, help="pairs of concurrent processes")
    ap.add_argument("--out", default=None)
    ap.add_argument("--child", choices=list(MODES), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(render_digests(args.child))
        return
    results = {mode: run_pairs(mode, args.pairs) for mode in MODES}
    rows = ["| scene loading | processes | processes with the row's most common images | "
            "distinct outcomes |", "|---|---|---|---|"]
    for mode, counts in results.items():
        rows.append(f"| {MODES[mode]} | {sum(counts.values())} | "
                    f"{counts.most_common(1)[0][1]} | {len(counts)} |")
    text = (markdown_header("Same bytes across processes", COMMAND, "mitsuba", "drjit") + "\n"
            + "Two yarns of the guided prior at scale 0.25, 8 spp, render seed 3; "
            f"{args.pairs} pairs of processes started together per row.\n\n"
            + "\n".join(rows) + "\n")
    publish(text, args.out)


if __name__ == "__main__":
    main()
