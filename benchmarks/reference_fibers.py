"""ipm's fibers beside the paper authors' own generator for the same parameters: the four
presets of ``../shared/reference-fibers/`` measured alike by the tests' own geometry
(``tests/geometry.py``: :func:`yarn_measures`, the measure ``tests/test_reference_fibers.py``
checks), ipm averaged over three fiber seeds; with ``--figure``, both rendered in the frontlit
scene at the same pixel size, the authors' left, ipm's right.

    python -m ipm.benchmarks.reference_fibers --out benchmarks/results/reference_fibers.md \\
        --figure docs/figures/reference_flyaways.jpg
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import sys
from pathlib import Path

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish
from ipm.fibers import FiberKind, FiberSet
from ipm.generator import generate
from ipm.params import YarnParams

COMMAND = ("python -m ipm.benchmarks.reference_fibers --out "
           "benchmarks/results/reference_fibers.md --figure docs/figures/reference_flyaways.jpg")
ROOT = Path(__file__).resolve().parents[1]
MEASURES = ("fiber_pitch", "ply_pitch", "core_p95", "reach", "beyond", "per_10mm")
#: Scale of the figure's renders (0.0167 mm per pixel) and the length of yarn shown (mm).
FIGURE_SCALE, FIGURE_MM = 0.6, 8.0


def _tests_module(name: str):
    """A module of the repository's tests folder (the measure is the tests' own)."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "tests" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(ROOT / "tests"))  # its own imports (geometry)
    spec.loader.exec_module(module)
    return module


def authors_fibers(npz) -> FiberSet:
    """The authors' polylines as a FiberSet, centred on z = 0 (their flyaways as hairs: the
    file does not tell hairs from loops)."""
    points = npz["points_mm"].astype(np.float32)
    core = npz["is_flyaway"] == 0
    z = points[: npz["offsets"][np.argmin(core)] if not core.all() else None, 2]
    points = points - np.float32([0, 0, 0.5 * (z.min() + z.max())])
    f = len(npz["offsets"]) - 1
    return FiberSet(points=points, offsets=npz["offsets"].astype(np.int64),
                    radii=np.column_stack([npz["bevel_radius_x_mm"], npz["bevel_radius_y_mm"]]),
                    kind=np.where(core, FiberKind.CORE, FiberKind.HAIR).astype(np.uint8),
                    ply=np.zeros(f, np.int16))


def figure(folder: Path, names: list[str], out: Path) -> None:
    from PIL import Image, ImageDraw

    from ipm.render.renderer import Renderer, to_srgb8
    from ipm.render.scene import pixel_size_mm

    renderer = Renderer()
    keep = int(FIGURE_MM / pixel_size_mm(FIGURE_SCALE))
    rows = []
    for name in names:
        params = YarnParams.from_dict(json.loads((folder / f"authors_{name}.json").read_text())
                                      ["params"])
        pair = []
        for fibers in (authors_fibers(np.load(folder / f"authors_{name}.npz")),
                       generate(params, 1)):
            image = to_srgb8(renderer.render_fibers(fibers, params.color, FIGURE_SCALE, 16))
            left = (image.shape[1] - keep) // 2
            pair.append(image[:, left:left + keep])
        gap = np.full((pair[0].shape[0], 8, 3), 255, np.uint8)
        row = Image.fromarray(np.concatenate([pair[0], gap, pair[1]], axis=1))
        ImageDraw.Draw(row).text((6, 4), f"{name}: authors' generator", fill=(255, 255, 255))
        ImageDraw.Draw(row).text((keep + 14, 4), f"{name}: ipm", fill=(255, 255, 255))
        rows.append(np.asarray(row))
    sheet = np.concatenate([np.pad(r, ((0, 6), (0, 0), (0, 0)), constant_values=255)
                            for r in rows])
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(sheet).save(out, quality=90)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reference", default=str(ROOT.parent / "shared" / "reference-fibers"))
    ap.add_argument("--out", default=None)
    ap.add_argument("--figure", default=None)
    args = ap.parse_args()
    folder = Path(args.reference)
    test = _tests_module("test_reference_fibers")
    rows = ["| preset | " + " | ".join(MEASURES) + " |", "|---" * (len(MEASURES) + 1) + "|"]
    data = {}
    test.REFERENCE = folder  # the test's measure, on the folder asked for
    for name in test.PRESETS:
        ratio = test.ratios(name)
        data[name] = ratio
        rows.append(f"| {name} | " + " | ".join(f"{ratio[k]:.3f}" for k in MEASURES) + " |")
    text = (markdown_header("ipm's fibers over the authors' for the same parameters", COMMAND)
            + "\nRatios ipm / authors (1 = the same), each measured from the polylines alone "
            "(`tests/geometry.py` `yarn_measures`): fiber pitch along the ply's own arc, ply "
            "pitch, the core's 95th-percentile radius, the median flyaway reach beyond it, "
            "the share of flyaway length more than 0.2 mm beyond it, and flyaways per 10 mm "
            "(the authors' per 40 mm of their fiber template; `tests/test_reference_fibers.py` "
            "says why).  The test's bounds: pitches within 2% and 1%, reach and share "
            "0.8-1.25, density within 15%.\n\n" + "\n".join(rows) + "\n")
    if args.figure:
        figure(folder, list(test.PRESETS), Path(args.figure))
        link = os.path.relpath(args.figure, Path(args.out).parent if args.out else ".")
        text += f"\n![the authors' fibers and ipm's, rendered alike]({link})\n"
    publish(text, args.out, data)


if __name__ == "__main__":
    main()
