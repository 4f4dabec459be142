"""Cross-renderer test sets: yarns of ipm's model rendered by Blender Cycles in capture
setups that are not ipm's scene (:mod:`ipm.benchmarks.cycles_setups`), written as an ipm
dataset folder (``manifest.jsonl`` with the true parameters) that ``nets_accuracy --data``
and ``ipm compare`` read.  Never used in training or tuning: the yarns come from the guided
prior with seeds no other set uses (:data:`SEED`), and every scene value is drawn per sample
from its own seed and recorded in the manifest.

    bash scripts/install_blender.sh
    python -m ipm.benchmarks.cycles_testset --setup frontlit --count 60 --out data/cycles-frontlit
    python -m ipm.benchmarks.cycles_testset --setup backlit --count 60 --out data/cycles-backlit

Resumable: images already listed in the manifest are kept.  16 x 6 mm at 0.04 mm per pixel
(the nets' own pitch), 400 x 150 px, 16 samples, 4 bounces; ``--pixel-size 0.01`` renders
the same yarns and scenes at the paper's pitch (1600 x 600 px), where the detail nets read
``alpha`` and ``m``; ``--frame-mm 3.2 3.2`` renders only the middle of each yarn, the detail
nets' window (a ninth of the pixels, so a ninth of the time at that pitch).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from ipm.dataset import MANIFEST
from ipm.generator import generate
from ipm.io import write_text
from ipm.prior import GuidedPrior

SEED = 31_415_926
PIXEL_SIZE_MM = 0.04
FRAME_MM = (16.0, 6.0)
SAMPLES = 16
#: Generator axes (x, y, z) -> Blender world: the yarn along world x, seen from +z.
TO_WORLD = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def scene_values(setup: str, rng: np.random.Generator) -> dict:
    """The sample's randomised capture: camera roll, focus, f-number, exposure, fiber
    roughness and the setup's lights and background."""
    v = {"roll_deg": rng.uniform(-2, 2), "focus_offset_mm": rng.uniform(-1.5, 1.5),
         "fstop": rng.uniform(2.8, 8.0), "exposure": rng.uniform(-0.4, 0.4),
         "roughness": rng.uniform(0.2, 0.5), "room": rng.uniform(0.0, 0.05)}
    if setup == "backlit":
        v.update(panel=rng.uniform(0.25, 0.45), fill=rng.uniform(0.0, 2e4))
    else:
        grey = rng.uniform(0.02, 0.15)
        v.update(lamp_azimuth_deg=rng.uniform(-40, 40), lamp_elevation_deg=rng.uniform(20, 60),
                 lamp_size=rng.uniform(40, 120), lamp_power=rng.uniform(2e5, 6e5),
                 card=[grey * rng.uniform(0.8, 1.2) for _ in range(3)])
    return v


def _write_manifest(out: Path, records: dict, done: dict, finished: set) -> dict:
    """Rewrite the manifest (atomically) with the images rendered so far, so that a killed
    run resumes where it stopped."""
    keep = {i: r for i, r in records.items() if i in done or str(out / r["image"]) in finished}
    write_text(out / MANIFEST, "".join(json.dumps(keep[i]) + "\n" for i in sorted(keep)))
    return keep


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--setup", choices=("frontlit", "backlit"), required=True)
    ap.add_argument("--count", type=int, default=60)
    ap.add_argument("--out", required=True)
    ap.add_argument("--blender-python", default="/opt/bpyenv/bin/python")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--pixel-size", type=float, default=PIXEL_SIZE_MM,
                    help="mm per pixel at the yarn")
    ap.add_argument("--frame-mm", type=float, nargs=2, default=FRAME_MM, metavar=("W", "H"),
                    help="the field of view at the yarn, mm (the yarn along W, centred)")
    args = ap.parse_args()
    frame_mm = tuple(args.frame_mm)
    frame = tuple(round(mm / args.pixel_size) for mm in frame_mm)
    out = Path(args.out)
    (out / "images").mkdir(parents=True, exist_ok=True)
    done = {}
    if (out / MANIFEST).is_file():
        done = {r["index"]: r for r in map(json.loads, (out / MANIFEST).read_text().splitlines())}
    for r in done.values():
        if (r["setup"], r["pixel_size_mm"], (r["width"], r["height"])) != (
                args.setup, args.pixel_size, frame):
            raise SystemExit(f"{out} holds a {r['setup']} set of {r['width']} x {r['height']} "
                             f"px at {r['pixel_size_mm']} mm per pixel; resume it with those "
                             "or choose another --out")
    setup_seed = {"frontlit": 1, "backlit": 2}[args.setup]
    yarns = GuidedPrior().sample_many(args.count, seed=SEED)
    jobs, records = [], dict(done)
    with tempfile.TemporaryDirectory() as tmp:
        for i, params in enumerate(yarns):
            if i in done:
                continue
            rng = np.random.default_rng([SEED, setup_seed, i])
            seed = int(rng.integers(2**31))
            fibers = generate(params, seed)
            values = scene_values(args.setup, rng)
            color = (np.array(params.color) if args.setup == "frontlit"
                     else np.full(3, rng.uniform(0.15, 0.4)))  # backlit: grey, as seen through
            npz = Path(tmp) / f"{i:06d}.npz"
            np.savez(npz, points=fibers.points.astype(np.float64) @ TO_WORLD.T,
                     offsets=fibers.offsets, radius=fibers.round_radii(), color=color,
                     frame=np.array(frame), frame_mm=frame_mm[0],
                     samples=SAMPLES, seed=i, threads=args.threads, setup=args.setup,
                     **{k: np.array(x) for k, x in values.items()})
            image = f"images/{i:06d}.png"
            jobs.append({"npz": str(npz), "png": str(out / image)})
            records[i] = {"index": i, "image": image, "split": "test", "seed": seed,
                          "params": params.to_dict(), "pixel_size_mm": args.pixel_size,
                          "width": frame[0], "height": frame[1], "setup": args.setup,
                          "renderer": "cycles", "scene": values}
        if jobs:
            batch = Path(tmp) / "batch.json"
            batch.write_text(json.dumps(jobs))
            script = Path(__file__).with_name("cycles_setups.py")
            proc = subprocess.Popen([args.blender_python, str(script), str(batch)],
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            finished = set()
            for line in proc.stdout:
                if line.startswith("{"):
                    finished.add(json.loads(line)["png"])
                    print(f"{len(finished)}/{len(jobs)} {line.strip()}", flush=True)
                    _write_manifest(out, records, done, finished)
            if proc.wait() != 0:
                raise SystemExit(f"Blender failed: {proc.stderr.read().strip()[-500:]}")
    records = _write_manifest(out, records, done, finished if jobs else set())
    write_text(out / "dataset.json", json.dumps({"setup": args.setup, "renderer": "cycles",
                                                 "seed": SEED, "count": len(records),
                                                 "pixel_size_mm": args.pixel_size,
                                                 "frame_mm": list(frame_mm),
                                                 "samples": SAMPLES}, indent=2))
    print(f"{len(records)} images in {out}")


if __name__ == "__main__":
    main()
