"""The encoder f: image ``(B, 3, H, W)`` -> latent code ``(B, C, ceil(H/32), ceil(W/32))``.

As in the paper the latent code is the output of the convolution stack of a ResNet18/34
(torchvision's blocks, written out here so that loading a ResNet net does not import
torchvision, which takes longer than the nets' prediction) without its average pooling and
fully connected layer: the pooling moves into the head h.  ``convnext`` keeps ResNet18's
stage layout (2, 2, 2, 2 blocks, 32x downsampling) with ConvNeXt blocks, which use layer
norm instead of batch norm.

``width`` scales the channels of every stage (64, 128, 256, 512 at width 1, the paper's
networks; C = 512 * width).  Narrower encoders are what makes training on a laptop CPU and
shipping nine nets in a small package possible: width 0.5 has a quarter of the weights and
multiply-adds.  All start from random weights: nothing is downloaded.
"""

from __future__ import annotations

import torch
from torch import nn

from ipm.nets.config import ENCODERS

BASE_WIDTHS = (64, 128, 256, 512)
DOWNSAMPLING = 32


def latent_channels(width: float) -> int:
    """C of the latent code at this width multiplier."""
    return stage_widths(width)[-1]


def stage_widths(width: float) -> tuple[int, ...]:
    if not 0 < width <= 4:
        raise ValueError(f"width multiplier must be in (0, 4], got {width}")
    return tuple(max(8, round(c * width)) for c in BASE_WIDTHS)


class BasicBlock(nn.Module):
    """torchvision's ResNet BasicBlock: the same layers, names (so the same weights load)
    and arithmetic."""

    def __init__(self, c_in: int, c: int, stride: int = 1,
                 downsample: nn.Module | None = None) -> None:
        super().__init__()
        self.conv1 = nn.Conv2d(c_in, c, 3, stride=stride, padding=1, bias=False)
        self.bn1 = nn.BatchNorm2d(c)
        self.relu = nn.ReLU(inplace=True)
        self.conv2 = nn.Conv2d(c, c, 3, stride=1, padding=1, bias=False)
        self.bn2 = nn.BatchNorm2d(c)
        self.downsample = downsample
        self.stride = stride

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        identity = x if self.downsample is None else self.downsample(x)
        out = self.bn2(self.conv2(self.relu(self.bn1(self.conv1(x)))))
        out += identity
        return self.relu(out)


def _resnet(depths: tuple[int, ...], widths: tuple[int, ...]) -> nn.Sequential:
    # torchvision's ResNet stem and BasicBlocks, assembled for any stage width.
    layers: list[nn.Module] = [nn.Conv2d(3, widths[0], 7, stride=2, padding=3, bias=False),
                               nn.BatchNorm2d(widths[0]), nn.ReLU(inplace=True),
                               nn.MaxPool2d(3, stride=2, padding=1)]
    c_in = widths[0]
    for i, (depth, c) in enumerate(zip(depths, widths, strict=True)):
        for b in range(depth):
            stride = 2 if i > 0 and b == 0 else 1
            down = None
            if stride != 1 or c_in != c:
                down = nn.Sequential(nn.Conv2d(c_in, c, 1, stride=stride, bias=False),
                                     nn.BatchNorm2d(c))
            layers.append(BasicBlock(c_in, c, stride, down))
            c_in = c
    for m in layers:  # torchvision's initialisation
        for mod in m.modules():
            if isinstance(mod, nn.Conv2d):
                nn.init.kaiming_normal_(mod.weight, mode="fan_out", nonlinearity="relu")
    return nn.Sequential(*layers)


def _convnext(depths: tuple[int, ...], widths: tuple[int, ...]) -> nn.Sequential:
    from torchvision.models.convnext import CNBlock, LayerNorm2d

    layers: list[nn.Module] = [nn.Conv2d(3, widths[0], kernel_size=4, stride=4),
                               LayerNorm2d(widths[0], eps=1e-6)]
    for i, (depth, c) in enumerate(zip(depths, widths, strict=True)):
        if i > 0:
            layers += [LayerNorm2d(widths[i - 1], eps=1e-6),
                       nn.Conv2d(widths[i - 1], c, kernel_size=2, stride=2)]
        layers += [CNBlock(c, layer_scale=1e-6, stochastic_depth_prob=0.0) for _ in range(depth)]
    layers.append(LayerNorm2d(widths[-1], eps=1e-6))
    return nn.Sequential(*layers)


class Encoder(nn.Module):
    """f: ``(B, 3, H, W)`` in [-1, 1] -> ``(B, 512 * width, ceil(H/32), ceil(W/32))``.

    >>> f = Encoder("resnet18", width=0.25)
    >>> f(torch.zeros(2, 3, 64, 96)).shape
    torch.Size([2, 128, 2, 3])
    """

    def __init__(self, name: str = "resnet18", width: float = 1.0) -> None:
        super().__init__()
        if name not in ENCODERS:
            raise ValueError(f"unknown encoder {name!r}; choose one of {', '.join(ENCODERS)}")
        widths = stage_widths(width)
        build = _convnext if name == "convnext" else _resnet
        self.body = build(ENCODERS[name], widths)
        self.channels = widths[-1]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.ndim != 4 or x.shape[1] != 3:
            raise ValueError(f"expected images of shape (B, 3, H, W), got {tuple(x.shape)}")
        return self.body(x)
