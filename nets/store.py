"""Weights on disk: safetensors (loading never runs code) plus a JSON config beside them.

A trained net is a folder with ``model.safetensors`` (f and h; the decoder is only needed
for training) and ``model.json`` (its :class:`~ipm.nets.model.NetConfig`, training summary
and validation errors).  A training checkpoint is one ``checkpoint.safetensors`` holding the
weights, the optimiser state and, in its metadata, the training state as JSON: one file,
written atomically, so a killed run resumes from the last complete epoch.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import torch
from safetensors import SafetensorError, safe_open
from safetensors.torch import load_file, save_file

from ipm.errors import UserError
from ipm.io import atomic_path, write_text
from ipm.nets.model import NetConfig, YarnNet

WEIGHTS = "model.safetensors"
CONFIG = "model.json"
#: An ensemble folder's list of its nets (and the setup they were trained on).
ENSEMBLE = "ensemble.json"
CHECKPOINT = "checkpoint.safetensors"


def save_tensors(path: str | os.PathLike, tensors: dict[str, torch.Tensor],
                 metadata: dict[str, str] | None = None) -> None:
    """Write ``tensors`` (moved to the CPU) atomically as safetensors."""
    cpu = {k: v.detach().to("cpu").contiguous() for k, v in tensors.items()}
    with atomic_path(path) as tmp:
        save_file(cpu, str(tmp), metadata=metadata)


def load_tensors(path: str | os.PathLike) -> tuple[dict[str, torch.Tensor], dict[str, str]]:
    """Read a safetensors file; a missing or corrupt file is a one-line :class:`UserError`."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"weights file {path} not found")
    try:
        tensors = load_file(str(path))
        with safe_open(str(path), "pt") as f:
            meta = f.metadata() or {}
    except (SafetensorError, OSError, ValueError, RuntimeError) as e:
        raise UserError(f"weights file {path} is corrupt or not safetensors "
                        f"({str(e).splitlines()[0] if str(e) else type(e).__name__})") from None
    return tensors, meta


def read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"{path} not found") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise UserError(f"{path} is not readable JSON ({e})") from None


def halve(folder: str | os.PathLike) -> None:
    """Store every net of an ensemble folder in float16 (half the bytes; a net loads its
    weights back into float32, :func:`load_net`), each file rewritten atomically.  The
    shipped nets are stored so where their accuracy is unchanged (the model cards)."""
    for path in sorted(Path(folder).glob(f"*/{WEIGHTS}")):
        tensors, meta = load_tensors(path)
        save_tensors(path, {k: v.half() if v.is_floating_point() else v
                            for k, v in tensors.items()}, meta)


def inference_state(net: YarnNet) -> dict[str, torch.Tensor]:
    return {k: v for k, v in net.state_dict().items() if not k.startswith("d.")}


def save_net(folder: Path, net: YarnNet, info: dict[str, Any]) -> None:
    """Write ``model.safetensors`` (f, h) then ``model.json`` (config + ``info``)."""
    folder.mkdir(parents=True, exist_ok=True)
    save_tensors(folder / WEIGHTS, inference_state(net), {"format": net.config.format})
    write_text(folder / CONFIG, json.dumps({"config": net.config.to_dict(), **info},
                                           indent=2) + "\n")


def load_net(folder: Path, device: str | torch.device = "cpu") -> tuple[YarnNet, dict]:
    """Rebuild a net from its folder, in eval mode; returns (net, model.json contents)."""
    meta = read_json(folder / CONFIG)
    try:
        cfg = meta["config"]
        config = NetConfig(**{**cfg, "decoder": False})
    except (KeyError, TypeError, ValueError) as e:
        raise UserError(f"{folder / CONFIG}: not a model config ({e})") from None
    net = YarnNet(config)
    tensors, _ = load_tensors(folder / WEIGHTS)
    try:
        net.load_state_dict(tensors)
    except RuntimeError as e:
        raise UserError(f"{folder / WEIGHTS} does not match {folder / CONFIG} "
                        f"({str(e).splitlines()[0]})") from None
    if not all(bool(torch.isfinite(t).all()) for t in tensors.values() if t.is_floating_point()):
        raise UserError(f"{folder / WEIGHTS} holds non-finite weights (NaN or inf): a diverged "
                        "training run; retrain it or restore the file")
    return net.to(device).eval(), meta


def save_checkpoint(path: Path, net: YarnNet, optimizer: torch.optim.Optimizer,
                    state: dict[str, Any]) -> None:
    """One atomic file: ``net.*`` weights, ``optim.<i>.<name>`` Adam moments, and the
    JSON-able training ``state`` plus the optimiser's param groups in the metadata."""
    tensors = {f"net.{k}": v for k, v in net.state_dict().items()}
    opt = optimizer.state_dict()
    for i, s in opt["state"].items():
        for name, v in s.items():
            tensors[f"optim.{i}.{name}"] = v if torch.is_tensor(v) else torch.tensor(v)
    meta = {"state": json.dumps(state), "param_groups": json.dumps(opt["param_groups"])}
    save_tensors(path, tensors, meta)


def load_checkpoint(path: Path, net: YarnNet, optimizer: torch.optim.Optimizer) -> dict:
    """Restore ``net`` and ``optimizer`` in place; returns the training state."""
    tensors, meta = load_tensors(path)
    try:
        net.load_state_dict({k[4:]: v for k, v in tensors.items() if k.startswith("net.")})
        opt_state: dict[int, dict[str, torch.Tensor]] = {}
        for k, v in tensors.items():
            if k.startswith("optim."):
                _, i, name = k.split(".", 2)
                opt_state.setdefault(int(i), {})[name] = v
        optimizer.load_state_dict({"state": opt_state,
                                   "param_groups": json.loads(meta["param_groups"])})
        return json.loads(meta["state"])
    except (KeyError, ValueError, RuntimeError) as e:
        raise UserError(f"checkpoint {path} does not match this run "
                        f"({str(e).splitlines()[0]}); use another --out") from None


def pack_ensemble(folder: Path) -> bytes:
    """The files of an ensemble folder that its nets load (its :data:`ENSEMBLE` and each
    listed net's config and weights) as one tar: nets sent to a worker on a machine that
    does not have the folder (``ipm fit FOLDER --ray ... --models DIR``)."""
    import io
    import tarfile

    manifest = read_json(folder / ENSEMBLE)
    names = manifest.get("nets") if isinstance(manifest, dict) else None
    if not isinstance(names, list):
        raise UserError(f"{folder / ENSEMBLE} lists no nets")
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w") as tar:
        tar.add(folder / ENSEMBLE, ENSEMBLE)
        for name in names:
            for f in (CONFIG, WEIGHTS):
                if (folder / str(name) / f).is_file():  # (a missing one: said when loaded)
                    tar.add(folder / str(name) / f, f"{name}/{f}")
    return buf.getvalue()


def unpack_ensemble(data: bytes) -> Path:
    """:func:`pack_ensemble`'s tar unpacked into a new temporary folder, returned."""
    import io
    import tarfile
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="ipm-nets-"))
    with tarfile.open(fileobj=io.BytesIO(data)) as tar:
        tar.extractall(folder, filter="data")
    return folder
