"""How long ``ipm`` takes to start: ``ipm --help`` and ``ipm predict`` on one photo as a
fresh process (median of ``--repeats``), beside the nets' own time in a warm process (load
the ensemble, predict one photo); and ``--count`` photos predicted in one call against one
call per photo.  ``--ipm`` times another install (e.g. a venv of an older commit); the
one-call row is left out when that ``ipm predict`` takes one photo only.

    python -m ipm.benchmarks.startup --photos DIR --pixel-size 0.04
        [--ipm PATH] [--out benchmarks/results/startup.md]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ipm.benchmarks.machine import markdown_header, publish

DEFAULT_IPM = str(Path(sys.executable).parent / "ipm")


def wall(args: list[str]) -> tuple[float, int]:
    """Seconds and exit status of one fresh process."""
    t0 = time.perf_counter()
    r = subprocess.run(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0, r.returncode


def median_wall(args: list[str], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t, rc = wall(args)
        if rc:
            raise SystemExit(f"{' '.join(args)} failed (exit {rc})")
        times.append(t)
    return statistics.median(times)


def nets_seconds(photo: Path, pixel_size: float, repeats: int) -> float:
    """Median of load + predict of the shipped ensemble in this (warm) process."""
    from ipm.nets.ensemble import Ensemble
    from ipm.photo import Photo

    Ensemble.load().predict(Photo.read(photo, pixel_size))  # warm-up: imports, kernels
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        Ensemble.load().predict(Photo.read(photo, pixel_size))
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--photos", type=Path, required=True, help="folder of photos (e.g. a "
                    "dataset's images/)")
    ap.add_argument("--pixel-size", type=float, default=0.04)
    ap.add_argument("--count", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--ipm", default=DEFAULT_IPM, help="the ipm executable (default: the one "
                    "installed beside this Python)")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    photos = sorted(p for p in args.photos.iterdir() if p.suffix == ".png")[:args.count]
    px = ["--pixel-size", f"{args.pixel_size:g}"]
    load = " / ".join(f"{v:.1f}" for v in os.getloadavg())
    helps = median_wall([args.ipm, "--help"], args.repeats)
    one = median_wall([args.ipm, "predict", str(photos[0]), *px], args.repeats)
    nets = nets_seconds(photos[0], args.pixel_size, args.repeats)
    t0 = time.perf_counter()
    for p in photos:
        wall([args.ipm, "predict", str(p), *px])
    separate = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        together, rc = wall([args.ipm, "predict", *map(str, photos), *px, "--out", tmp])
    rows = ["| what | seconds |", "|---|---|",
            f"| `ipm --help`, fresh process (median of {args.repeats}) | {helps:.2f} |",
            f"| `ipm predict` one photo, fresh process (median of {args.repeats}) | {one:.2f} |",
            f"| the nets' own time in a warm process: load + predict (median) | {nets:.2f} |",
            f"| `ipm predict` beyond the nets' own time | {one - nets:.2f} |",
            f"| {len(photos)} photos, one `ipm predict` each | {separate:.1f} |"]
    if rc == 0:
        rows.append(f"| {len(photos)} photos, one `ipm predict` call | {together:.1f} |")
    command = " ".join(["python -m ipm.benchmarks.startup --photos", str(args.photos),
                        *px, "--count", str(args.count), "--repeats", str(args.repeats)]
                       + (["--ipm", args.ipm] if args.ipm != DEFAULT_IPM else [])
                       + (["--out", args.out] if args.out else []))
    text = (markdown_header("ipm start-up time", command, "torch") + "\n"
            + "\n".join(rows) + "\n\n"
            + f"`{args.ipm}`; photos of `{args.photos}` at {args.pixel_size:g} mm per pixel; "
            f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}; load average "
            f"before: {load}.\n")
    publish(text, args.out)


if __name__ == "__main__":
    sys.exit(main())
