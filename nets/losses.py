"""The paper's losses, each a function and a thin ``nn.Module`` twin (kornia style).

* :func:`regress_loss` L_regress: L1 between h(f(x)) and the normalised parameters y.
* :func:`recon_loss` L_recon: squared error between d(f(x)) and the image x (at the
  decoder's resolution, see :mod:`ipm.nets.decoder`).
* :func:`latent_loss` L_latent: squared distance of the latent codes f(x) of synthetic
  images to sg(mu_SMA), the simple moving average of real-image latent codes over the last
  5 batches (:class:`LatentSMA`).

All are means over elements, so their weights lambda do not depend on the input size.
"""

from __future__ import annotations

from collections import deque

import torch
import torch.nn.functional as F
from torch import nn


def _check_same(a: torch.Tensor, b: torch.Tensor, what: str) -> None:
    if a.shape != b.shape:
        raise ValueError(f"{what}: shapes differ, {tuple(a.shape)} vs {tuple(b.shape)}")


def regress_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """L_regress = mean |pred - target| over ``(B, K)`` normalised parameters.

    >>> regress_loss(torch.zeros(2, 3), torch.ones(2, 3))
    tensor(1.)
    """
    if pred.ndim != 2:
        raise ValueError(f"expected predictions (B, K), got {tuple(pred.shape)}")
    _check_same(pred, target, "regress_loss")
    return F.l1_loss(pred, target)


def recon_loss(recon: torch.Tensor, image: torch.Tensor) -> torch.Tensor:
    """L_recon = mean (recon - image')^2 with recon ``(B, 3, h, w)`` and image ``(B, 3, H, W)``,
    where image' is the image area-averaged to ``(h, w)`` (h <= H, w <= W).

    >>> recon_loss(torch.zeros(1, 3, 4, 4), torch.ones(1, 3, 8, 8))
    tensor(1.)
    """
    if recon.ndim != 4 or image.ndim != 4 or recon.shape[:2] != image.shape[:2]:
        raise ValueError(f"expected (B, C, h, w) and (B, C, H, W), got {tuple(recon.shape)} "
                         f"and {tuple(image.shape)}")
    return F.mse_loss(recon, F.adaptive_avg_pool2d(image, recon.shape[-2:]))


def latent_loss(z: torch.Tensor, mu_real: torch.Tensor) -> torch.Tensor:
    """L_latent = mean (z - sg(mu_real))^2, z ``(B, C, h, w)``, mu_real ``(C, h, w)``.

    >>> latent_loss(torch.ones(2, 4, 1, 1), torch.zeros(4, 1, 1))
    tensor(1.)
    """
    if z.ndim != 4:
        raise ValueError(f"expected latent codes (B, C, h, w), got {tuple(z.shape)}")
    _check_same(z[0], mu_real, "latent_loss")
    return F.mse_loss(z, mu_real.detach().expand_as(z))


class RegressLoss(nn.Module):
    """Module twin of :func:`regress_loss`."""

    def forward(self, pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        return regress_loss(pred, target)


class ReconLoss(nn.Module):
    """Module twin of :func:`recon_loss`."""

    def forward(self, recon: torch.Tensor, image: torch.Tensor) -> torch.Tensor:
        return recon_loss(recon, image)


class LatentLoss(nn.Module):
    """Module twin of :func:`latent_loss`."""

    def forward(self, z: torch.Tensor, mu_real: torch.Tensor) -> torch.Tensor:
        return latent_loss(z, mu_real)


class LatentSMA:
    """mu_SMA: the mean latent code of real images over the last ``batches`` batches.

    >>> sma = LatentSMA(batches=2)
    >>> for v in (0.0, 2.0, 4.0):
    ...     sma.update(torch.full((3, 4, 1, 1), v))
    >>> sma.mean.flatten()
    tensor([3., 3., 3., 3.])
    """

    def __init__(self, batches: int = 5) -> None:
        if batches < 1:
            raise ValueError(f"batches must be >= 1, got {batches}")
        self._means: deque[torch.Tensor] = deque(maxlen=batches)

    def update(self, z_real: torch.Tensor) -> None:
        """Add the batch ``(B, C, h, w)`` of real-image latent codes (detached)."""
        if z_real.ndim != 4:
            raise ValueError(f"expected latent codes (B, C, h, w), got {tuple(z_real.shape)}")
        self._means.append(z_real.detach().mean(0))

    @property
    def ready(self) -> bool:
        return bool(self._means)

    @property
    def mean(self) -> torch.Tensor:
        """sg(mu_SMA), ``(C, h, w)``."""
        if not self._means:
            raise RuntimeError("no real-image batch seen yet")
        return torch.stack(tuple(self._means)).mean(0)
