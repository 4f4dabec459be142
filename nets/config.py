"""Options of the nets' commands: one frozen dataclass per command (its defaults are the
command's defaults, its fields are saved with a run) and the named training presets."""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from ipm.errors import UserError
from ipm.frame import PIXEL_SIZE_MM
from ipm.nets.tasks import ENSEMBLE_TASKS, REG_TASKS, TASKS
from ipm.setups import DEFAULT_SETUP, check_setup_name, setup_of

#: The encoders :mod:`ipm.nets.encoders` builds: blocks per stage (a ResNet's, or a ConvNeXt's).
ENCODERS = {"resnet18": (2, 2, 2, 2), "resnet34": (3, 4, 6, 3), "convnext": (2, 2, 2, 2)}


@dataclass(frozen=True)
class Preset:
    """Which nets to train and which of them add the domain-adaptation losses."""

    tasks: tuple[str, ...]
    recon: bool = False
    latent: bool = False
    #: The paper trains the flyaway net with L_regress alone in every variant.
    adapted: tuple[str, ...] = ()
    help: str = ""


_REG = tuple(t.name for t in REG_TASKS)
PRESETS: dict[str, Preset] = {
    "ensemble": Preset(tuple(t.name for t in ENSEMBLE_TASKS),
                       help="one net per raw-yarn parameter (n and the fiber thickness as "
                            "classes) plus the flyaway net: the paper's best"),
    "reg": Preset(_REG, help="Reg: one net for all raw-yarn parameters, one for flyaways"),
    "reg-ae": Preset(_REG, recon=True, adapted=("raw",),
                     help="Reg^ae: Reg + decoder, L_regress + lambda_recon L_recon"),
    "reg-latent": Preset(_REG, latent=True, adapted=("raw",),
                         help="Reg_latent: Reg + lambda_latent L_latent (needs --real)"),
    "reg-ae-latent": Preset(_REG, recon=True, latent=True, adapted=("raw",),
                            help="Reg^ae_latent: both (needs --real)"),
}

#: The paper's training (Experiments): full-width ResNet at 1200 x 584, 1000 epochs, batch
#: 32, Adam at 1e-4 -- days on a CPU, hours on GPUs.
PAPER = dict(encoder="resnet18", width=1.0, input_scale=1.0, epochs=1000, batch_size=32,
             lr=1e-4, schedule="constant")
SCHEDULES = ("cosine", "constant")


@dataclass(frozen=True)
class TrainConfig:
    """``ipm train``.  The defaults are sized for a 2-core CPU and a small package: ResNet18
    at a quarter of its width (0.77 M weights, 3.1 MB per net, 28 MB for the nine nets) on
    inputs at a quarter of the paper's resolution (300 x 146 px, 0.04 mm per pixel), 12
    epochs with a cosine-decaying learning rate (a short run needs the decay to settle; the
    paper's 1000 epochs used a constant rate).  ``TrainConfig.paper()`` / ``--paper`` is
    the paper's configuration."""

    data: Path
    val: Path
    out: Path
    preset: str = "ensemble"
    real: Path | None = None
    nets: tuple[str, ...] = ()
    encoder: str = "resnet18"
    width: float = 0.25
    input_scale: float = 0.25
    crop: tuple[int, int] | None = None
    epochs: int = 12
    batch_size: int = 32
    lr: float = 1e-3
    schedule: str = "cosine"
    lambda_recon: float = 1.0
    lambda_latent: float = 0.1
    sma_batches: int = 5
    exposure_ev: float = 0.5
    blur_px: float = 0.0
    look: bool = False
    setup: str = DEFAULT_SETUP
    steps_per_epoch: int | None = None
    seed: int = 0
    device: str = "cpu"
    workers: int = 0
    real_pixel_size: float = PIXEL_SIZE_MM
    real_invert: bool = False
    init: Path | None = None

    def __post_init__(self) -> None:
        if self.preset not in PRESETS:
            raise UserError(f"unknown preset {self.preset!r}; one of {', '.join(PRESETS)}")
        p = PRESETS[self.preset]
        bad = [n for n in self.nets if n not in p.tasks]
        if bad:
            raise UserError(f"preset {self.preset} has no net {', '.join(bad)}; "
                            f"its nets: {', '.join(p.tasks)}")
        if p.latent and self.real is None:
            raise UserError(f"preset {self.preset} needs unlabelled real photos: --real DIR")
        if self.encoder not in ENCODERS:
            raise UserError(f"unknown encoder {self.encoder!r}; one of {', '.join(ENCODERS)}")
        checks = [("width", self.width, 0 < self.width <= 4),
                  ("input scale", self.input_scale, 0 < self.input_scale <= 1),
                  ("crop", self.crop, self.crop is None or min(self.crop) >= 32),
                  ("epochs", self.epochs, self.epochs >= 1),
                  ("batch size", self.batch_size, self.batch_size >= 1),
                  ("learning rate", self.lr, self.lr > 0),
                  ("lambda_recon", self.lambda_recon, self.lambda_recon >= 0),
                  ("lambda_latent", self.lambda_latent, self.lambda_latent >= 0),
                  ("SMA batches", self.sma_batches, self.sma_batches >= 1),
                  ("exposure range", self.exposure_ev, self.exposure_ev >= 0),
                  ("blur", self.blur_px, 0 <= self.blur_px <= 8),
                  ("steps per epoch", self.steps_per_epoch,
                   self.steps_per_epoch is None or self.steps_per_epoch >= 1),
                  ("workers", self.workers, self.workers >= 0),
                  ("real pixel size", self.real_pixel_size, self.real_pixel_size > 0)]
        for name, value, ok in checks:
            if not ok:
                raise UserError(f"{name} = {value} is out of range")
        setup_of(self.setup)  # an unknown setup is one line naming the choices
        if self.schedule not in SCHEDULES:
            raise UserError(f"unknown schedule {self.schedule!r}; one of {', '.join(SCHEDULES)}")
        if self.device.split(":")[0] not in ("cpu", "cuda", "mps"):
            raise UserError(f"unknown device {self.device!r} (cpu, cuda, cuda:N, mps)")
        for name in ("data", "val", "real", "init"):
            folder = getattr(self, name)
            if folder is not None and not Path(folder).is_dir():
                raise UserError(f"--{name} {folder} is not a folder")

    @classmethod
    def paper(cls, **overrides: Any) -> TrainConfig:
        """The paper's configuration, with ``overrides`` on top."""
        return cls(**{**PAPER, **overrides})

    @property
    def tasks(self) -> tuple[str, ...]:
        return self.nets or PRESETS[self.preset].tasks

    def to_dict(self) -> dict[str, Any]:
        return {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(self).items()}

    def replace(self, **changes: Any) -> TrainConfig:
        return replace(self, **changes)


@dataclass(frozen=True)
class PredictConfig:
    """``ipm predict``: the photos, the models, crops to average, the photos' capture setup
    (each photo's pixel size is its own: :func:`ipm.photo.pixel_size_of`)."""

    photos: tuple[Path, ...]
    models: Path | None = None
    crops: int = 3
    invert: bool = False
    device: str = "cpu"
    setup: str = DEFAULT_SETUP

    def __post_init__(self) -> None:
        check_setup_name(self.setup)  # an unknown setup is one line naming the choices
        if not 1 <= self.crops <= 64:
            raise UserError(f"crops must be in 1..64, got {self.crops}")


@dataclass(frozen=True)
class SaliencyConfig:
    """``ipm saliency``: the photo, the parameter (or net) whose prediction is explained."""

    photo: Path
    param: str
    models: Path | None = None
    pixel_size: float = PIXEL_SIZE_MM
    invert: bool = False

    def __post_init__(self) -> None:
        if not self.pixel_size > 0:
            raise UserError(f"pixel size must be positive, got {self.pixel_size}")
        from ipm.params import PAPER_INTERVALS

        known = {*PAPER_INTERVALS, *TASKS}
        if self.param not in known:
            raise UserError(f"unknown parameter or net {self.param!r}; one of "
                            f"{', '.join(sorted(known))}")

