"""Textile measures of a yarn photo, net-free and render-free (``ipm measure``): the yarn's
diameter and its variation along the yarn, its ply twist (turns per metre and S or Z) and its
hairiness as the instruments report it (Uster's H, Zweigle's counts per distance class).  The
same analysis is the yardstick that judges fits on photos ipm did not make
(``benchmarks/photo_measures.py``, ``benchmarks/real_photos.py``): a fit's render is measured
as its photo is.  Definitions and how they relate to the testers: ``docs/measure.md``.

* Signal: how much the yarn differs from the background, in [0, 1]: the background level is
  the median of the top and bottom tenths of the frame; backlit (dark yarn on a light panel)
  ``(bg - I) / bg``, frontlit (light yarn on a dark card) ``(I - bg) / (1 - bg)``.
* Axis: the signal's centroid in each column, a line fitted through them (a photo's yarn is
  rarely exactly level); every column is shifted so the axis is the middle row.
* Core diameter: the half-contrast width of the row profile (the median over columns, which
  flyaways do not move): the width of the run of rows around the peak where the profile is
  above half its peak, with linear interpolation at both edges.
* Ply-stripe period: in the band of rows within half the core radius of the axis, each row's
  autocorrelation along the axis (mean removed), averaged over rows; the period is the lag of
  the first of its maxima after its first zero crossing that reaches 60 % of the highest
  (parabolic interpolation): a yarn repeats exactly only after a whole ply turn
  ``alpha_ply``, since its plies differ, and that later maximum can be the highest.  On a plied yarn
  this is the distance between neighbouring plies' crossings, ``alpha_ply / n``.
* Fiber width (for a photo's unknown scale): the flyaway fibers in the rows beyond 0.8 core
  diameters from the axis, thresholded at half the median darkness of their skeleton (their
  half contrast); the width at each skeleton pixel is twice its distance to the background
  minus one.  The median over the skeleton pixels of components of at least
  :data:`MIN_FIBER_PIXELS` px; defocused fibers look wider, so this errs large.
* Hairiness (as a Zweigle-type hairiness tester counts it in transmitted light): the fibers
  that cross a line parallel to the axis at a distance beyond the core's edge, per mm of
  yarn, both sides averaged, at :data:`HAIR_DISTANCES_MM`.  The image is first brought to
  :data:`HAIR_PITCH_MM` (box filter) and blurred by one of its pixels, so that a sharp
  render and a photo of the same fibers count alike; a fiber counts where the signal
  exceeds :data:`HAIR_SHARE` of the core's (the row profile's peak), so that faint
  out-of-focus fibers count too.  Each line's count is the mean over its row and the two
  next to it.
* Diameter along the yarn: the width of every :data:`DIAMETER_WINDOW_MM` of yarn between
  the outermost crossings of half the core's signal by the window's median row profile;
  its coefficient of variation (CV) over the windows.
* Twist direction: the sign of the ply stripes' slant in the core band: how the phase of
  the ply period's wave along the yarn moves from row to row across the middle half of the
  core (:func:`twist_slant`; the surface fibers, which slant against the plies, do not
  count).
  Z (a right-handed helix) slants as the middle stroke of a Z held upright, which along a
  horizontal yarn runs from upper left to lower right.  In
  transmitted light a yarn and its mirror image through the image plane cast the same
  shadow, so a pure silhouette shows no direction (strength near 0: ``None``); what a
  backlit photo shows of the direction comes from the surface in focus.
* Hairiness H (Uster): the total projected length (mm) of the fibers beyond the core's
  edges per mm of yarn, both sides.  Fibers overlap where hairs are dense (a sleeve of
  loops), so their length is not their skeleton's: each row beyond the edges is read as a
  Boolean model of fibers (stereology: fibers of width w dropped at random cover a share
  ``c = 1 - exp(-L_A w)`` of the area, where ``L_A`` is their length per area), so the
  row's fiber length per length of yarn is ``-ln(1 - c) / w``; w is the fiber pixels' area
  per length of their skeleton on the rows where hairs are sparse
  (:data:`SPARSE_COVERAGE`), measured on the image itself.  Hair lengths and angles: each
  8-connected piece of the skeleton of the fiber pixels beyond the edges.
* Zweigle-type counts: the crossings of the lines at :data:`ZWEIGLE_DISTANCES_MM` beyond the
  core's edge per 100 m of yarn, one side (both averaged), as far as the frame reaches;
  ``S3`` is the count at 3 mm where the frame reaches it.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np
from PIL import Image
from scipy import ndimage

#: A maximum of the autocorrelation counts as the period if it reaches this share of the
#: highest one (see the module notes).
FIRST_PEAK_SHARE = 0.6
#: Flyaway components smaller than this (px) are dust or noise, not fibers.
MIN_FIBER_PIXELS = 300
#: Hairiness: distances (mm) beyond the core's edge at which crossing fibers are counted, the
#: pitch (mm per pixel) they are counted at, and the signal, as a share of the core's, above
#: which a pixel is fiber.
HAIR_DISTANCES_MM = (0.05, 0.1, 0.2, 0.4)
HAIR_PITCH_MM = 0.01
HAIR_SHARE = 0.2


def gray(path: str) -> np.ndarray:
    """The image as float grayscale in [0, 1] (the mean of its channels)."""
    with Image.open(path) as im:
        a = np.asarray(im.convert("RGB"), dtype=np.float64) / 255.0
    return a.mean(axis=2)


def yarn_signal(img: np.ndarray, backlit: bool) -> np.ndarray:
    """How much each pixel differs from the background, towards the yarn, clipped to [0, 1]."""
    h = img.shape[0]
    edge = max(1, h // 10)
    bg = float(np.median(np.concatenate([img[:edge].ravel(), img[-edge:].ravel()])))
    sig = (bg - img) / max(bg, 1e-6) if backlit else (img - bg) / max(1 - bg, 1e-6)
    return np.clip(sig, 0.0, 1.0)


def axis_line(sig: np.ndarray) -> tuple[float, float]:
    """(slope, offset) of the yarn's axis, row = slope * column + offset: a line fitted
    through the columns' centroids of the squared signal (a photo's yarn is rarely level)."""
    h, w = sig.shape
    rows = np.arange(h, dtype=np.float64)[:, None]
    weight = sig ** 2
    centroid = (weight * rows).sum(0) / np.maximum(weight.sum(0), 1e-9)
    slope, offset = np.polyfit(np.arange(w), centroid, 1, w=np.sqrt(weight.sum(0)) + 1e-9)
    return float(slope), float(offset)


def levelled(sig: np.ndarray, line: tuple[float, float] | None = None) -> np.ndarray:
    """The signal with every column shifted so that the yarn's axis (:func:`axis_line`, or
    ``line``) is the middle row."""
    h, w = sig.shape
    slope, offset = axis_line(sig) if line is None else line
    x = np.arange(w)
    shift = (slope * x + offset) - (h - 1) / 2
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    return ndimage.map_coordinates(sig, [yy + shift[None, :], xx], order=1, mode="nearest")


def _crossing(profile: np.ndarray, i: int, j: int, level: float) -> float:
    """Where the profile crosses ``level`` between neighbouring rows i and j (linear)."""
    a, b = profile[i], profile[j]
    return i + (level - a) / (b - a) * (j - i) if b != a else float(i)


def core_diameter_px(sig: np.ndarray) -> float:
    """Half-contrast width (px) of the row profile of a levelled signal."""
    profile = ndimage.uniform_filter1d(np.median(sig, axis=1), 3)
    peak = int(np.argmax(profile))
    half = profile[peak] / 2
    top = peak
    while top > 0 and profile[top - 1] > half:
        top -= 1
    bottom = peak
    while bottom < len(profile) - 1 and profile[bottom + 1] > half:
        bottom += 1
    lo = _crossing(profile, top - 1, top, half) if top > 0 else 0.0
    hi = _crossing(profile, bottom, bottom + 1, half) if bottom < len(profile) - 1 else bottom
    return float(hi - lo)


def stripe_period_px(sig: np.ndarray, diameter_px: float) -> float:
    """Period (px) of the stripes along the axis in the core band of a levelled signal, or
    NaN when the autocorrelation has no maximum after its first zero crossing."""
    h, w = sig.shape
    half = max(1, int(diameter_px / 4))
    band = sig[(h - 1) // 2 - half:(h - 1) // 2 + half + 1]
    band = band - band.mean(axis=1, keepdims=True)
    n = 2 * w
    spec = np.fft.rfft(band, n=n, axis=1)
    ac = np.fft.irfft(spec * np.conj(spec), n=n, axis=1)[:, : w // 2].mean(axis=0)
    ac /= max(ac[0], 1e-12)
    below = np.flatnonzero(ac < 0)
    if not len(below):
        return float("nan")
    k = np.arange(below[0] + 1, len(ac) - 1)
    peaks = k[(ac[k] > ac[k - 1]) & (ac[k] >= ac[k + 1]) & (ac[k] > 0)]
    if not len(peaks):
        return float("nan")
    k = int(peaks[np.argmax(ac[peaks] >= FIRST_PEAK_SHARE * ac[peaks].max())])
    a, b, c = ac[k - 1], ac[k], ac[k + 1]
    denom = a - 2 * b + c
    return float(k + (0.5 * (a - c) / denom if denom != 0 else 0.0))


def fiber_width_px(sig: np.ndarray, diameter_px: float) -> tuple[float, int]:
    """(median width in px of the flyaway fibers outside the core, skeleton pixels it rests
    on) of a levelled signal; NaN and 0 without fibers."""
    from skimage.morphology import skeletonize

    h, w = sig.shape
    outside = np.broadcast_to((np.abs(np.arange(h) - (h - 1) / 2) > 0.8 * diameter_px)[:, None],
                              (h, w))
    smooth = ndimage.gaussian_filter(sig, 0.7)
    fibers = ndimage.binary_opening((smooth > 0.25) & outside)
    labels, count = ndimage.label(fibers)
    sizes = ndimage.sum(fibers, labels, range(1, count + 1))
    skeleton = skeletonize(np.isin(labels, 1 + np.flatnonzero(sizes >= MIN_FIBER_PIXELS)))
    if not skeleton.any():
        return float("nan"), 0
    half = (smooth > np.median(smooth[skeleton]) / 2) & outside
    widths = 2 * ndimage.distance_transform_edt(half)[skeleton & half] - 1
    widths = widths[widths > 1]
    return (float(np.median(widths)), len(widths)) if len(widths) else (float("nan"), 0)


def at_pitch(img: np.ndarray, pixel_size_mm: float, pitch_mm: float) -> np.ndarray:
    """A grey image (H, W) at ``pixel_size_mm`` brought to the coarser ``pitch_mm`` by a box
    filter (returned as it is if it is not finer)."""
    if pixel_size_mm >= pitch_mm:
        return img
    f = pixel_size_mm / pitch_mm
    size = (max(1, round(img.shape[1] * f)), max(1, round(img.shape[0] * f)))
    im = Image.fromarray(img.astype(np.float32), mode="F").resize(size, Image.Resampling.BOX)
    return np.asarray(im, dtype=np.float64)


def hair_signal(img: np.ndarray, pixel_size_mm: float, backlit: bool
                ) -> tuple[np.ndarray, float, float, tuple[float, float]]:
    """(the levelled signal at :data:`HAIR_PITCH_MM` or coarser, blurred by one of its
    pixels; that pitch (mm); the core's radius there (px); the axis it was levelled by
    there, :func:`axis_line`) of a grey image (H, W) at ``pixel_size_mm``: what the
    hairiness measures read (module notes)."""
    raw = yarn_signal(at_pitch(img, pixel_size_mm, HAIR_PITCH_MM), backlit)
    line = axis_line(raw)
    sig = ndimage.gaussian_filter(levelled(raw, line), 1.0)
    return sig, max(pixel_size_mm, HAIR_PITCH_MM), core_diameter_px(sig) / 2, line


def fiber_pixels(sig: np.ndarray) -> np.ndarray:
    """The pixels of a :func:`hair_signal` that count as fiber: above :data:`HAIR_SHARE` of
    the core's signal (the row profile's peak)."""
    return sig > HAIR_SHARE * np.median(sig, axis=1).max()


def crossings_per_mm(fiber: np.ndarray, radius_px: float, pitch_mm: float,
                     distances_mm: tuple[float, ...]) -> dict[float, float]:
    """Fibers per mm of yarn crossing the lines at each of ``distances_mm`` beyond the core's
    edge (``radius_px`` from the middle row of a levelled ``fiber`` mask), each line's count
    the mean over its row and the two next to it, both sides averaged; NaN where a line
    leaves the frame on both sides."""
    h, w = fiber.shape
    crossings = np.count_nonzero(fiber[:, 1:] & ~fiber[:, :-1], axis=1) + fiber[:, 0]
    out = {}
    for dist in distances_mm:
        rows = [round((h - 1) / 2 + side * (radius_px + dist / pitch_mm)) + k
                for side in (-1, 1) for k in (-1, 0, 1)]
        rows = [r for r in rows if 0 <= r < h]
        out[dist] = float(np.mean(crossings[rows])) / (w * pitch_mm) if rows else float("nan")
    return out


def hairiness(img: np.ndarray, pixel_size_mm: float, backlit: bool = True
              ) -> dict[float, float]:
    """Fibers per mm of yarn crossing the lines at each of :data:`HAIR_DISTANCES_MM` beyond
    the core's edge (module notes) in a grey image (H, W) at ``pixel_size_mm``; NaN where a
    line leaves the frame on both sides."""
    sig, pitch, radius, _ = hair_signal(img, pixel_size_mm, backlit)
    return crossings_per_mm(fiber_pixels(sig), radius, pitch, HAIR_DISTANCES_MM)


def measure_image(img: np.ndarray, backlit: bool) -> dict[str, float]:
    """Core diameter and ply-stripe period (px) of a grey image (H, W) in [0, 1]."""
    sig = levelled(yarn_signal(img, backlit))
    d = core_diameter_px(sig)
    return {"core_diameter_px": d, "stripe_period_px": stripe_period_px(sig, d)}




#: Length of yarn (mm) over which each diameter of the profile is measured.
DIAMETER_WINDOW_MM = 0.3
#: Distances (mm) beyond the core's edge of the Zweigle-type counts; S3 is the one at 3 mm.
ZWEIGLE_DISTANCES_MM = (0.1, 0.2, 0.5, 1.0, 2.0, 3.0)
S3_DISTANCE_MM = 3.0
#: A window's core edges are sought this many times the whole frame's radius from the axis
#: at most: its bulges are inside, a sleeve of flyaways is not.
REACH = 1.5
#: The harmonics of the ply period among which the twist's slant takes the strongest.
HARMONICS = (1, 2, 3)
#: The twist's slant is read on the rows within this share of the core's diameter of the
#: axis (the middle half of the core).
SLANT_BAND = 0.25
#: A slant (:func:`twist_slant`) weaker than this tells no twist direction.
MIN_SLANT = 0.05
#: Pixels (at the hair pitch) beyond the core's half-contrast edge at which hairs start:
#: the edge's own blur, above the fibers' lower threshold, is not hair.
EDGE_MARGIN_PX = 2
#: Rows beyond the core whose fiber pixels cover less than this share of the yarn's length
#: have sparse hairs: the fibers' width for H is measured there.
SPARSE_COVERAGE = 0.1
#: mm in 100 m: the Zweigle counts' unit length.
MM_PER_100M = 1e5


def diameter_profile_px(sig: np.ndarray, window_px: int, diameter_px: float) -> np.ndarray:
    """The core diameter (px) of every whole ``window_px`` columns of a levelled signal,
    along the yarn: between the outermost crossings of half the whole frame's core signal
    by the window's median row profile (a window's dips between plies are inside the yarn),
    sought within :data:`REACH` times the whole frame's ``diameter_px`` of the axis."""
    h, w = sig.shape
    window_px = max(1, min(window_px, w))
    level = np.median(sig, axis=1).max() / 2
    half = REACH * diameter_px / 2
    reach = slice(max(1, int((h - 1) / 2 - half)), min(h - 1, int((h - 1) / 2 + half) + 1))
    out = []
    for a in range(0, w - window_px + 1, window_px):
        profile = ndimage.uniform_filter1d(np.median(sig[:, a:a + window_px], axis=1), 3)
        rows = reach.start + np.flatnonzero(profile[reach] > level)
        if not len(rows):
            out.append(0.0)
            continue
        top, bottom = rows[0], rows[-1]
        out.append(_crossing(profile, bottom, bottom + 1, level)
                   - _crossing(profile, top - 1, top, level))
    return np.array(out)


def twist_slant(sig: np.ndarray, diameter_px: float, period_px: float) -> float:
    """The slant of the ply stripes in the core band of a levelled signal, in [-1, 1]: > 0
    slanting as Z twist (upper left to lower right along a horizontal yarn), < 0 as S, 0
    without a ply period.  Each row's Fourier coefficient at the ply period ``period_px``
    along the yarn, over the rows within :data:`SLANT_BAND` core diameters of the axis: a
    stripe slanting as Z lies further right in each lower row, so the coefficients' phase
    falls row by row.  Their phases unwrapped from row to row (a projected helix's phase
    moves fastest at the axis and turns more than half a period across the core of a yarn
    of many plies) and a line fitted through them weighted by the rows' amplitude; the
    slant is ``-tanh`` of the phase the line turns over half the band, times how well the
    rows agree with the line.  Of the period and its :data:`HARMONICS` (a period read as a
    multiple of the plies' when they differ), the strongest wave.  Only the plies' period
    counts: the surface fibers, which slant against the plies, and the core's straight
    edges do not."""
    if not (np.isfinite(period_px) and period_px > 2):
        return 0.0
    h, w = sig.shape
    mid, half = (h - 1) // 2, max(2, int(round(SLANT_BAND * diameter_px)))
    band = sig[max(0, mid - half):mid + half + 1]
    band = band - band.mean(axis=1, keepdims=True)
    waves = [np.exp(-2j * np.pi * np.arange(w) * k / period_px) for k in HARMONICS]
    coeff = max((band @ wave for wave in waves), key=lambda c: float(np.sum(np.abs(c) ** 2)))
    weight = np.abs(coeff)
    if weight.sum() <= 0:
        return 0.0
    phase = np.unwrap(np.angle(coeff))
    rows = np.arange(len(coeff)) - (mid - max(0, mid - half))
    centred = rows - np.average(rows, weights=weight)
    slope = float(np.sum(weight * centred * phase) / max(np.sum(weight * centred ** 2), 1e-12))
    offset = np.average(phase - slope * rows, weights=weight)
    agree = abs(np.sum(coeff * np.exp(-1j * (slope * rows + offset)))) / weight.sum()
    return float(-np.tanh(slope * half) * agree)


def skeleton_links(skeleton: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """The links between neighbouring pixels of a one-pixel-wide ``skeleton``: (first
    pixels' flat indices, second pixels', the link's length in px) for the orthogonal links
    (1) and for the diagonal links (sqrt 2) that no two orthogonal links already join."""
    s = np.pad(skeleton, 1)
    idx = np.arange(s.size).reshape(s.shape)
    out = []
    for dy, dx in ((0, 1), (1, 0)):
        both = s[1:-1, 1:-1] & s[1 + dy:s.shape[0] - 1 + dy, 1 + dx:s.shape[1] - 1 + dx]
        out.append((idx[1:-1, 1:-1][both], idx[1 + dy:-1 + dy or None, 1 + dx:-1 + dx or None]
                    [both], 1.0))
    for dx in (1, -1):  # down-right and down-left
        a = s[1:-1, 1:-1]
        b = s[2:, 1 + dx:s.shape[1] - 1 + dx]
        via = s[2:, 1:-1] | s[1:-1, 1 + dx:s.shape[1] - 1 + dx]  # an orthogonal corner
        both = a & b & ~via
        out.append((idx[1:-1, 1:-1][both], idx[2:, 1 + dx:s.shape[1] - 1 + dx][both],
                    math.sqrt(2.0)))
    return out


def beyond_core(shape: tuple[int, int], radius_px: float) -> np.ndarray:
    """(H,) bool: the rows of a levelled image farther than ``radius_px`` and
    :data:`EDGE_MARGIN_PX` from its middle row."""
    return np.abs(np.arange(shape[0]) - (shape[0] - 1) / 2) > radius_px + EDGE_MARGIN_PX


def hair_pieces(fiber: np.ndarray, radius_px: float) -> tuple[np.ndarray, np.ndarray,
                                                              np.ndarray]:
    """(the skeleton of the fiber pixels beyond the core's edges (``radius_px`` from the
    middle row of a levelled ``fiber`` mask), each pixel labelled by its 8-connected piece,
    1 .. K, 0 off it; each piece's length (px); each piece's angle to the axis in degrees)."""
    from skimage.morphology import skeletonize

    skeleton = skeletonize(fiber & beyond_core(fiber.shape, radius_px)[:, None])
    labels, count = ndimage.label(skeleton, structure=np.ones((3, 3)))
    padded = np.pad(labels, 1).ravel()
    lengths = np.zeros(count + 1)
    for first, _, step in skeleton_links(skeleton):
        np.add.at(lengths, padded[first], step)
    angles = np.zeros(count)
    for k, piece in enumerate(ndimage.find_objects(labels)):
        ys, xs = np.nonzero(labels[piece] == k + 1)
        if len(ys) > 1:
            _, vecs = np.linalg.eigh(np.cov(np.stack([xs, ys]).astype(np.float64)))
            vx, vy = vecs[:, -1]
            angles[k] = math.degrees(math.atan2(abs(vy), abs(vx)))
    return labels, lengths[1:], angles


def hair_length_per_length(fiber: np.ndarray, radius_px: float, labels: np.ndarray,
                           lengths: np.ndarray) -> float:
    """Uster's H of a levelled ``fiber`` mask: the fibers' length beyond the core's edges
    per length of yarn, both sides, each row read as a Boolean model (module notes);
    ``labels``, ``lengths``: :func:`hair_pieces` of the mask (its skeleton and the length
    of each piece, px).  0 without fiber beyond the edges."""
    rows = beyond_core(fiber.shape, radius_px)
    out = fiber & rows[:, None]
    cover = out.sum(axis=1) / fiber.shape[1]
    skeleton = labels > 0
    sparse = rows & (cover > 0) & (cover < SPARSE_COVERAGE) & skeleton.any(axis=1)
    if not sparse.any():
        sparse = rows & skeleton.any(axis=1)
    if not sparse.any():
        return 0.0
    per_pixel = lengths.sum() / skeleton.sum()  # skeleton length per skeleton pixel
    width = out[sparse].sum() / (skeleton[sparse].sum() * per_pixel)  # px of mask per px
    return float((-np.log(np.clip(1 - cover[rows], 1e-3, 1)) / width).sum())


@dataclass(frozen=True)
class TextileMeasures:
    """What ``ipm measure`` reports of one photo (mm unless named; module notes).

    length_mm: the yarn in view.  diameter_mm: the half-contrast core diameter;
    diameter_profile_mm: it every :data:`DIAMETER_WINDOW_MM` along the yarn; diameter_cv_pct:
    their CV.  ply_period_mm: the distance between neighbouring plies' crossings
    (``alpha_ply / n``); plies: the ply count given; ply_twist_tpm: turns per metre
    (1000 / (plies * ply_period_mm)), None without ``plies``.  twist_direction: ``"S"``,
    ``"Z"`` or None; twist_slant: its strength.  hairiness_h: Uster's H (mm of fiber beyond
    the core per mm of yarn).  hairs_per_100m: Zweigle-type counts per distance beyond the
    core's edge (those the frame reaches); s3: the count at 3 mm, None if the frame does
    not reach it.  hair_lengths_mm, hair_angles_deg: each piece of fiber beyond the core."""

    pixel_size_mm: float
    backlit: bool
    length_mm: float
    diameter_mm: float
    diameter_cv_pct: float
    ply_period_mm: float
    plies: int | None
    ply_twist_tpm: float | None
    twist_direction: str | None
    twist_slant: float
    hairiness_h: float
    s3: float | None
    hairs_per_100m: dict[str, float] = field(default_factory=dict)
    diameter_profile_mm: list[float] = field(default_factory=list)
    hair_lengths_mm: list[float] = field(default_factory=list)
    hair_angles_deg: list[float] = field(default_factory=list)

    def to_dict(self) -> dict:
        """The measures as JSON-ready values (NaN as None), rounded to what they resolve."""
        def clean(v):
            if isinstance(v, np.generic):
                v = v.item()
            if isinstance(v, float):
                return None if not math.isfinite(v) else round(v, 6)
            if isinstance(v, dict):
                return {k: clean(x) for k, x in v.items()}
            if isinstance(v, list):
                return [clean(x) for x in v]
            return v
        return {k: clean(v) for k, v in asdict(self).items()}

    def brief(self) -> dict:
        """The scalar measures and the Zweigle-type counts (:meth:`to_dict` without the
        profiles and the pieces), with the pieces' count and median length."""
        d = self.to_dict()
        for k in ("diameter_profile_mm", "hair_lengths_mm", "hair_angles_deg"):
            d.pop(k)
        lengths = self.hair_lengths_mm
        d["hair_pieces"] = len(lengths)
        d["hair_length_median_mm"] = round(float(np.median(lengths)), 4) if lengths else None
        return d

    def summary(self) -> list[str]:
        """The measures as a few lines for the terminal."""
        twist = (f"{self.ply_twist_tpm:.0f} turns/m" if self.ply_twist_tpm is not None
                 else "turns/m: give --plies")
        direction = self.twist_direction or "not seen"
        counts = ", ".join(f"{k} mm: {v:.3g}" for k, v in self.hairs_per_100m.items())
        return [f"diameter {self.diameter_mm:.3f} mm, CV {self.diameter_cv_pct:.1f}% "
                f"over {self.length_mm:.2f} mm",
                f"ply crossings every {self.ply_period_mm:.3f} mm; {twist}; direction "
                f"{direction} (slant {self.twist_slant:+.2f})",
                f"hairiness H {self.hairiness_h:.3g}; hairs per 100 m beyond {counts}; "
                f"S3 {'beyond the frame' if self.s3 is None else format(self.s3, '.3g')}",
                f"{len(self.hair_lengths_mm)} hair pieces, median length "
                f"{np.median(self.hair_lengths_mm) if self.hair_lengths_mm else 0:.2f} mm"]


@dataclass(frozen=True)
class Drawing:
    """Where :func:`analyse` found things, in the photo's pixels: the axis (row = slope *
    column + offset), the core's half-width across it, and every skeleton pixel of fiber
    beyond the core with the length (mm) of its piece."""

    slope: float
    offset: float
    radius_px: float
    hair_xy: np.ndarray  # (K, 2) columns, rows
    hair_length_mm: np.ndarray  # (K,)


def measure_photo(img: np.ndarray, pixel_size_mm: float, backlit: bool,
                  plies: int | None = None) -> TextileMeasures:
    """The textile measures (module notes) of a grey image (H, W) in [0, 1] at
    ``pixel_size_mm``; ``plies``, if known, turns the ply period into turns per metre."""
    return analyse(img, pixel_size_mm, backlit, plies)[0]


def analyse(img: np.ndarray, pixel_size_mm: float, backlit: bool, plies: int | None = None
            ) -> tuple[TextileMeasures, Drawing]:
    """:func:`measure_photo`, and where it found the core and the hairs (:class:`Drawing`)."""
    raw = yarn_signal(img, backlit)
    line = axis_line(raw)
    sig = levelled(raw, line)
    d = core_diameter_px(sig)
    window = max(1, round(DIAMETER_WINDOW_MM / pixel_size_mm))
    profile = diameter_profile_px(sig, window, d) * pixel_size_mm
    period = stripe_period_px(sig, d) * pixel_size_mm
    slant = twist_slant(sig, d, period / pixel_size_mm)
    direction = None if abs(slant) < MIN_SLANT else ("Z" if slant > 0 else "S")
    hair, pitch, radius, coarse_line = hair_signal(img, pixel_size_mm, backlit)
    fiber = fiber_pixels(hair)
    labels, lengths, angles = hair_pieces(fiber, radius)
    length_mm = hair.shape[1] * pitch
    counts = {k: v * MM_PER_100M for k, v in
              crossings_per_mm(fiber, radius, pitch, ZWEIGLE_DISTANCES_MM).items()
              if math.isfinite(v)}
    tpm = 1000.0 / (plies * period) if plies and math.isfinite(period) else None
    measures = TextileMeasures(
        pixel_size_mm=pixel_size_mm, backlit=backlit, length_mm=length_mm,
        diameter_mm=d * pixel_size_mm,
        diameter_cv_pct=float(100 * np.std(profile) / np.mean(profile)) if len(profile) > 1
        else float("nan"),
        ply_period_mm=period, plies=plies, ply_twist_tpm=tpm, twist_direction=direction,
        twist_slant=slant, hairiness_h=hair_length_per_length(fiber, radius, labels, lengths),
        s3=counts.get(S3_DISTANCE_MM), hairs_per_100m={f"{k:g}": v for k, v in counts.items()},
        diameter_profile_mm=[float(x) for x in profile],
        hair_lengths_mm=[float(x) for x in lengths * pitch],
        hair_angles_deg=[float(x) for x in angles])
    # back from the levelled coarse grid to the photo's pixels
    rows, cols = np.nonzero(labels)
    h = hair.shape[0]
    unlevelled = rows + coarse_line[0] * cols + coarse_line[1] - (h - 1) / 2
    f = pitch / pixel_size_mm
    drawing = Drawing(line[0], line[1], d / 2,
                      np.stack([(cols + 0.5) * f - 0.5, (unlevelled + 0.5) * f - 0.5], axis=1),
                      (lengths * pitch)[labels[rows, cols] - 1])
    return measures, drawing
