"""Dataset and training time of the shipped nets on this machine: the recipe of
``scripts/make_nets.sh`` (its image counts and epochs, :data:`RECIPE`) times rates measured
here with the same commands on small sets.

    python -m ipm.benchmarks.make_nets_time [--images 48] \\
        [--out benchmarks/results/make_nets_time.md]

Method.  Per kind of dataset, ``ipm generate`` renders ``--images`` samples with the
recipe's options, and a fourth as many: the difference of the two commands' wall times
(all cores) over the difference in images is the time per image without the start-up; per
kind of net, ``ipm train`` trains it one epoch on them, one thread as the recipe
runs it, and its ``model.json`` gives the epoch's seconds per training image (validation
and start-up left out: a forward pass over 200 images per epoch, a few per cent).  The
projection multiplies these rates by the recipe's images and epochs; training runs as two
one-thread processes side by side, so its wall time is, phase by phase, the longer of the
two lanes.  The load average before and after is printed: other processes slow it all.  Why
projected, not timed: the whole recipe takes hours, and a shared machine makes one full run
a poor measure of either.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from ipm.benchmarks.machine import markdown_header, publish

COMMAND = "python -m ipm.benchmarks.make_nets_time --out benchmarks/results/make_nets_time.md"


@dataclass(frozen=True)
class Data:
    """A kind of dataset: ``ipm generate`` options, and how many images of it each setup's
    recipe renders (train and val sets together; a test set rendered otherwise, at the
    default spp, is a kind of its own)."""

    options: tuple[str, ...]
    images: dict[str, int]


@dataclass(frozen=True)
class Training:
    """One ``ipm train`` of the recipe: nets trained one after the other in a process, on a
    kind of dataset with extra options, in lane 1 or 2 (the two processes side by side) of
    phase 1 to 4 (the script waits for both lanes of a phase before the next; phases 3 and
    4 fine-tune, at the same cost per epoch)."""

    nets: tuple[str, ...]
    epochs: int
    data: str
    lane: int
    options: tuple[str, ...] = ()
    phase: int = 1
    preset: str = "ensemble"


DETAIL_TRAIN = ("--input-scale", "1", "--crop", "256", "256")
BACKLIT_TRAIN = ("--setup", "backlit", "--look")
FINE_WINDOW = ("--scale", "1", "--view", "320", "320", "--spp", "4-24", "--yarns", "fine",
               "--setup", "backlit", "--vary-look", "--vary-material")
FINE = "fine window, varied look"
#: scripts/make_nets.sh, as numbers (tests/test_bench.py checks them against the script).
RECIPE_DATA = {
    "frame": Data(("--spp", "4-24"), {"frontlit": 2000 + 200}),
    "test frame": Data((), {"frontlit": 200}),
    "detail window": Data(("--scale", "1", "--view", "320", "320", "--spp", "4-24"),
                          {"frontlit": 4000 + 200}),
    "whole frame at 0.01 mm": Data(("--scale", "1"), {"frontlit": 200}),
    "frontlit frame, varied look": Data(("--vary-look", "--vary-material", "--spp", "4-24"),
                                        {"frontlit": 2000 + 200}),
    "frontlit test frame, varied look": Data(("--vary-look", "--vary-material"),
                                             {"frontlit": 200}),
    "detail window, varied look": Data(("--scale", "1", "--view", "320", "320", "--spp", "4-24",
                                        "--vary-look", "--vary-material"),
                                       {"frontlit": 2000 + 200}),
    "backlit frame, varied look": Data(("--setup", "backlit", "--vary-look", "--vary-material",
                                        "--spp", "4-24"), {"backlit": 2000 + 200}),
    "backlit test frame, varied look": Data(("--setup", "backlit", "--vary-look",
                                             "--vary-material"), {"backlit": 200}),
    "fine window, varied look": Data(FINE_WINDOW, {"backlit": 2000 + 200 + 200}),
}
#: The training images of each dataset kind.
TRAIN_IMAGES = {"frame": 2000, "detail window": 4000, "frontlit frame, varied look": 2000,
                "detail window, varied look": 2000, "backlit frame, varied look": 2000,
                FINE: 2000}
TUNED = "frontlit frame, varied look"
RECIPE = {
    "frontlit": (
        Training(("alpha", "m"), 18, "frame", 1),
        Training(("n", "thickness"), 12, "frame", 1),
        Training(("alpha_ply", "R_ply", "r_x", "r_y"), 12, "frame", 2),
        Training(("flyaways",), 8, "frame", 2),
        Training(("raw",), 12, "frame", 2, preset="reg"),
        Training(("alpha",), 16, "detail window", 1, DETAIL_TRAIN, phase=2),
        Training(("alpha_ply",), 24, "frame", 1, phase=2),
        Training(("m",), 28, "detail window", 2, DETAIL_TRAIN, phase=2),
        Training(("n", "alpha_ply", "R_ply"), 6, TUNED, 1, phase=3),
        Training(("alpha", "m", "thickness", "flyaways"), 6, TUNED, 1, phase=3),
        Training(("raw",), 6, TUNED, 2, phase=3, preset="reg"),
        Training(("r_x", "r_y"), 6, TUNED, 2, phase=3),
        Training(("alpha",), 6, "detail window, varied look", 1, DETAIL_TRAIN, phase=4),
        Training(("m",), 6, "detail window, varied look", 2, DETAIL_TRAIN, phase=4),
    ),
    "backlit": (
        Training(("alpha", "m"), 18, "backlit frame, varied look", 1, BACKLIT_TRAIN),
        Training(("n", "thickness"), 12, "backlit frame, varied look", 1, BACKLIT_TRAIN),
        Training(("alpha_ply", "R_ply", "r_x", "r_y"), 12, "backlit frame, varied look", 2,
                 BACKLIT_TRAIN),
        Training(("flyaways",), 8, "backlit frame, varied look", 2, BACKLIT_TRAIN),
        Training(("raw",), 12, "backlit frame, varied look", 2, BACKLIT_TRAIN, preset="reg"),
        Training(("n", "thickness", "alpha", "m"), 12, FINE, 1, DETAIL_TRAIN + BACKLIT_TRAIN,
                 phase=2),
        Training(("flyaways",), 8, FINE, 1, DETAIL_TRAIN + BACKLIT_TRAIN, phase=2),
        Training(("alpha_ply", "R_ply", "r_x", "r_y"), 12, FINE, 2,
                 DETAIL_TRAIN + BACKLIT_TRAIN, phase=2),
        Training(("raw",), 12, FINE, 2, DETAIL_TRAIN + BACKLIT_TRAIN, phase=2, preset="reg"),
    ),
}


def run(args: list[str], threads: int | None = None) -> float:
    """Wall seconds of a command; a failure stops the benchmark with its output."""
    env = dict(os.environ, **({"OMP_NUM_THREADS": str(threads)} if threads else {}))
    t0 = time.perf_counter()
    done = subprocess.run(args, env=env, capture_output=True, text=True)
    if done.returncode:
        raise SystemExit(f"{' '.join(args)} failed:\n{done.stderr[-2000:]}")
    return time.perf_counter() - t0


def render_rates(folder: Path, images: int) -> dict[str, float]:
    """Seconds per image of each dataset kind, start-up left out: the difference of the wall
    times of ``images`` samples and of a fourth of them, over the difference in images.  The
    samples are left in ``folder`` as a train and a val set of each kind."""
    rates = {}
    for kind, data in RECIPE_DATA.items():
        out = folder / kind.replace(" ", "-")
        out.mkdir(parents=True)
        few = max(4, images // 4)
        times = [run(["ipm", "generate", "--out", str(out / split), "--count", str(count),
                      "--seed", str(seed), "--split", split, *data.options])
                 for split, count, seed in (("train", images, 0), ("val", few, 1))]
        rates[kind] = (times[0] - times[1]) / (images - few)
    return rates


def train_rate(folder: Path, kind: str, net: str, options: tuple[str, ...],
               preset: str = "ensemble") -> float:
    """Seconds per training image and epoch of ``net`` (of ``preset``) on dataset kind
    ``kind``."""
    data = folder / kind.replace(" ", "-")
    out = folder / f"run-{kind.replace(' ', '-')}-{net}-{len(options)}"
    run(["ipm", "train", "--preset", preset, "--nets", net, "--data", str(data / "train"),
         "--val", str(data / "val"), "--epochs", "1", "--blur", "1.5", "--seed", "0",
         "--lr", "1e-3", "--out", str(out), *options], threads=1)
    info = json.loads((out / net / "model.json").read_text())
    return info["seconds_per_epoch"] / info["train_images"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--images", type=int, default=48, help="images rendered per dataset kind")
    ap.add_argument("--out", default=None, help="markdown report to write")
    args = ap.parse_args()

    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="ipm-make-nets-") as tmp:
        folder = Path(tmp)
        render = render_rates(folder, args.images)
        train = {(t.data, net, t.options): train_rate(folder, t.data, net, t.options, t.preset)
                 for trainings in RECIPE.values() for t in trainings for net in t.nets}

    lines = [markdown_header("Dataset and training time of the shipped nets", COMMAND,
                             "torch", "mitsuba"),
             f"Rates measured on {args.images} images per kind (the recipe: "
             "`scripts/make_nets.sh`; method: `benchmarks/make_nets_time.py`).", "",
             "| dataset kind | s per image (2 cores) | recipe images | minutes |",
             "|---|---|---|---|"]
    for kind, data in RECIPE_DATA.items():
        count = sum(data.images.values())
        lines.append(f"| {kind} | {render[kind]:.2f} | {count} | "
                     f"{render[kind] * count / 60:.0f} |")
    lines += ["", "| setup | nets | epochs | dataset | phase, lane | s per image-epoch "
              "(1 thread) | minutes |", "|---|---|---|---|---|---|---|"]
    totals = {}
    for setup, trainings in RECIPE.items():
        lanes: dict[tuple[int, int], float] = {}
        for t in trainings:
            rates = [train[(t.data, net, t.options)] for net in t.nets]
            minutes = sum(rates) * t.epochs * TRAIN_IMAGES[t.data] / 60
            lanes[(t.phase, t.lane)] = lanes.get((t.phase, t.lane), 0.0) + minutes
            lines.append(f"| {setup} | {', '.join(t.nets)} | {t.epochs} | {t.data} | "
                         f"{t.phase}, {t.lane} | {sum(rates) / len(rates):.3f} | "
                         f"{minutes:.0f} |")
        data_min = sum(render[k] * d.images.get(setup, 0) for k, d in RECIPE_DATA.items()) / 60
        phases = sorted({phase for phase, _ in lanes})
        wall = [max(m for (ph, _), m in lanes.items() if ph == phase) for phase in phases]
        totals[setup] = (data_min, wall)
    lines += ["", "| setup | datasets (min) | training, the longer lane of each phase (min) | "
              "**whole recipe, wall (h)** |", "|---|---|---|---|"]
    for setup, (data_min, wall) in totals.items():
        lines.append(f"| {setup} | {data_min:.0f} | {' + '.join(f'{m:.0f}' for m in wall)} | "
                     f"**{(data_min + sum(wall)) / 60:.1f}** |")
    lines += ["", "Load average (1 / 5 / 15 min) before: "
              f"{' / '.join(f'{x:.1f}' for x in load_before)}; after: "
              f"{' / '.join(f'{x:.1f}' for x in os.getloadavg())}."]
    publish("\n".join(lines) + "\n", args.out)


if __name__ == "__main__":
    main()
