"""How often the fits' 80% intervals hold the truth, per parameter, re-derived from the rows
of ``ipm compare`` reports on labelled sets (``fits.jsonl``: the neural and refined values
and the search's profile interval) with today's :meth:`ipm.refine.fit.FitResult.intervals`
rule, so that a change of the rule is measured on fits already made.  Per capture setup,
the reports' photos are also counted together (issue 22's calibration: 30 of ipm's renders
and 30 of another renderer's, the share within 70-90% for every parameter).

    python -m ipm.benchmarks.interval_coverage /tmp/compare:data/test \\
        /tmp/compare-cycles-frontlit:data/cycles-frontlit \\
        --out benchmarks/results/interval_coverage.md
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish
from ipm.dataset import read_manifest
from ipm.params import PAPER_INTERVALS, RAW_CONTINUOUS, YarnParams
from ipm.refine.fit import FitResult
from ipm.refine.search import LEVEL, SearchResult


def coverage(report: Path, data: Path, sigma: dict[str, float]) -> dict[str, dict]:
    """Per parameter: the share of the report's photos whose true value lies in the
    interval, the mean width (share of the parameter's range) and its source.  A fit made
    without the nets' prior (``prior`` false in its row: a yarn outside their range) has
    no nets' interval."""
    truth = {str(r.image): r.params for r in read_manifest(data)}
    held: dict[str, list] = {k: [] for k in RAW_CONTINUOUS}
    for line in (report / "fits.jsonl").read_text().splitlines():
        row = json.loads(line)
        if "error" in row:
            continue
        neural, refined = YarnParams.from_dict(row["neural"]), YarnParams.from_dict(row["refined"])
        profile = {k: tuple(v[:2]) for k, v in row["intervals"].items()
                   if v[2].startswith("search profile")}
        search = SearchResult(neural, refined, 0.0, 0.0, row["improved"], intervals=profile)
        result = FitResult(neural, refined, 0.0, 0.0, row["improved"], search=search,
                           sigma=sigma if row.get("prior", True) else None)
        t = truth[row["image"]]
        for k, (lo, hi, source) in result.intervals().items():
            held[k].append((lo <= getattr(t, k) <= hi, (hi - lo) / PAPER_INTERVALS[k].width,
                            source))
    return {k: {"holds": float(np.mean([h for h, _, _ in v])),
                "width": float(np.mean([w for _, w, _ in v])), "source": v[0][2],
                "photos": len(v)} for k, v in held.items() if v}


def pooled(reports: list[dict[str, dict]]) -> dict[str, tuple[int, float]]:
    """Per parameter, (photos, share holding the truth) of several :func:`coverage` results
    counted together."""
    out = {}
    for k in RAW_CONTINUOUS:
        parts = [r[k] for r in reports if k in r]
        count = sum(c["photos"] for c in parts)
        if count:
            out[k] = (count, sum(c["holds"] * c["photos"] for c in parts) / count)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("pairs", nargs="+", help="REPORT:DATASET, an ipm compare folder and the "
                    "labelled set it fitted")
    ap.add_argument("--models", default=None, help="the nets the reports used (default: the "
                    "shipped ones)")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    from ipm.nets.ensemble import Ensemble

    lines = [f"Share of the photos whose true value lies inside the reported {LEVEL:.0%} "
             "interval (its mean width in % of the parameter's range; where it comes from).",
             ""]
    by_setup: dict[str, list[dict]] = {}
    for pair in args.pairs:
        report, data = (Path(p) for p in pair.split(":"))
        records = read_manifest(data)
        sigma = Ensemble.load(args.models, setup=records[0].setup).sigma(
            records[0].pixel_size_mm)
        lines += [f"## `{report}` (`{data}`)", "", "| parameter | holds | width | from |",
                  "|---|---|---|---|"]
        covered = coverage(report, data, sigma)
        by_setup.setdefault(records[0].setup, []).append(covered)
        for k, c in covered.items():
            lines.append(f"| {k} | {c['holds']:.0%} | {100 * c['width']:.1f}% | "
                         f"{c['source']} |")
        lines.append("")
    for setup, reports in by_setup.items():
        if len(reports) < 2:
            continue
        lines += [f"## {setup}: the {len(reports)} reports' photos together", "",
                  "| parameter | photos | holds |", "|---|---|---|"]
        lines += [f"| {k} | {count} | {held:.0%} |" for k, (count, held) in pooled(reports).items()]
        lines.append("")
    command = "python -m ipm.benchmarks.interval_coverage " + " ".join(sys.argv[1:])
    publish(markdown_header("Calibration of the fits' intervals", command, "numpy") + "\n"
            + "\n".join(lines), args.out)


if __name__ == "__main__":
    main()
