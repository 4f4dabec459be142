"""Training: every net of a preset, one after the other, each resumable after a kill.

Layout of ``--out``::

    train.json                 the TrainConfig of the run
    ensemble.json              the nets trained so far (what ``ipm predict --models`` reads)
    <net>/model.safetensors    best epoch's weights (f, h)
    <net>/model.json           its NetConfig, validation errors, baseline, timings
    <net>/checkpoint.safetensors   last epoch: weights, Adam state, history (for resuming)

Under ``torchrun --nproc-per-node K -m ipm train ...`` each process trains on a shard of
every epoch (DistributedDataParallel; gloo on CPU, NCCL on CUDA); rank 0 validates and
writes.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch.utils.data import DataLoader, DistributedSampler

from ipm.errors import UserError
from ipm.io import write_text
from ipm.nets.config import PRESETS, TrainConfig
from ipm.nets.data import Crops, Frames
from ipm.nets.model import FORMAT, NetConfig, YarnNet, crop_size, frame_size
from ipm.nets.objective import Objective
from ipm.nets.store import (
    CHECKPOINT,
    CONFIG,
    ENSEMBLE,
    load_checkpoint,
    load_net,
    read_json,
    save_checkpoint,
    save_net,
)
from ipm.nets.tasks import TASKS, Task
from ipm.params import PAPER_INTERVALS, from_unit

#: Options that may change when a run is resumed; any other change needs a new --out.
RESUMABLE = {"epochs", "workers", "device", "out", "nets", "steps_per_epoch", "data", "val",
             "real", "init"}


@dataclass(frozen=True)
class Dist:
    """This process's place in a torchrun job (rank 0 of 1 without torchrun)."""

    rank: int = 0
    world: int = 1
    device: str = "cpu"

    @property
    def main(self) -> bool:
        return self.rank == 0

    def barrier(self) -> None:
        if self.world > 1:
            torch.distributed.barrier()


def init_dist(device: str) -> Dist:
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if device.startswith("cuda") and not torch.cuda.is_available():
        raise UserError("--device cuda: no CUDA device is available (torch.cuda)")
    if world <= 1:
        return Dist(device=device)
    local = int(os.environ.get("LOCAL_RANK", "0"))
    if device.startswith("cuda"):
        device = f"cuda:{local}"
        torch.cuda.set_device(device)
    else:  # share the cores between the processes of this machine
        local_world = int(os.environ.get("LOCAL_WORLD_SIZE", str(world)))
        torch.set_num_threads(max(1, (os.cpu_count() or 1) // local_world))
    if not torch.distributed.is_initialized():
        torch.distributed.init_process_group("nccl" if device.startswith("cuda") else "gloo")
    return Dist(torch.distributed.get_rank(), world, device)


# -- validation --------------------------------------------------------------------------------
@torch.no_grad()
def predict_all(net: YarnNet, crops: Crops, batch_size: int, device: str) -> np.ndarray:
    """Outputs ``(N, K)`` (probabilities for classification) over ``crops`` in order."""
    net.eval()
    loader = DataLoader(crops, batch_size=batch_size, shuffle=False)
    return torch.cat([net.predict(x.to(device)).cpu() for x, _ in loader]).numpy()


def raw_values(task: Task, normalised: np.ndarray) -> np.ndarray:
    """``(N, K)`` normalised -> raw units (clipped to the intervals, integers rounded)."""
    return np.array([[from_unit(k, x) for k, x in zip(task.params, row, strict=True)]
                     for row in np.asarray(normalised).reshape(-1, len(task.params))],
                    dtype=np.float64).reshape(np.shape(normalised))


def errors(task: Task, outputs: np.ndarray, targets: np.ndarray) -> dict:
    """Validation summary: ``loss`` (the training loss on the validation set), per-parameter
    MAE in raw units and in % of the interval, or the accuracy of a classification."""
    if task.is_classification:
        probs = torch.from_numpy(outputs).clamp_min(1e-12)
        loss = F.nll_loss(probs.log(), torch.from_numpy(targets).long()).item()
        return {"loss": loss, "accuracy": float(np.mean(outputs.argmax(1) == targets))}
    pred, true = raw_values(task, outputs), raw_values(task, targets)
    mae = np.abs(pred - true).mean(0)
    span = np.array([PAPER_INTERVALS[k].width for k in task.params])
    return {"loss": float(np.abs(outputs - targets).mean()),
            "mae": dict(zip(task.params, mae.tolist(), strict=True)),
            "mae_pct": dict(zip(task.params, (100 * mae / span).tolist(), strict=True))}


def baseline(task: Task, train_targets: np.ndarray, val_targets: np.ndarray) -> dict:
    """The same summary for predicting the training set's mean (majority class)."""
    if task.is_classification:
        counts = np.bincount(train_targets, minlength=task.outputs)
        probs = np.tile(counts / counts.sum(), (len(val_targets), 1))
        return errors(task, probs, val_targets)
    return errors(task, np.tile(train_targets.mean(0), (len(val_targets), 1)), val_targets)


def summary_line(task: Task, m: dict) -> str:
    if task.is_classification:
        return f"accuracy {100 * m['accuracy']:.1f}%"
    return "  ".join(f"{k} {m['mae'][k]:.4g}{(' ' + PAPER_INTERVALS[k].unit).rstrip()} "
                     f"({m['mae_pct'][k]:.1f}%)" for k in task.params)


# -- one net -----------------------------------------------------------------------------------
def learning_rate(cfg: TrainConfig, epoch: int) -> float:
    """The rate of ``epoch`` (1-based): constant, or cosine from lr down to lr / 100; a
    function of the epoch alone, so a resumed run continues the same schedule."""
    if cfg.schedule == "constant" or cfg.epochs == 1:
        return cfg.lr
    floor = cfg.lr / 100
    return floor + 0.5 * (cfg.lr - floor) * (1 + math.cos(math.pi * (epoch - 1) / (cfg.epochs - 1)))


def _real_batches(real: Crops, batch_size: int, dist: Dist, seed: int) -> Iterator[torch.Tensor]:
    """Endless real-image batches, a new shuffle and new crops per pass."""
    g, epoch = torch.Generator(), 0
    while True:
        real.set_epoch(epoch)
        g.manual_seed(seed * 7919 + epoch * dist.world + dist.rank)
        for x, _ in DataLoader(real, batch_size=min(batch_size, len(real)), shuffle=True,
                               generator=g):
            yield x
        epoch += 1


def warm_start(net: YarnNet, folder: Path) -> None:
    """Start ``net`` from the trained weights in ``folder`` (``--init``: fine-tuning, e.g. a
    shipped net on more epochs or other data); its encoder, width, input scale and outputs
    must be the same.  A decoder the folder's net lacks starts from scratch."""
    trained, _ = load_net(folder)
    mine, theirs = net.config.to_dict(), trained.config.to_dict()
    differ = [k for k in mine if k != "decoder" and mine[k] != theirs.get(k)]
    if differ:
        theirs_text = ", ".join(f"{k} {theirs.get(k)}" for k in differ)
        mine_text = ", ".join(f"{k} {mine[k]}" for k in differ)
        raise UserError(f"--init {folder} is another net ({theirs_text}); this run trains "
                        f"{mine_text}")
    net.load_state_dict(trained.state_dict(), strict=False)


def train_net(name: str, cfg: TrainConfig, train_frames: Frames, val_frames: Frames,
              real_frames: Frames | None, dist: Dist, log: Callable[[str], None]) -> None:
    task, preset = TASKS[name], PRESETS[cfg.preset]
    adapted = name in preset.adapted
    recon, latent = adapted and preset.recon, adapted and preset.latent
    ncfg = NetConfig(name, cfg.encoder, cfg.width, cfg.input_scale, decoder=recon,
                     crop_px=cfg.crop)
    folder = cfg.out / name
    torch.manual_seed(cfg.seed)
    net = YarnNet(ncfg).to(dist.device)
    objective = Objective(net, recon, latent, cfg.lambda_recon, cfg.lambda_latent,
                          cfg.sma_batches)
    optimizer = torch.optim.Adam(net.parameters(), lr=cfg.lr)

    train_crops = Crops(train_frames, ncfg.crop, task, True, cfg.seed, cfg.exposure_ev,
                        cfg.blur_px, cfg.look)
    val_crops = Crops(val_frames, ncfg.crop, task, False)
    train_targets = np.stack([task.target(p) for p in train_frames.labels])
    val_targets = np.stack([task.target(p) for p in val_frames.labels])
    base = baseline(task, train_targets, val_targets)
    # The predict-the-mean baseline on any test set: mean normalised label, class frequencies.
    train_mean = (np.bincount(train_targets, minlength=task.outputs) / len(train_targets)
                  if task.is_classification else train_targets.mean(0)).tolist()

    state = {"epoch": 0, "best_epoch": None, "best_loss": None, "history": [],
             "seconds": 0.0, "net": ncfg.to_dict()}
    if (folder / CHECKPOINT).is_file():
        state = load_checkpoint(folder / CHECKPOINT, net, optimizer)
        if state.get("net") != ncfg.to_dict():
            raise UserError(f"{folder} holds a different net ({state.get('net')}); "
                            "use another --out")
        if dist.main:
            log(f"[{name}] resuming after epoch {state['epoch']}")
    elif cfg.init is not None:
        warm_start(net, cfg.init / name)
        if dist.main:
            log(f"[{name}] starting from the weights of {cfg.init / name}")
    if state["epoch"] >= cfg.epochs:
        if dist.main:
            log(f"[{name}] done ({state['epoch']} epochs; best {state['best_epoch']})")
        return
    if dist.main:
        log(f"[{name}] {ncfg.encoder} x{ncfg.width:g}, input {ncfg.crop[1]}x{ncfg.crop[0]} px, "
            f"{len(train_frames)} train / {len(val_frames)} val images; "
            f"predict-the-mean baseline: {summary_line(task, base)}")

    model: torch.nn.Module = objective
    if dist.world > 1:
        model = torch.nn.parallel.DistributedDataParallel(
            objective, device_ids=[dist.device] if dist.device.startswith("cuda") else None)
    per_rank = max(1, cfg.batch_size // dist.world)
    sampler = (DistributedSampler(train_crops, dist.world, dist.rank, shuffle=True,
                                  seed=cfg.seed) if dist.world > 1 else None)
    shuffle_gen = torch.Generator()
    loader = DataLoader(train_crops, batch_size=per_rank, sampler=sampler,
                        shuffle=sampler is None, generator=shuffle_gen,
                        num_workers=cfg.workers, drop_last=len(train_crops) >= 2 * per_rank)
    real_iter = None
    if real_frames is not None and (recon or latent):
        real_crops = Crops(real_frames, ncfg.crop, None, True, cfg.seed + 1, cfg.exposure_ev)
        real_iter = _real_batches(real_crops, per_rank, dist, cfg.seed)

    for epoch in range(state["epoch"] + 1, cfg.epochs + 1):
        t0 = time.perf_counter()
        train_crops.set_epoch(epoch)
        for group in optimizer.param_groups:
            group["lr"] = learning_rate(cfg, epoch)
        shuffle_gen.manual_seed(cfg.seed * 1_000_003 + epoch)
        if sampler is not None:
            sampler.set_epoch(epoch)
        steps = len(loader) if cfg.steps_per_epoch is None else min(len(loader),
                                                                     cfg.steps_per_epoch)
        net.train()
        sums: dict[str, float] = {}
        with _progress(dist.main, f"[{name}] epoch {epoch}/{cfg.epochs}", steps) as advance:
            for step, (x, y) in enumerate(loader):
                if step >= steps:
                    break
                x_real = next(real_iter).to(dist.device) if real_iter is not None else None
                terms = model(x.to(dist.device), y.to(dist.device), x_real)
                optimizer.zero_grad(set_to_none=True)
                terms["loss"].backward()
                optimizer.step()
                for k, v in terms.items():
                    sums[k] = sums.get(k, 0.0) + v.item()
                advance(terms["loss"].item())
        train_terms = {k: v / max(1, steps) for k, v in sums.items()}
        seconds = time.perf_counter() - t0
        if dist.main:
            metrics = errors(task, predict_all(net, val_crops, per_rank, dist.device),
                             val_targets)
            best = state["best_loss"] is None or metrics["loss"] < state["best_loss"]
            state["history"].append({"epoch": epoch, "train": train_terms, "val": metrics,
                                     "seconds": seconds})
            state["seconds"] += seconds
            state["epoch"] = epoch
            if best:
                state["best_epoch"], state["best_loss"] = epoch, metrics["loss"]
                save_net(folder, net, {"epoch": epoch, "val": metrics, "baseline": base,
                                       "train_mean": train_mean,
                                       "train": {k: v for k, v in cfg.to_dict().items()
                                                 if k not in RESUMABLE},
                                       "train_images": len(train_frames),
                                       "val_images": len(val_frames),
                                       "seconds_per_epoch": state["seconds"] / epoch})
                _write_ensemble(cfg)
            save_checkpoint(folder / CHECKPOINT, net, optimizer, state)
            log(f"[{name}] epoch {epoch}/{cfg.epochs} {seconds:.0f}s train "
                f"{train_terms['loss']:.4f} val {metrics['loss']:.4f}"
                f"{' *' if best else '  '} {summary_line(task, metrics)}")
        else:
            state["epoch"] = epoch
        dist.barrier()


class _progress:
    """A rich progress bar over one epoch on rank 0; a no-op elsewhere."""

    def __init__(self, show: bool, title: str, total: int) -> None:
        from rich.console import Console

        self.console = Console(stderr=True)
        # Not on a terminal (logs, CI): the per-epoch lines suffice.
        self.show = show and self.console.is_terminal
        self.title, self.total = title, total

    def __enter__(self) -> Callable[[float], None]:
        if not self.show:
            return lambda loss: None
        from ipm.progress import progress_bar

        self.bar = progress_bar("loss {task.fields[loss]:.4f}", transient=True,
                                console=self.console)
        self.bar.start()
        task = self.bar.add_task(self.title, total=self.total, loss=float("nan"))
        return lambda loss: self.bar.update(task, advance=1, loss=loss)

    def __exit__(self, *exc: object) -> None:
        if self.show:
            self.bar.stop()


# -- a run -------------------------------------------------------------------------------------
def _write_ensemble(cfg: TrainConfig) -> None:
    nets = [n for n in PRESETS[cfg.preset].tasks if (cfg.out / n / CONFIG).is_file()]
    write_text(cfg.out / ENSEMBLE, json.dumps({"format": FORMAT, "preset": cfg.preset,
                                               "setup": cfg.setup, "nets": nets}, indent=2)
               + "\n")


def _check_resume(cfg: TrainConfig) -> None:
    path = cfg.out / "train.json"
    if not path.is_file():
        return
    old, new = read_json(path), json.loads(json.dumps(cfg.to_dict()))  # tuples as lists
    # an option newer than the run counts as its default there
    defaults = {f.name: f.default for f in fields(TrainConfig)}
    changed = sorted(k for k in new if k not in RESUMABLE and old.get(k, defaults[k]) != new[k])
    if changed:
        raise UserError(f"{cfg.out} holds a run with other options ({', '.join(changed)}); "
                        "use another --out or the same options to resume")


def train(cfg: TrainConfig, log: Callable[[str], None] = print) -> Path:
    """Train (or resume) every net of ``cfg``; returns the run folder."""
    dist = init_dist(cfg.device)
    if dist.main:
        cfg.out.mkdir(parents=True, exist_ok=True)
        _check_resume(cfg)
        write_text(cfg.out / "train.json", json.dumps(cfg.to_dict(), indent=2) + "\n")
    dist.barrier()
    crop = cfg.crop or crop_size(cfg.input_scale)
    train_frames = Frames.synthetic(cfg.data, cfg.input_scale, crop)
    val_frames = Frames.synthetic(cfg.val, cfg.input_scale, crop)
    for folder, frames in ((cfg.data, train_frames), (cfg.val, val_frames)):
        other = sorted({r.setup for r in frames.records} - {cfg.setup})
        if other:
            raise UserError(f"{folder} holds {', '.join(other)} renders; these nets are for "
                            f"{cfg.setup} photos (--setup)")
    real_frames = None
    if cfg.real is not None:
        real_frames = Frames.real(cfg.real, cfg.input_scale, crop, cfg.real_pixel_size,
                                  cfg.real_invert, frame_size(cfg.input_scale)[0])
    for name in cfg.tasks:
        train_net(name, cfg, train_frames, val_frames, real_frames, dist, log)
    if dist.main:
        _write_ensemble(cfg)
    return cfg.out
