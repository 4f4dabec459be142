"""The regression head h: latent code ``(B, C, h, w)`` -> ``(B, K)`` outputs.

The average pooling of the ResNet lives here (the paper moved it out of the encoder).  After
it, a two-layer MLP with hidden width 512 and an ELU for the ResNet encoders, a linear
projection for ConvNeXt.  Outputs are raw: normalised parameters for regression, logits for
classification.
"""

from __future__ import annotations

import torch
from torch import nn


class RegressionHead(nn.Module):
    """h: ``(B, C, h, w)`` -> ``(B, outputs)``.

    >>> RegressionHead(3, channels=512)(torch.zeros(2, 512, 4, 9)).shape
    torch.Size([2, 3])
    """

    def __init__(self, outputs: int, channels: int = 512, mlp: bool = True,
                 hidden: int = 512) -> None:
        super().__init__()
        self.channels = channels
        self.pool = nn.AdaptiveAvgPool2d(1)
        self.mlp = (nn.Sequential(nn.Linear(channels, hidden), nn.ELU(),
                                  nn.Linear(hidden, outputs)) if mlp
                    else nn.Linear(channels, outputs))

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        if z.ndim != 4 or z.shape[1] != self.channels:
            raise ValueError(f"expected latent codes (B, {self.channels}, h, w), "
                             f"got {tuple(z.shape)}")
        return self.mlp(self.pool(z).flatten(1))
