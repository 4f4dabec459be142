"""The decoder d of the autoencoder path: latent code -> image at half the input resolution.

The paper's four transposed convolutions (output channels 256, 128, 64, 3; ReLU, ReLU, ReLU,
Tanh) with kernel 2 and stride k/2 = 1 cannot bring a 32x downsampled code back to image
size.  We keep four layers and the channels but use kernel 2, stride 2 in each: 16x
upsampling, i.e. a reconstruction at half the input resolution, compared against the input
area-downsampled to the same size (:func:`ipm.nets.losses.recon_loss`).  That is 4x cheaper
than a full-size output and the fiber-scale detail the encoder must keep for the real-image
path survives at half resolution.
"""

from __future__ import annotations

import torch
from torch import nn

CHANNELS = (256, 128, 64, 3)
UPSAMPLING = 16


class Decoder(nn.Module):
    """d: ``(B, C, h, w)`` -> ``(B, 3, 16 h, 16 w)`` in [-1, 1].

    >>> Decoder(channels=512)(torch.zeros(2, 512, 4, 9)).shape
    torch.Size([2, 3, 64, 144])
    """

    def __init__(self, channels: int = 512) -> None:
        super().__init__()
        self.channels = channels
        layers: list[nn.Module] = []
        c_in = channels
        for i, c_out in enumerate(CHANNELS):
            layers.append(nn.ConvTranspose2d(c_in, c_out, kernel_size=2, stride=2))
            layers.append(nn.Tanh() if i == len(CHANNELS) - 1 else nn.ReLU(inplace=True))
            c_in = c_out
        self.layers = nn.Sequential(*layers)

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        if z.ndim != 4 or z.shape[1] != self.channels:
            raise ValueError(f"expected latent codes (B, {self.channels}, h, w), "
                             f"got {tuple(z.shape)}")
        return self.layers(z)
