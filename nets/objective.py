"""The training objective of one net: the task loss plus, for the adapted nets of the
``reg-ae*`` / ``reg-*latent`` presets, lambda_recon L_recon and lambda_latent L_latent.

It is an ``nn.Module`` holding the net, so that DistributedDataParallel wraps one forward
that touches every trained weight (encoder, head, decoder).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from ipm.nets.losses import LatentSMA, latent_loss, recon_loss, regress_loss
from ipm.nets.model import YarnNet


def task_loss(net: YarnNet, out: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    """L_regress (L1 on normalised parameters) or, for ``n`` and the thickness class,
    the cross-entropy of the softmax classification."""
    if net.config.spec.is_classification:
        return F.cross_entropy(out, y)
    return regress_loss(out, y)


class Objective(nn.Module):
    """``forward(x, y, x_real=None)`` -> dict of the loss terms and their weighted sum
    ``loss``.  x ``(B, 3, H, W)`` synthetic crops, y their labels, x_real ``(B', 3, H, W)``
    unlabelled real crops (needed by L_latent; used by L_recon when given)."""

    def __init__(self, net: YarnNet, recon: bool = False, latent: bool = False,
                 lambda_recon: float = 1.0, lambda_latent: float = 0.1,
                 sma_batches: int = 5) -> None:
        super().__init__()
        if recon and net.d is None:
            raise ValueError("L_recon needs a net with a decoder")
        self.net, self.recon, self.latent = net, recon, latent
        self.lambda_recon, self.lambda_latent = lambda_recon, lambda_latent
        self.sma = LatentSMA(sma_batches)

    def forward(self, x: torch.Tensor, y: torch.Tensor,
                x_real: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
        z, out = self.net(x)
        terms = {"task": task_loss(self.net, out, y)}
        loss = terms["task"]
        z_real = None
        if x_real is not None and (self.recon or self.latent):
            # Only L_recon back-propagates through real images; mu_SMA is a constant.
            with torch.set_grad_enabled(self.recon and torch.is_grad_enabled()):
                z_real = self.net.f(x_real)
        if self.recon:
            terms["recon"] = recon_loss(self.net.decode(z), x)
            if z_real is not None:
                terms["recon"] = 0.5 * (terms["recon"] + recon_loss(self.net.decode(z_real),
                                                                    x_real))
            loss = loss + self.lambda_recon * terms["recon"]
        if self.latent:
            if z_real is None:
                raise ValueError("L_latent needs real images (x_real)")
            self.sma.update(z_real)
            terms["latent"] = latent_loss(z, self.sma.mean)
            loss = loss + self.lambda_latent * terms["latent"]
        terms["loss"] = loss
        return terms
