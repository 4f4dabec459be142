"""How wide the nets' yarn renders against the photo's core, per set of photos: the gate
(:data:`ipm.refine.plan.COUNT_WIDTH_FACTOR`) beyond which a fit takes the yarn for one
outside the nets' range and searches its thickness first (:func:`ipm.refine.plan.plan`), and
within which a backlit fit chooses its ply count (the choice reads the core's outline at the yarn's
thickness; where the nets' thickness is far from the photo's, it misread the count:
real-photos-count@35cd98b at cc59bd2).  Per photo, :func:`ipm.refine.measure.width_ratio` of the
nets' guess in the photo's setup, before its fiber colour is matched to the photo, as ``ipm
fit`` decides the switch.

    python -m ipm.benchmarks.count_width --data data-backlit/val --data data-backlit/test \\
        --data data/cycles-backlit --photos ../shared/real-yarns --pixel-size 0.0021 \\
        --out benchmarks/results/count_width.md
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish


def ratios(photos: list, setup: str) -> list[float]:
    """:func:`ipm.refine.measure.width_ratio` of the shipped nets' guess for each photo."""
    from ipm.nets.ensemble import Ensemble
    from ipm.refine.fit import search_objective
    from ipm.refine.measure import width_ratio
    from ipm.refine.plan import FitConfig
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options

    ens = Ensemble.load(None, setup=setup)
    renderer = Renderer(options=setup_options(setup))
    out = []
    for photo in photos:
        objective, small = search_objective(photo, renderer, FitConfig())
        out.append(width_ratio(objective, ens.predict(photo), small))
    return out


def main() -> None:
    from ipm.benchmarks.report import load_records
    from ipm.photo import Photo
    from ipm.refine.plan import COUNT_WIDTH_FACTOR, within_gate

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", action="append", default=[], help="a labelled set (repeat)")
    ap.add_argument("--count", type=int, default=30)
    ap.add_argument("--photos", type=Path, default=None, help="a folder of backlit photos")
    ap.add_argument("--pixel-size", type=float, default=None, help="mm per pixel of --photos")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    sets = {d: [r.photo() for r in load_records(Path(d), args.count)] for d in args.data}
    if args.photos is not None:
        sets[str(args.photos)] = [Photo.read(f, args.pixel_size, "backlit")
                                  for f in sorted(args.photos.glob("*.png"))]
    rows = ["| photos | count | min | median | max | outside the gate |",
            "|---|---|---|---|---|---|"]
    data = {}
    for name, photos in sets.items():
        r = np.array(ratios(photos, photos[0].setup))
        outside = sum(not within_gate(x) for x in r)
        data[name] = r.tolist()
        rows.append(f"| `{name}` | {len(r)} | {r.min():.2f} | {np.median(r):.2f} | "
                    f"{r.max():.2f} | {outside} |")
        print(rows[-1], flush=True)
    command = "python -m ipm.benchmarks.count_width " + " ".join(sys.argv[1:])
    text = (markdown_header("The nets' yarn against the photo's core width", command,
                            "mitsuba", "torch")
            + f"\nThe render of the nets' guess (fiber seed 0, before its colour is matched "
            f"to the photo) over the photo's core width (`ipm.refine.measure.width_ratio`); "
            f"outside a factor {COUNT_WIDTH_FACTOR:g} of 1 a backlit fit takes the yarn for "
            f"one outside the nets' range and searches its thickness first, without their "
            f"prior.\n\n" + "\n".join(rows) + "\n")
    publish(text, args.out, data)


if __name__ == "__main__":
    main()
