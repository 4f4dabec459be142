"""The textile measures of a fitted yarn from its fibers (``ipm fit``'s ``textile`` block):
what a lab would measure on the yarn the fit made, with every fiber known, beside what the
photo shows (:mod:`ipm.textile.image`).

* diameter: the yarn's shadow width, as an optical tester and :mod:`ipm.textile.image` see
  it: the projection of every fiber (each as wide as its round radius says) drawn at
  :data:`SHADOW_PITCH_MM`, and the width of the run of rows about the axis that fiber
  covers on at least half the yarn's length (:func:`shadow_radius`).  A yarn in a dense
  sleeve of loops casts a wider shadow than its plies' envelope ``2 (R_ply + max(r_x,
  r_y))``, which is given beside it;
* ply twist: ``1000 / |alpha_ply|`` turns per metre, S where ``alpha_ply > 0`` (the
  generator's placement ``(sin theta, cos theta)`` turns a positive pitch left-handed:
  :mod:`ipm.generator`), Z where it is negative;
* hairiness H: the length of fiber beyond the shadow's edges per mm of yarn, in the
  camera's projection (the generator's z to the right, its x up: what a photo shows, as
  :mod:`ipm.textile.image` measures it), and in 3-D beyond the envelope's cylinder;
* Zweigle-type counts: the fibers crossing the lines at each distance beyond the shadow's
  edges in the projection, per 100 m, one side (both averaged).

Over the middle of the generated yarn, away from its cut ends (:data:`END_MARGIN_MM`).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ipm.fibers import FiberSet
from ipm.params import YarnParams
from ipm.textile.image import MM_PER_100M, ZWEIGLE_DISTANCES_MM

#: Yarn (mm) left out at each end of the generated fibers (cut fibers, clipped flyaways).
END_MARGIN_MM = 3.0
#: Pixel (mm) at which the fibers' shadow is drawn, and the segments drawn at once (memory).
SHADOW_PITCH_MM = 0.005
SHADOW_CHUNK = 200_000


def envelope_radius(p: YarnParams) -> float:
    """Half the yarn's envelope (mm)."""
    return p.R_ply + max(p.r_x, p.r_y)


def _segments(fs: FiberSet) -> tuple[np.ndarray, np.ndarray]:
    """(starts, ends) (K, 3) of every segment of every fiber, none joining two fibers."""
    pts = fs.points.astype(np.float64)
    keep = np.ones(len(pts) - 1, bool)
    keep[fs.offsets[1:-1] - 1] = False
    return pts[:-1][keep], pts[1:][keep]


def shadow_coverage(fs: FiberSet, half_length: float, half_height: float) -> np.ndarray:
    """(rows,) the share of the yarn's length that fiber covers in each row of the camera's
    projection (z to the right, x up; row 0 at ``x = -half_height``), over ``|z| <
    half_length``, at :data:`SHADOW_PITCH_MM`: every segment sampled at half a pixel and
    each sample drawn as a disc of its fiber's round radius."""
    rows, cols = round(2 * half_height / SHADOW_PITCH_MM), round(2 * half_length / SHADOW_PITCH_MM)
    pts = fs.points.astype(np.float64)
    keep = np.ones(len(pts) - 1, bool)
    keep[fs.offsets[1:-1] - 1] = False
    radius = np.repeat(fs.round_radii(), np.diff(fs.offsets))[:-1][keep]
    a, b = pts[:-1][keep], pts[1:][keep]
    mask = np.zeros((rows, cols), bool)
    for lo in range(0, len(a), SHADOW_CHUNK):
        sa, sb = a[lo:lo + SHADOW_CHUNK], b[lo:lo + SHADOW_CHUNK]
        steps = np.maximum(1, np.ceil(2 * np.hypot(*(sb - sa)[:, [2, 0]].T)
                                      / SHADOW_PITCH_MM)).astype(np.int64)
        seg = np.repeat(np.arange(len(sa)), steps)
        t = ((np.arange(steps.sum()) - np.repeat(np.cumsum(steps) - steps, steps) + 0.5)
             / steps[seg])
        z = sa[seg, 2] + t * (sb[seg, 2] - sa[seg, 2])
        x = sa[seg, 0] + t * (sb[seg, 0] - sa[seg, 0])
        col = np.floor((z + half_length) / SHADOW_PITCH_MM).astype(np.int64)
        row = np.floor((x + half_height) / SHADOW_PITCH_MM).astype(np.int64)
        inside = (col >= 0) & (col < cols) & (row >= 0) & (row < rows)
        mask[row[inside], col[inside]] = True
    r = max(float(np.median(radius)) / SHADOW_PITCH_MM, 0.5) if len(radius) else 0.5
    k = int(np.ceil(r))
    yy, xx = np.mgrid[-k:k + 1, -k:k + 1]
    return ndimage.binary_dilation(mask, yy ** 2 + xx ** 2 <= r * r).mean(axis=1)


def shadow_radius(coverage: np.ndarray) -> float:
    """Half the width (mm) of the run of rows about the axis (the middle row) of
    :func:`shadow_coverage` that fiber covers on at least half the yarn's length."""
    mid = len(coverage) // 2
    covered = coverage >= 0.5
    if not covered[mid]:
        return 0.0
    top = mid - int(np.argmin(covered[mid::-1])) if not covered[:mid + 1].all() else 0
    bottom = (mid + int(np.argmin(covered[mid:])) if not covered[mid:].all()
              else len(coverage))
    return (bottom - top) * SHADOW_PITCH_MM / 2


def beyond(a: np.ndarray, b: np.ndarray, radius: float) -> float:
    """Projected length (mm) of the segments from ``a`` to ``b`` (K, 3) whose both ends lie
    farther than ``radius`` from the axis in the camera's projection (``|x|``)."""
    out = (np.abs(a[:, 0]) > radius) & (np.abs(b[:, 0]) > radius)
    d = b[out] - a[out]
    return float(np.hypot(d[:, 2], d[:, 0]).sum())


def fiber_measures(p: YarnParams, fs: FiberSet) -> dict:
    """The measures (module notes) of the fibers ``fs`` of the yarn ``p``."""
    a, b = _segments(fs)
    half = float(fs.points[:, 2].max() - fs.points[:, 2].min()) / 2 - END_MARGIN_MM
    length = 2 * half
    mid = (np.abs(a[:, 2]) < half) & (np.abs(b[:, 2]) < half)
    a, b = a[mid], b[mid]
    envelope = envelope_radius(p)
    radius = shadow_radius(shadow_coverage(fs, half, float(np.abs(fs.points[:, 0]).max())
                                           + SHADOW_PITCH_MM))
    h_2d = beyond(a, b, radius) / length
    d = b - a
    ra, rb = np.hypot(a[:, 0], a[:, 1]), np.hypot(b[:, 0], b[:, 1])
    h_3d = float(np.linalg.norm(d[(ra > envelope) & (rb > envelope)], axis=1).sum() / length)
    counts = {}
    for dist in ZWEIGLE_DISTANCES_MM:
        line = radius + dist
        crossings = sum(int(np.count_nonzero((side * a[:, 0] - line) * (side * b[:, 0] - line)
                                             < 0)) for side in (-1, 1))
        counts[f"{dist:g}"] = round(crossings / 2 / length * MM_PER_100M, 1)
    return {"diameter_mm": round(2 * radius, 5), "envelope_mm": round(2 * envelope, 5),
            "ply_twist_tpm": round(1000 / abs(p.alpha_ply), 2),
            "twist_direction": "S" if p.alpha_ply > 0 else "Z",
            "hairiness_h": round(h_2d, 4), "hairiness_h_3d": round(h_3d, 4),
            "hairs_per_100m": counts}
