"""How long ``ipm measure`` takes per photo: one photo as a fresh process (median over the
photos of one run each, ``--repeats`` times), and a whole folder in one call (its wall time
over the number of photos), both writing their files (``-o``) as a user's run does; with the
analysis alone in a warm process (median per photo) beside them.

    python -m ipm.benchmarks.measure_speed --photos ../shared/real-yarns --pixel-size 0.0021 \\
        --out benchmarks/results/measure_speed.md
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from ipm.benchmarks.machine import markdown_header, publish
from ipm.benchmarks.startup import DEFAULT_IPM, wall
from ipm.dataset import photo_files


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--photos", type=Path, required=True)
    ap.add_argument("--pixel-size", type=float, required=True)
    ap.add_argument("--repeats", type=int, default=1, help="fresh-process runs per photo")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    files = photo_files(args.photos)
    size = ["--pixel-size", str(args.pixel_size)]
    with tempfile.TemporaryDirectory() as tmp:
        fresh = []
        for i, f in enumerate(files):
            for r in range(args.repeats):
                t, rc = wall([DEFAULT_IPM, "measure", str(f), *size, "-o",
                              f"{tmp}/one{i}_{r}"])
                if rc:
                    raise SystemExit(f"ipm measure {f} failed (exit {rc})")
                fresh.append(t)
        t_folder, rc = wall([DEFAULT_IPM, "measure", str(args.photos), *size, "-o",
                             f"{tmp}/folder"])
        if rc:
            raise SystemExit(f"ipm measure {args.photos} failed (exit {rc})")
    from ipm.textile.image import gray, measure_photo

    warm = []
    measure_photo(gray(str(files[0])), args.pixel_size, True)  # imports
    for f in files:
        img = gray(str(f))
        t0 = time.perf_counter()
        measure_photo(img, args.pixel_size, True)
        warm.append(time.perf_counter() - t0)
    command = (f"python -m ipm.benchmarks.measure_speed --photos {args.photos} --pixel-size "
               f"{args.pixel_size:g}" + (f" --repeats {args.repeats}" if args.repeats > 1
                                         else "") + (f" --out {args.out}" if args.out else ""))
    lines = [markdown_header("ipm measure: time per photo", command, "numpy", "scipy"),
             f"{len(files)} photos of {files[0].name}'s size; the fresh-process and folder runs "
             "write each photo's JSON and drawing (`-o`), the folder run its CSV and plots too.",
             "", "| how | seconds per photo (median) |", "|---|---|",
             f"| one photo, a fresh process | {statistics.median(fresh):.2f} |",
             f"| a folder in one call | {t_folder / len(files):.2f} |",
             f"| the analysis alone, warm | {statistics.median(warm):.2f} |"]
    publish("\n".join(lines) + "\n", args.out)


if __name__ == "__main__":
    main()
