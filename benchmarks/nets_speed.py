"""Speed of the nets on this machine: predict time for one photo with the whole ensemble,
and training time per epoch of each kind of net, extrapolated from median step times.

    python -m ipm.benchmarks.nets_speed [--steps 30] [--threads 1 2] [--paper]
        [--out benchmarks/results/nets_speed.md]

Method.  Weights are random (the cost does not depend on them).  Predict: a 2000 x 600 px
photo at the scene's pixel pitch through :meth:`Ensemble.predict` (resampling to the input
scale, 3 crops per net, all 9 nets of the ``ensemble`` preset), median of 5 after one
warm-up.  Training: the real training step (:class:`Objective`, Adam, the crop and exposure
pipeline over in-memory frames) at the default batch size; median of ``--steps`` steps after
2 warm-ups, times the steps of one epoch over ``--images`` images, plus validation of
``--val-images`` images (median per-image forward time).  The load average before and after
is printed: on a shared machine other processes slow everything down.
"""

from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np
import torch

from ipm.benchmarks.machine import markdown_header, publish
from ipm.nets.config import TrainConfig
from ipm.nets.data import Crops, Frames
from ipm.nets.ensemble import Ensemble
from ipm.nets.model import NetConfig, YarnNet, frame_size
from ipm.nets.objective import Objective
from ipm.nets.tasks import ENSEMBLE_TASKS
from ipm.photo import Photo

COMMAND = "python -m ipm.benchmarks.nets_speed --out benchmarks/results/nets_speed.md"


class RandomFrames(Frames):
    """In-memory random uint8 frames with labels, standing in for a dataset folder."""

    def __init__(self, count: int, scale: float, seed: int = 0) -> None:
        from ipm.prior import GuidedPrior

        rng = np.random.default_rng(seed)
        h, w = frame_size(scale)
        self.images = [rng.integers(0, 256, (h, w, 3), dtype=np.uint8) for _ in range(count)]
        self.labels = GuidedPrior().sample_many(count, seed)

    def __len__(self) -> int:
        return len(self.images)

    def __getitem__(self, i: int) -> np.ndarray:
        return self.images[i]


def median_time(fn, repeats: int, warmup: int = 1) -> float:
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def predict_seconds(encoder: str, width: float, scale: float) -> float:
    torch.manual_seed(0)
    nets = {t.name: YarnNet(NetConfig(t.name, encoder, width, scale)).eval()
            for t in ENSEMBLE_TASKS}
    ens = Ensemble(nets, {}, None)
    photo = Photo(np.random.default_rng(0).random((600, 2000, 3), dtype=np.float32), 0.01)
    return median_time(lambda: ens.predict(photo), repeats=5)


def epoch_seconds(task: str, encoder: str, width: float, scale: float, batch: int, steps: int,
                  images: int, val_images: int, recon: bool = False) -> tuple[float, float]:
    """(median seconds per training step, extrapolated seconds per epoch incl. validation)."""
    torch.manual_seed(0)
    net = YarnNet(NetConfig(task, encoder, width, scale, decoder=recon))
    objective = Objective(net, recon=recon)
    opt = torch.optim.Adam(net.parameters(), 1e-3)
    frames = RandomFrames(2 * batch, scale)
    crops = Crops(frames, net.config.crop, net.config.spec)
    loader = torch.utils.data.DataLoader(crops, batch_size=batch, shuffle=True)
    real = next(iter(loader))[0] if recon else None

    def step() -> None:
        x, y = next(iter(loader))
        terms = objective(x, y, real)
        opt.zero_grad()
        terms["loss"].backward()
        opt.step()

    net.train()
    t_step = median_time(step, steps, warmup=2)
    net.eval()
    x = torch.stack([crops[i][0] for i in range(batch)])
    with torch.no_grad():
        t_val = median_time(lambda: net.predict(x), 3) / batch
    return t_step, math.ceil(images / batch) * t_step + val_images * t_val


def load() -> str:
    return " / ".join(f"{v:.1f}" for v in os.getloadavg())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=None)
    ap.add_argument("--steps", type=int, default=30, help="timed training steps per row")
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--images", type=int, default=2000, help="training images per epoch")
    ap.add_argument("--val-images", type=int, default=345)
    ap.add_argument("--paper", action="store_true", help="also time the paper's configuration "
                    "(full-width ResNet18 at 1200 x 584, a few steps of batch 4)")
    args = ap.parse_args()
    d = TrainConfig.__dataclass_fields__
    enc, width, scale = (d[k].default for k in ("encoder", "width", "input_scale"))
    batch, epochs = d["batch_size"].default, d["epochs"].default
    crop = NetConfig("alpha", enc, width, scale).crop
    before = load()
    rows = [f"Defaults: {enc} at width {width}, input scale {scale} ({crop[1]} x {crop[0]} px), "
            f"batch {batch}, {epochs} epochs, {args.images} training images.", "",
            "| threads | what | median | per epoch (s) | default run (min) |",
            "|---|---|---|---|---|"]
    for threads in args.threads:
        torch.set_num_threads(threads)
        t = predict_seconds(enc, width, scale)
        rows.append(f"| {threads} | predict, whole ensemble (9 nets, 3 crops), one photo | "
                    f"{t:.2f} s | | |")
        total = 0.0
        kinds = [("alpha", "one-parameter net (x6: m, alpha, r_x, r_y, alpha_ply, R_ply)", 6),
                 ("n", "classification net (x2: n, thickness)", 2),
                 ("flyaways", "flyaway net (x1)", 1)]
        for task, label, count in kinds:
            t_step, t_epoch = epoch_seconds(task, enc, width, scale, batch, args.steps,
                                            args.images, args.val_images)
            total += count * t_epoch * epochs
            rows.append(f"| {threads} | train step, {label}, batch {batch} | {t_step:.2f} s | "
                        f"{t_epoch:.0f} | {count * t_epoch * epochs / 60:.0f} |")
        rows.append(f"| {threads} | **whole default ensemble, {epochs} epochs** | | | "
                    f"**{total / 60:.0f}** |")
        t_step, t_epoch = epoch_seconds("raw", enc, width, scale, batch, args.steps,
                                        args.images, args.val_images, recon=True)
        rows.append(f"| {threads} | train step, reg-ae raw net (decoder, + real batch) | "
                    f"{t_step:.2f} s | {t_epoch:.0f} | |")
        if args.paper:
            t_step, _ = epoch_seconds("alpha", "resnet18", 1.0, 1.0, 4, 3, 4, 0)
            rows.append(f"| {threads} | paper: ResNet18 x1 at 1200 x 584, per image "
                        f"| {t_step / 4:.2f} s | {t_step / 4 * 4000:.0f} (4000 images) | |")
    rows += ["", f"Load average (1 / 5 / 15 min) before: {before}; after: {load()}."]
    text = (markdown_header("Nets speed", COMMAND, "torch", "torchvision") + "\n"
            + "\n".join(rows) + "\n")
    publish(text, args.out)


if __name__ == "__main__":
    main()
