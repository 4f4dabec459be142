"""10,000 draws of the guided prior: min/max per parameter beside the paper's intervals.

    python -m ipm.benchmarks.prior_intervals [--out docs/prior_intervals.md]
"""

from __future__ import annotations

import argparse

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish
from ipm.params import PAPER_INTERVALS
from ipm.prior import GuidedPrior

COMMAND = "python -m ipm.benchmarks.prior_intervals --out docs/prior_intervals.md"


def report(count: int = 10_000, seed: int = 0) -> str:
    draws = GuidedPrior().sample_many(count, seed)
    rows = ["| parameter | interval (paper, see ipm/params.py) | min drawn | max drawn | inside |",
            "|---|---|---|---|---|"]
    for k, iv in PAPER_INTERVALS.items():
        v = np.array([getattr(p, k) for p in draws], dtype=float)
        ok = "yes" if iv.lo <= v.min() and v.max() <= iv.hi else "NO"
        rows.append(f"| `{k}` | [{iv.lo:g}, {iv.hi:g}] {iv.unit} | {v.min():.4g} | "
                    f"{v.max():.4g} | {ok} |")
    return (markdown_header(f"Guided prior: {count} draws (seed {seed})", COMMAND)
            + "\n" + "\n".join(rows) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default=None)
    ap.add_argument("--count", type=int, default=10_000)
    args = ap.parse_args()
    text = report(args.count)
    publish(text, args.out)


if __name__ == "__main__":
    main()
