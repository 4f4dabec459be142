"""The paper's saliency map: m_ij = max_c | d/dx_ijc (1/P sum_p f_p(x)) |.

For a regression net the mean runs over the explained parameters (one column, or all of
the net's outputs as in the paper's raw-yarn / flyaway comparison); for a classification
net (``n``, thickness) over the expected normalised class index, a smooth stand-in for the
predicted value.  The nets are fully convolutional up to the average pooling in h, so the
map covers the whole photo, not only one crop.
"""

from __future__ import annotations

import numpy as np
import torch

from ipm.errors import UserError
from ipm.nets.ensemble import Ensemble
from ipm.nets.model import YarnNet


def saliency(net: YarnNet, x: torch.Tensor, columns: list[int] | None = None) -> torch.Tensor:
    """Saliency ``(B, H, W)`` of ``net`` for inputs x ``(B, 3, H, W)``; ``columns``: the
    outputs to average (default all; ignored for classification nets).

    >>> from ipm.nets.model import NetConfig
    >>> net = YarnNet(NetConfig("alpha", width=0.25, input_scale=0.1)).eval()
    >>> saliency(net, torch.zeros(1, 3, 64, 128)).shape
    torch.Size([1, 64, 128])
    """
    if x.ndim != 4 or x.shape[1] != 3:
        raise ValueError(f"expected images (B, 3, H, W), got {tuple(x.shape)}")
    x = x.detach().clone().requires_grad_(True)
    out = net.h(net.f(x))
    if net.config.spec.is_classification:
        k = out.shape[1]
        value = (out.softmax(1) * torch.linspace(0, 1, k, device=out.device)).sum(1)
    else:
        value = out[:, columns].mean(1) if columns is not None else out.mean(1)
    (grad,) = torch.autograd.grad(value.sum(), x)
    return grad.abs().amax(1)


def net_for(ensemble: Ensemble, param: str, pixel_size_mm: float
            ) -> tuple[YarnNet, list[int] | None]:
    """The net that decides ``param`` (a parameter or a net name) for a photo of
    ``pixel_size_mm`` (:meth:`Ensemble.deciders`), and its output columns."""
    if param in ensemble.nets:
        return ensemble.nets[param], None
    name = ensemble.deciders(pixel_size_mm).get(param)
    if name is not None:
        net = ensemble.nets[name]
        spec = net.config.spec
        return net, None if spec.is_classification else [spec.params.index(param)]
    raise UserError(f"no net in {ensemble.folder} predicts {param!r}; nets: "
                    f"{', '.join(ensemble.nets)}")


def to_image(s: np.ndarray) -> np.ndarray:
    """``(H, W)`` saliency -> uint8, scaled so the 99.5th percentile is white (a few hot
    pixels would otherwise leave the rest black)."""
    top = float(np.percentile(s, 99.5)) or float(s.max()) or 1.0
    return np.round(np.clip(s / top, 0, 1) * 255).astype(np.uint8)
