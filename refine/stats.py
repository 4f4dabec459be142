"""Image statistics of a yarn photo that do not depend on where each random fiber lands.

A render with the right parameters and another fiber seed should score as well as the photo
itself, so the loss compares statistics, not pixels (DESIGN.md).  The yarn runs horizontally;
after centring it vertically, the image is cut into horizontal strips (the core band in the
middle, the border band with the flyaways outside) and each strip is described by:

* ``profile``: the mean signed deviation from the background per row (occupancy across the
  yarn: core thickness ``2 (R_ply + r)``, flyaway density by distance);
* ``texture``: the standard deviation along each row;
* ``orientation``: magnitude-weighted double-angle moments of the image gradient (harmonics 2
  and 4 of the orientation histogram) and the log gradient energy: the helix angles of the
  fibers and plies, and the direction of twist;
* ``spectrum``: log power in log-spaced frequency bands along the axis, relative to the
  strip's mean power: the periodicity of the ply twist (``alpha_ply / n``) and of the fibers;
* ``histogram``: a soft intensity histogram of the whole image.

Each statistic is computed on a kornia Gaussian pyramid (``levels``).  Shapes: images are
``(B, C, H, W)`` floats in [0, 1], C = 1 or 3.
"""

from __future__ import annotations

import math

import kornia
import torch
from torch import Tensor, nn

GROUPS = ("profile", "texture", "orientation", "spectrum", "histogram")


def _check_image(x: Tensor, name: str) -> None:
    if not isinstance(x, Tensor) or x.ndim != 4 or x.shape[1] not in (1, 3):
        raise ValueError(f"{name} must be a (B, C, H, W) tensor with C in (1, 3), got "
                         f"{tuple(x.shape) if isinstance(x, Tensor) else type(x).__name__}")
    if x.shape[-2] < 16 or x.shape[-1] < 32:
        raise ValueError(f"{name} is too small for yarn statistics: {tuple(x.shape)}")


def _centred_deviation(gray: Tensor) -> Tensor:
    """(B, 1, H, W) signed deviation from the background, rolled so the yarn's centre of
    mass (of |deviation|) sits on the middle row."""
    h = gray.shape[-2]
    edge = max(1, h // 12)
    border = torch.cat([gray[..., :edge, :], gray[..., -edge:, :]], dim=-2)
    bg = border.flatten(1).median(dim=1).values.view(-1, 1, 1, 1)
    dev = gray - bg
    weight = dev.abs().mean(dim=-1).squeeze(1)  # (B, H)
    rows = torch.arange(h, dtype=gray.dtype, device=gray.device)
    centre = (weight * rows).sum(-1) / weight.sum(-1).clamp_min(1e-8)
    shifts = (h // 2 - centre.round()).long().tolist()
    return torch.stack([torch.roll(d, s, dims=-2) for d, s in zip(dev, shifts, strict=True)])


def _strip_mean(x: Tensor, strips: int) -> Tensor:
    """(B, H, ...) -> (B, strips, ...): mean over equal groups of rows."""
    h = x.shape[1] - x.shape[1] % strips
    return x[:, :h].reshape(x.shape[0], strips, h // strips, *x.shape[2:]).mean(dim=2)


def _band_edges(w: int, bands: int) -> list[tuple[int, int]]:
    top = w // 2
    edges = torch.unique(torch.logspace(0, math.log10(top + 1), bands + 1).long()).tolist()
    return [(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]


def _level_stats(dev: Tensor, strips: int, bands: int) -> dict[str, Tensor]:
    b, _, h, w = dev.shape
    d = dev[:, 0]
    profile = d.mean(dim=-1)  # (B, H)
    texture = _strip_mean(d.std(dim=-1, keepdim=True), strips)[..., 0]

    g = kornia.filters.spatial_gradient(dev)[:, 0]  # (B, 2, H, W)
    gx, gy = g[:, 0], g[:, 1]
    energy = gx * gx + gy * gy
    c2, s2 = gx * gx - gy * gy, 2 * gx * gy
    inv = 1 / (energy + 1e-12)
    moments = torch.stack([energy, c2, s2, (c2 * c2 - s2 * s2) * inv, 2 * c2 * s2 * inv], -1)
    m = _strip_mean(moments.mean(dim=2), strips)  # (B, strips, 5)
    e = m[..., :1].clamp_min(1e-12)
    orientation = torch.cat([m[..., 1:] / e, 0.1 * torch.log(e)], dim=-1).flatten(1)

    window = torch.hann_window(w, dtype=dev.dtype, device=dev.device)
    centred = d - d.mean(dim=-1, keepdim=True)
    power = torch.fft.rfft(centred * window, dim=-1).abs().square()  # (B, H, W/2 + 1)
    power = _strip_mean(power, strips)
    banded = torch.stack([power[..., a:bb].mean(-1) for a, bb in _band_edges(w, bands)], -1)
    logp = torch.log(banded + 1e-10)
    spectrum = 0.25 * (logp - logp.mean(dim=-1, keepdim=True)).flatten(1)
    return {"profile": 4 * profile, "texture": 4 * texture, "orientation": orientation,
            "spectrum": spectrum}


def yarn_statistics(image: Tensor, levels: int = 2, strips: int = 12, bands: int = 16
                    ) -> dict[str, Tensor]:
    """Statistics of a batch of yarn images, each group ``(B, D_group)``.

    >>> s = yarn_statistics(torch.rand(2, 3, 120, 400))
    >>> sorted(s) == sorted(GROUPS)
    True
    """
    _check_image(image, "image")
    gray = kornia.color.rgb_to_grayscale(image) if image.shape[1] == 3 else image
    dev = _centred_deviation(gray)
    out: dict[str, list[Tensor]] = {k: [] for k in GROUPS}
    for level in range(levels):
        if level:
            dev = kornia.geometry.transform.pyrdown(dev)
        for k, v in _level_stats(dev, strips, bands).items():
            out[k].append(v)
    bins = torch.linspace(0, 1, 24, dtype=gray.dtype, device=gray.device)
    hist = kornia.enhance.histogram(gray.flatten(1), bins, torch.tensor(0.02, dtype=gray.dtype))
    out["histogram"] = [4 * hist.sqrt()]
    return {k: torch.cat(v, dim=1) for k, v in out.items()}


def yarn_stat_loss(x: Tensor, x_o: Tensor, weights: dict[str, float] | None = None,
                   **kwargs) -> Tensor:
    """(B,) weighted mean squared difference of :func:`yarn_statistics` between renders
    ``x`` and the observed photo(s) ``x_o`` (both ``(B, C, H, W)`` or ``x_o`` with B = 1).

    >>> x = torch.rand(1, 3, 120, 400)
    >>> float(yarn_stat_loss(x, x))
    0.0
    """
    _check_image(x, "x")
    _check_image(x_o, "x_o")
    if x.shape[-2:] != x_o.shape[-2:]:
        raise ValueError(f"x and x_o must have the same size, got {tuple(x.shape[-2:])} and "
                         f"{tuple(x_o.shape[-2:])}")
    weights = weights or {}
    sx, so = yarn_statistics(x, **kwargs), yarn_statistics(x_o, **kwargs)
    return sum(weights.get(k, 1.0) * (sx[k] - so[k]).square().mean(dim=1) for k in GROUPS)


class YarnStatLoss(nn.Module):
    """Module twin of :func:`yarn_stat_loss`; precomputes nothing, holds the options."""

    def __init__(self, weights: dict[str, float] | None = None, levels: int = 2,
                 strips: int = 12, bands: int = 16) -> None:
        super().__init__()
        self.weights, self.kw = weights, dict(levels=levels, strips=strips, bands=bands)

    def forward(self, x: Tensor, x_o: Tensor) -> Tensor:
        return yarn_stat_loss(x, x_o, self.weights, **self.kw)
