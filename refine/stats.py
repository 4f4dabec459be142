"""Image statistics of a yarn photo that do not depend on where each random fiber lands.

A render with the right parameters and another fiber seed should score as well as the photo
itself, so the loss compares statistics, not pixels.  The yarn runs horizontally; after
centring it vertically, the groups (:data:`GROUPS`) are:

* ``core``: per row, the median deviation from the background along the axis, in units of
  the core's contrast (the median ignores sparse flyaways: the core's occupancy, thickness
  ``2 (R_ply + r)``; the units leave out the capture's contrast);
* ``flyaways``: per row, the fibers crossing it per pixel along the axis (as a hairiness
  tester counts them): how many flyaways reach each distance from the axis, in the rows
  beyond :data:`FLYAWAY_ROWS_BEYOND` core half-widths (0 in the others, where the core's own
  texture and ragged edge would read as flyaways);
* ``orientation``: per horizontal strip, magnitude-weighted double-angle moments of the
  image gradient (harmonics 2 and 4 of the orientation histogram) and the log gradient
  energy: the helix angles of the fibers and plies, and the direction of twist;
* ``spectrum``: log power of the core band in log-spaced frequency and orientation bins:
  the periodicity of the ply twist (``alpha_ply / n``) and of the fibers;
* ``period``, ``stripes``: of the core band along the axis, its autocorrelation and the
  cumulative distribution of its power over log frequency: the ply stripes' period;
* ``silhouette``: whether the core's two edges move out and in together along the axis
  (an even ply count) or one out as the other moves in (odd) (:func:`_silhouette`);
* ``contour``: the autocorrelation of those edges along the axis: the plies' period
  ``alpha_ply / n`` read off the core's outline (:func:`_contour`);
* ``histogram``: a soft intensity histogram of the whole image.

Each statistic is computed on a kornia Gaussian pyramid (``levels``).  Shapes: images are
``(B, C, H, W)`` floats in [0, 1], C = 1 or 3.
"""

from __future__ import annotations

import math

import kornia
import torch
from torch import Tensor, nn

GROUPS = ("core", "flyaways", "orientation", "spectrum", "period", "stripes", "silhouette",
          "contour", "histogram")


def _check_image(x: Tensor, name: str) -> None:
    if not isinstance(x, Tensor) or x.ndim != 4 or x.shape[1] not in (1, 3):
        raise ValueError(f"{name} must be a (B, C, H, W) tensor with C in (1, 3), got "
                         f"{tuple(x.shape) if isinstance(x, Tensor) else type(x).__name__}")
    if x.shape[-2] < 16 or x.shape[-1] < 32:
        raise ValueError(f"{name} is too small for yarn statistics: {tuple(x.shape)}")


def yarn_centre(gray: Tensor) -> tuple[Tensor, Tensor]:
    """Background level (B,) and the row (B,) of the core's centre in a ``(B, 1, H, W)``
    image: the centroid of the upper half of the per-row median of |deviation|, which
    sparse flyaways do not move."""
    h = gray.shape[-2]
    edge = max(1, h // 12)
    border = torch.cat([gray[..., :edge, :], gray[..., -edge:, :]], dim=-2)
    bg = border.flatten(1).median(dim=1).values
    weight = (gray - bg.view(-1, 1, 1, 1)).abs().median(dim=-1).values.squeeze(1)  # (B, H)
    weight = torch.clamp(weight - 0.5 * weight.amax(dim=-1, keepdim=True), min=0)
    rows = torch.arange(h, dtype=gray.dtype, device=gray.device)
    return bg, (weight * rows).sum(-1) / weight.sum(-1).clamp_min(1e-8)


def yarn_tilt(gray: Tensor, blocks: int = 10) -> Tensor:
    """Tilt (B,) of the yarn's axis in a ``(B, 1, H, W)`` image, in degrees, counter-clockwise
    (the scene's y points up, rows point down): :func:`yarn_centre` in ``blocks`` vertical
    strips, and the Theil-Sen slope (median of the pairwise slopes, so a strip whose centre a
    flyaway or the frame's edge moves does not tilt the line) through them."""
    b, _, h, w = gray.shape
    bw = w // blocks
    strips = gray[..., : bw * blocks].reshape(b, 1, h, blocks, bw).permute(0, 3, 1, 2, 4)
    _, centres = yarn_centre(strips.reshape(b * blocks, 1, h, bw))
    centres = centres.view(b, blocks)
    x = (torch.arange(blocks, dtype=gray.dtype, device=gray.device) + 0.5) * bw
    i, j = torch.triu_indices(blocks, blocks, offset=1)
    slopes = (centres[:, j] - centres[:, i]) / (x[j] - x[i])
    return -torch.rad2deg(torch.atan(slopes.median(dim=1).values))


def centre_rows(image: Tensor, centre: Tensor) -> Tensor:
    """Shift ``(B, C, H, W)`` vertically (bilinear, sub-pixel) so row ``centre`` (B,) lands
    on the middle row."""
    shift = torch.stack([torch.zeros_like(centre), (image.shape[-2] - 1) / 2 - centre], dim=-1)
    return kornia.geometry.transform.translate(image, shift, padding_mode="border")


#: The smallest core contrast the deviation is divided by: an empty image stays near 0.
CONTRAST_FLOOR = 0.02


def _centred_deviation(gray: Tensor) -> Tensor:
    """(B, 1, H, W) signed deviation from the background, the core centred vertically, in
    units of the core's contrast (the largest |per-row median deviation|).

    Why in those units: the core's contrast is the capture's (lamps, exposure, background
    level, the fibers' translucency), not the yarn's shape.  A real microscope photo's grey,
    low-contrast core matched a thinner render's core best in absolute units, so fitted
    cores came out thinner than the photos' (benchmarks/README.md, "Real photos: thickness first").
    The autocorrelation, the stripes and the spectrum were already invariant to it."""
    bg, centre = yarn_centre(gray)
    dev = centre_rows(gray - bg.view(-1, 1, 1, 1), centre)
    contrast = dev[:, 0].median(dim=-1).values.abs().amax(dim=-1)
    return dev / contrast.clamp_min(CONTRAST_FLOOR).view(-1, 1, 1, 1)


def _strip_mean(x: Tensor, strips: int) -> Tensor:
    """(B, H, ...) -> (B, strips, ...): mean over equal groups of rows."""
    h = x.shape[1] - x.shape[1] % strips
    return x[:, :h].reshape(x.shape[0], strips, h // strips, *x.shape[2:]).mean(dim=2)


def _spectrum_bins(h: int, w: int, bands: int, angles: int, device, dtype):
    """(bands * angles, h * (w // 2 + 1)) averaging matrix of the rfft2 plane: log-spaced
    radial frequency bands times orientation bins over [0, pi)."""
    fy = torch.fft.fftfreq(h, device=device, dtype=dtype)[:, None].expand(h, w // 2 + 1)
    fx = torch.fft.rfftfreq(w, device=device, dtype=dtype)[None, :].expand(h, w // 2 + 1)
    radius = torch.sqrt(fx * fx + fy * fy).flatten()
    angle = torch.remainder(torch.atan2(fy, fx), torch.pi).flatten()
    edges = torch.logspace(math.log10(1.5 / w), math.log10(0.5), bands + 1, dtype=dtype,
                           device=device)
    band = torch.bucketize(radius, edges) - 1
    ang = (angle / torch.pi * angles).long().clamp(max=angles - 1)
    valid = (band >= 0) & (band < bands)
    index = torch.where(valid, band * angles + ang, torch.full_like(band, bands * angles))
    m = torch.zeros(bands * angles + 1, radius.numel(), dtype=dtype, device=device)
    m[index, torch.arange(radius.numel(), device=device)] = 1
    m = m[:-1]
    return m / m.sum(dim=1, keepdim=True).clamp_min(1)


#: The flyaways' rows: farther from the axis than this many times the core's half-contrast
#: half-width.  Nearer, the core's stripes and the plies' bumps along its ragged edge cross
#: the fiber level as often as the flyaways do.
FLYAWAY_ROWS_BEYOND = 1.25


def _beyond_core(median: Tensor) -> Tensor:
    """(B, H) bool: the rows of a centred image farther from its axis than
    :data:`FLYAWAY_ROWS_BEYOND` times its core's half-width (the rows where the per-row
    ``median`` (B, H), in units of the core's contrast, is above one half, counted)."""
    h = median.shape[-1]
    rows = torch.arange(h, dtype=median.dtype, device=median.device) - (h - 1) / 2
    return rows.abs() > FLYAWAY_ROWS_BEYOND * _half_width(median)[:, None]


def _half_width(median: Tensor) -> Tensor:
    """(B,) the core's half-width in rows: half the rows where the per-row ``median`` (B, H),
    in units of the core's contrast, is above one half."""
    return (median.abs() > 0.5).sum(dim=-1) / 2


def core_width(gray: Tensor) -> Tensor:
    """(B,) the core's half-contrast width in rows of a ``(B, 1, H, W)`` image: the rows
    whose median deviation from the background along the axis is above half the core's
    contrast (flyaways do not move the median)."""
    return 2 * _half_width(_centred_deviation(gray)[:, 0].median(dim=-1).values)


#: A pixel is fiber where its deviation exceeds this share of the core's contrast (soft, by a
#: logistic step of FIBER_SOFTNESS).
FIBER_LEVEL = 0.2
FIBER_SOFTNESS = 0.05


def _crossings(d: Tensor) -> Tensor:
    """(B, H): per row of ``d`` (B, H, W) in units of the core's contrast, the fibers that
    cross it per pixel along the axis: the rises of its soft fiber mask (a logistic step at
    :data:`FIBER_LEVEL`), after a blur of one pixel against pixel noise.  A sharp fiber and
    a defocused one count alike, as long as it stands out by FIBER_LEVEL; the darkness they
    add to a row (the statistic's former form, the per-row mean minus the median) depends
    on how opaque and sharp each fiber is, which differs between a render and a photo.
    How the fitted renders' hairiness compares with real photos':
    benchmarks/results/real_photos.md."""
    x = kornia.filters.gaussian_blur2d(d[:, None].abs(), (5, 5), (1.0, 1.0),
                                       border_type="replicate")[:, 0]
    fiber = torch.sigmoid((x - FIBER_LEVEL) / FIBER_SOFTNESS)
    return torch.relu(fiber[..., 1:] - fiber[..., :-1]).mean(dim=-1)


def _level_stats(dev: Tensor, strips: int, bands: int) -> dict[str, Tensor]:
    b, _, h, w = dev.shape
    d = dev[:, 0]
    # the median over the axis ignores sparse flyaways: the core's occupancy
    median = d.median(dim=-1).values
    fly = torch.where(_beyond_core(median), _crossings(d), 0.0)
    edges = _core_edges(d)

    g = kornia.filters.spatial_gradient(dev)[:, 0]  # (B, 2, H, W)
    gx, gy = g[:, 0], g[:, 1]
    energy = gx * gx + gy * gy
    c2, s2 = gx * gx - gy * gy, 2 * gx * gy
    inv = 1 / (energy + 1e-12)
    moments = torch.stack([energy, c2, s2, (c2 * c2 - s2 * s2) * inv, 2 * c2 * s2 * inv], -1)
    m = _strip_mean(moments.mean(dim=2), strips)  # (B, strips, 5)
    e = m[..., :1].clamp_min(1e-12)
    orientation = torch.cat([m[..., 1:] / e, 0.1 * torch.log(e)], dim=-1).flatten(1)

    # 2-D power spectrum of the core band: the ply and fiber twist as stripes of one
    # period and orientation, averaged over the whole band
    band = d[:, h // 2 - h // 6: h // 2 + h // 6]
    window = torch.outer(torch.hann_window(band.shape[1], dtype=d.dtype, device=d.device),
                         torch.hann_window(w, dtype=d.dtype, device=d.device))
    power = torch.fft.rfft2((band - band.mean(dim=(1, 2), keepdim=True)) * window).abs().square()
    bins = _spectrum_bins(band.shape[1], w, bands, 4, d.device, d.dtype)
    logp = torch.log(power.flatten(1) @ bins.T + 1e-10)
    spectrum = 0.25 * (logp - logp.mean(dim=-1, keepdim=True))
    # the factors keep the groups' balance of the loss as it was in absolute units for a
    # core of contrast 0.5
    return {"core": 2 * median, "flyaways": 10 * fly, "orientation": orientation,
            "spectrum": spectrum, "period": _axial_autocorrelation(band),
            "stripes": _axial_spectrum_cdf(band), "silhouette": _silhouette(edges),
            "contour": _contour(edges)}


#: The silhouette: the pixels where the core's deviation, blurred by SILHOUETTE_BLUR
#: (across, along the axis) px, exceeds this share of the core's contrast; each edge
#: median-filtered along the axis over SILHOUETTE_MEDIAN px against flyaways that cross it.
SILHOUETTE_LEVEL = 0.5
SILHOUETTE_BLUR = (1.0, 2.0)
SILHOUETTE_MEDIAN = 5
#: The silhouette statistic's factor: near 1 for two round plies that touch.
SILHOUETTE_SCALE = 10.0


def _edge_distance(x: Tensor, reach: Tensor) -> Tensor:
    """(B, W): per column of ``x`` (B, R, W), rows ordered outwards from the axis, how many
    of its first ``reach`` (B,) rows are above SILHOUETTE_LEVEL (soft, by a logistic step of
    FIBER_SOFTNESS): the edge's distance from the axis.  Counted rather than the run from the
    axis to the first row below the level, so that a gap between the core's fibers does not
    cut the edge short; the rows beyond ``reach`` hold the flyaways."""
    rows = torch.arange(x.shape[1], dtype=x.dtype, device=x.device)
    within = (rows[None, :] < reach[:, None]).to(x.dtype)[..., None]
    return (torch.sigmoid((x - SILHOUETTE_LEVEL) / FIBER_SOFTNESS) * within).sum(dim=1)


def _detrended(y: Tensor) -> Tensor:
    """``y`` (..., W) minus its least-squares line along W."""
    x = torch.linspace(-1, 1, y.shape[-1], dtype=y.dtype, device=y.device)
    y = y - y.mean(dim=-1, keepdim=True)
    return y - x * (y * x).sum(-1, keepdim=True) / (x * x).sum()


def _levelled(x: Tensor) -> Tensor:
    """``x`` (B, 1, H, W), its yarn centred on the middle row, sheared about the middle
    column so that its axis runs level (:func:`yarn_tilt`; bilinear, zero outside)."""
    b, _, h, w = x.shape
    slope = -torch.tan(torch.deg2rad(yarn_tilt(x)))  # rows per column, rows pointing down
    gx = torch.linspace(-1, 1, w, dtype=x.dtype, device=x.device)
    gy = torch.linspace(-1, 1, h, dtype=x.dtype, device=x.device)
    shift = (slope * (w - 1) / (h - 1))[:, None, None] * gx[None, None, :]
    grid = torch.stack([gx.expand(b, h, w), gy[None, :, None] + shift], dim=-1)
    return torch.nn.functional.grid_sample(x, grid, align_corners=True)


def _core_edges(d: Tensor) -> Tensor:
    """(B, 2, W): the distances of the upper and lower edge of the core's silhouette from
    the axis along it, of ``d`` (B, H, W), centred, in units of the core's contrast (within
    :data:`FLYAWAY_ROWS_BEYOND` core half-widths, :func:`_edge_distance`).  The image is
    sheared level by its tilt (:func:`yarn_tilt`), blurred by SILHOUETTE_BLUR, and each
    edge median-filtered along the axis over SILHOUETTE_MEDIAN px against flyaways that
    cross it."""
    h = d.shape[1]
    x = _levelled(d[:, None].abs())
    k = [2 * math.ceil(3 * s) + 1 for s in SILHOUETTE_BLUR]
    x = kornia.filters.gaussian_blur2d(x, tuple(k), SILHOUETTE_BLUR, border_type="replicate")[:, 0]
    mid = (h - 1) // 2
    reach = FLYAWAY_ROWS_BEYOND * _half_width(x.median(dim=-1).values)
    edges = torch.stack([_edge_distance(x[:, : mid + 1].flip(1), reach),
                         _edge_distance(x[:, mid:], reach)], 1)
    pad = SILHOUETTE_MEDIAN // 2
    edges = torch.nn.functional.pad(edges, (pad, pad), mode="replicate")
    return edges.unfold(-1, SILHOUETTE_MEDIAN, 1).median(dim=-1).values


def _silhouette(edges: Tensor) -> Tensor:
    """(B, 1): how the two edges of the core's silhouette (:func:`_core_edges`, (B, 2, W))
    move along the axis: the covariance of the distances ``u``, ``v`` of the upper and
    lower edge from the axis, as a signed root over the mean width ``W``, times
    SILHOUETTE_SCALE: ``sign(C) sqrt(|C|) / W``.

    Why: the core's outline is the union of the plies' outlines.  Two plies winding about
    the axis are seen side by side (widest) and one behind the other (narrowest) in turn:
    both edges move out and in together, ``C > 0``.  With three plies (any odd count) a
    ply standing out on one side leaves a gap on the other: the centreline wanders, one
    edge moves out as the other moves in, ``C < 0``.  Four plies swing the width less than
    two.  The stripes and the period see the pitch ``alpha_ply / n`` alone, which a 2-ply
    and a 3-ply yarn of other pitches share.  Why the covariance, not the correlation: a
    real yarn's edges also wander apart from each other (uneven plies, hairs at the edge),
    which a render's do less; such independent wander adds to each edge's variance but not
    to their covariance.  The image is sheared level and the edges detrended, so that a
    tilted yarn does not read as a wandering centreline."""
    u, v = _detrended(edges[:, 0]), _detrended(edges[:, 1])
    cov = (u * v).mean(dim=-1)
    width = edges.sum(dim=1).mean(dim=-1).clamp_min(1.0)
    root = torch.sqrt(cov.abs() + 1e-4) - 1e-2  # finite gradient at 0
    return (SILHOUETTE_SCALE * torch.sign(cov) * root / width)[:, None]


#: The longest lag of the contour's autocorrelation, as a fraction of the image's width.
CONTOUR_LAGS = 0.5


def _contour(edges: Tensor) -> Tensor:
    """(B, CONTOUR_LAGS * W) the autocorrelation along the axis of each edge of the core's
    silhouette (:func:`_core_edges`, (B, 2, W)), detrended, averaged over the two edges, at
    lags 1 .. CONTOUR_LAGS W, each lag normalised by its overlap (:func:`_lag_products`) and
    all by lag 0.

    The plies' outlines make the core's edges move out and in every ``alpha_ply / n``
    (:func:`_silhouette`), so the autocorrelation peaks there, wherever each fiber lands.
    Why beside ``period`` and ``stripes``, which read the stripes inside the core band: a
    core of many fibers lit from behind is nearly opaque in a render and grey in a photo, so the
    stripes inside it differ between the two more than the outline does; and a microscope's
    photo shows three or four ply periods, which the ``period`` group's lags (a third of
    the width) do not reach."""
    w = edges.shape[-1]
    acf = _lag_products(_detrended(edges), int(CONTOUR_LAGS * w))
    return (acf[..., 1:] / acf[..., :1].clamp_min(1e-12)).mean(dim=1)


def _lag_products(x: Tensor, lags: int) -> Tensor:
    """(..., lags + 1) the autocorrelation of ``x`` (..., W) along its last axis at lags
    0 .. ``lags``, each lag's sum of products divided by its overlap ``W - lag``.
    Zero-padded FFT, so that the lags do not wrap around."""
    w = x.shape[-1]
    acf = torch.fft.irfft(torch.fft.rfft(x, n=2 * w).abs().square(), n=2 * w)[..., : lags + 1]
    return acf / torch.arange(w, w - lags - 1, -1, dtype=x.dtype, device=x.device)


#: Gaussian blur (std in pixels) of the core band before its autocorrelation and spectrum:
#: pixel noise (sensor noise in a photo, Monte Carlo noise in a render, at other levels)
#: would otherwise lower every normalised lag alike and read as a faster decorrelation, i.e.
#: a tighter twist; the blur keeps 1/30 of it and the ply stripes (periods of 6 px and more).
ACF_BLUR = 1.5


def _blurred_rows(band: Tensor) -> Tensor:
    """``band`` (B, h, W) blurred by ACF_BLUR, each row minus its mean."""
    k = 2 * math.ceil(3 * ACF_BLUR) + 1
    x = kornia.filters.gaussian_blur2d(band[:, None], (k, k), (ACF_BLUR, ACF_BLUR),
                                       border_type="replicate")[:, 0]
    return x - x.mean(dim=-1, keepdim=True)


def _axial_autocorrelation(band: Tensor) -> Tensor:
    """(B, W // 3) mean autocorrelation along the axis of the rows of ``band`` (B, h, W),
    blurred by ACF_BLUR, at lags 1 .. W // 3, normalised by lag 0: the stripes of the ply
    twist repeat every ``alpha_ply / n`` and peak there, wherever each fiber lands
    (:func:`_lag_products`)."""
    acf = _lag_products(_blurred_rows(band), band.shape[-1] // 3).mean(dim=1)
    return acf[:, 1:] / acf[:, :1].clamp_min(1e-12)


#: Log-spaced frequency bins of the axial spectrum, from 2 / W to PERIOD_FMAX cycles per px.
PERIOD_BINS = 24
PERIOD_FMAX = 0.25


def _axial_spectrum_cdf(band: Tensor) -> Tensor:
    """(B, PERIOD_BINS) cumulative distribution of the axial power of ``band`` (B, h, W)
    over log frequency: the rows blurred by ACF_BLUR, Hann-windowed, their power spectra
    averaged and summed into log-spaced bins, then accumulated and normalised.

    The ply stripes repeat every ``alpha_ply / n`` wherever each fiber lands, and put a peak
    there.  Why beside the autocorrelation (``period``): two autocorrelations whose periods
    differ drift apart in phase at long lags, so their squared distance has a minimum only a
    few % of the range wide around the truth and can be lower for a far tighter twist whose
    stripes the blur erases (a flat curve is closer to an oscillation than a shifted one
    is).  Between cumulative distributions the squared distance grows with how far the peak
    moved: a wide basin, coarser at its bottom, that keeps the search in the right one."""
    w = band.shape[-1]
    x = _blurred_rows(band) * torch.hann_window(w, dtype=band.dtype, device=band.device)
    power = torch.fft.rfft(x, dim=-1).abs().square().mean(dim=1)  # (B, W // 2 + 1)
    f = torch.fft.rfftfreq(w, dtype=x.dtype, device=x.device)
    edges = torch.logspace(math.log10(2 / w), math.log10(PERIOD_FMAX), PERIOD_BINS + 1,
                           dtype=x.dtype, device=x.device)
    index = torch.bucketize(f, edges) - 1
    inside = (index >= 0) & (index < PERIOD_BINS)
    binned = power.new_zeros(power.shape[0], PERIOD_BINS).index_add_(1, index[inside],
                                                                     power[:, inside])
    return binned.cumsum(dim=-1) / binned.sum(dim=-1, keepdim=True).clamp_min(1e-20)


def yarn_statistics(image: Tensor, levels: int = 2, strips: int = 6, bands: int = 6
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
    return stat_distance(yarn_statistics(x, **kwargs), yarn_statistics(x_o, **kwargs), weights)


def group_distances(sx: dict[str, Tensor], so: dict[str, Tensor]) -> dict[str, Tensor]:
    """Per group, the (B,) mean squared difference of two :func:`yarn_statistics` results
    (and of any further groups both hold, such as the nets' readings)."""
    return {k: (sx[k] - so[k]).square().mean(dim=1) for k in so}


def weighted_sum(distances: dict, weights: dict[str, float] | None = None):
    """The loss from :func:`group_distances` (tensors or floats): weights default to 1."""
    weights = weights or {}
    return sum(weights.get(k, 1.0) * v for k, v in distances.items())


def stat_distance(sx: dict[str, Tensor], so: dict[str, Tensor],
                  weights: dict[str, float] | None = None) -> Tensor:
    """(B,) weighted mean squared difference of two :func:`yarn_statistics` results (to
    compare many renders with one photo whose statistics are computed once)."""
    return weighted_sum(group_distances(sx, so), weights)


class YarnStatLoss(nn.Module):
    """Module twin of :func:`yarn_stat_loss`; precomputes nothing, holds the options."""

    def __init__(self, weights: dict[str, float] | None = None, levels: int = 2,
                 strips: int = 6, bands: int = 6) -> None:
        super().__init__()
        self.weights, self.kw = weights, dict(levels=levels, strips=strips, bands=bands)

    def forward(self, x: Tensor, x_o: Tensor) -> Tensor:
        return yarn_stat_loss(x, x_o, self.weights, **self.kw)
