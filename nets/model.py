"""One net of the ensemble: encoder f, regression head h and, for the autoencoder presets,
decoder d; and :class:`NetConfig`, everything needed to rebuild it (saved as JSON beside the
weights)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn

from ipm.frame import FRAME_HEIGHT_PX, FRAME_WIDTH_PX
from ipm.nets.config import ENCODERS
from ipm.nets.decoder import Decoder
from ipm.nets.encoders import Encoder, latent_channels
from ipm.nets.heads import RegressionHead
from ipm.nets.tasks import TASKS, Task

#: The paper's net input, 1200 x 584 px out of the 2000 x 600 px frame at full resolution.
CROP_FULL = (584, 1200)
FORMAT = "ipm.nets/1"


def crop_size(input_scale: float) -> tuple[int, int]:
    """(H, W) of the net input at ``input_scale`` (1 = the paper's 584 x 1200)."""
    return tuple(max(32, round(c * input_scale)) for c in CROP_FULL)


def frame_size(input_scale: float) -> tuple[int, int]:
    """(H, W) of the full 2000 x 600 frame at ``input_scale``."""
    return round(FRAME_HEIGHT_PX * input_scale), round(FRAME_WIDTH_PX * input_scale)


@dataclass(frozen=True)
class NetConfig:
    """A net's architecture and input: task, encoder, width multiplier, input scale (the
    scene's pixel pitch is ``PIXEL_SIZE_MM / input_scale``), whether d is trained, and
    ``crop_px`` (H, W): the input size when it is not the paper's crop at that scale -- a
    detail net sees a small window at a fine pitch (``ipm generate --view``), where the
    fibers' slant shows, at a fraction of the full crop's cost."""

    task: str
    encoder: str = "resnet18"
    width: float = 1.0
    input_scale: float = 1.0
    decoder: bool = False
    format: str = FORMAT
    crop_px: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        if self.crop_px is not None:  # JSON gives a list
            object.__setattr__(self, "crop_px", tuple(int(c) for c in self.crop_px))
            if len(self.crop_px) != 2 or min(self.crop_px) < 32:
                raise ValueError(f"crop must be (H, W), each at least 32 px, got {self.crop_px}")
        if self.task not in TASKS:
            raise ValueError(f"unknown task {self.task!r}; one of {', '.join(TASKS)}")
        if self.encoder not in ENCODERS:
            raise ValueError(f"unknown encoder {self.encoder!r}; one of {', '.join(ENCODERS)}")
        latent_channels(self.width)  # validates
        if not 0 < self.input_scale <= 1:
            raise ValueError(f"input scale must be in (0, 1], got {self.input_scale}")
        if self.format != FORMAT:
            raise ValueError(f"unsupported model format {self.format!r} (expected {FORMAT})")

    @property
    def crop(self) -> tuple[int, int]:
        return self.crop_px or crop_size(self.input_scale)

    @property
    def spec(self) -> Task:
        return TASKS[self.task]

    def to_dict(self) -> dict:
        d = asdict(self)
        if self.crop_px is None:  # as saved before detail nets: their runs still resume
            del d["crop_px"]
        else:
            d["crop_px"] = list(self.crop_px)  # as JSON gives it back
        return d


class YarnNet(nn.Module):
    """x ``(B, 3, H, W)`` in [-1, 1] -> (latent z = f(x), output h(z) ``(B, K)``).

    >>> net = YarnNet(NetConfig("alpha", width=0.25, input_scale=0.1, decoder=True))
    >>> z, y = net(torch.zeros(2, 3, *net.config.crop))
    >>> y.shape, net.decode(z).shape
    (torch.Size([2, 1]), torch.Size([2, 3, 32, 64]))
    """

    def __init__(self, config: NetConfig) -> None:
        super().__init__()
        self.config = config
        self.f = Encoder(config.encoder, config.width)
        self.h = RegressionHead(config.spec.outputs, self.f.channels,
                                mlp=config.encoder != "convnext")
        self.d = Decoder(self.f.channels) if config.decoder else None

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        z = self.f(x)
        return z, self.h(z)

    def decode(self, z: torch.Tensor) -> torch.Tensor:
        if self.d is None:
            raise RuntimeError("this net has no decoder (config.decoder is False)")
        return self.d(z)

    def predict(self, x: torch.Tensor) -> torch.Tensor:
        """h(f(x)), with class probabilities (softmax) for a classification net."""
        y = self.h(self.f(x))
        return y.softmax(1) if self.config.spec.is_classification else y
