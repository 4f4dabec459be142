"""The textile measures of a fitted yarn from its fibers (``ipm fit``'s ``textile`` block):
what a lab would measure on the yarn the fit made, with every fiber known, beside what the
photo shows (:mod:`ipm.textile.image`).

* diameter: the yarn's envelope ``2 (R_ply + max(r_x, r_y))``;
* ply twist: ``1000 / |alpha_ply|`` turns per metre, S where ``alpha_ply > 0`` (the
  generator's placement ``(sin theta, cos theta)`` turns a positive pitch left-handed:
  :mod:`ipm.generator`), Z where it is negative;
* hairiness H: the length of fiber beyond the envelope per mm of yarn, in the camera's
  projection (the generator's z to the right, its x up: what a photo shows, as
  :mod:`ipm.textile.image` measures it) and in 3-D (beyond the envelope's cylinder);
* Zweigle-type counts: the fibers crossing the lines at each distance beyond the envelope
  in the projection, per 100 m, one side (both averaged).

Over the middle of the generated yarn, away from its cut ends (:data:`END_MARGIN_MM`).
"""

from __future__ import annotations

import numpy as np

from ipm.fibers import FiberSet
from ipm.params import YarnParams
from ipm.textile.image import MM_PER_100M, ZWEIGLE_DISTANCES_MM

#: Yarn (mm) left out at each end of the generated fibers (cut fibers, clipped flyaways).
END_MARGIN_MM = 3.0


def envelope_radius(p: YarnParams) -> float:
    """Half the yarn's envelope (mm)."""
    return p.R_ply + max(p.r_x, p.r_y)


def _segments(fs: FiberSet) -> tuple[np.ndarray, np.ndarray]:
    """(starts, ends) (K, 3) of every segment of every fiber, none joining two fibers."""
    pts = fs.points.astype(np.float64)
    keep = np.ones(len(pts) - 1, bool)
    keep[fs.offsets[1:-1] - 1] = False
    return pts[:-1][keep], pts[1:][keep]


def fiber_measures(p: YarnParams, fs: FiberSet) -> dict:
    """The measures (module notes) of the fibers ``fs`` of the yarn ``p``."""
    a, b = _segments(fs)
    half = float(fs.points[:, 2].max() - fs.points[:, 2].min()) / 2 - END_MARGIN_MM
    length = 2 * half
    mid = (np.abs(a[:, 2]) < half) & (np.abs(b[:, 2]) < half)
    a, b = a[mid], b[mid]
    radius = envelope_radius(p)
    out_2d = (np.abs(a[:, 0]) > radius) & (np.abs(b[:, 0]) > radius)
    d = b - a
    h_2d = float(np.hypot(d[out_2d, 2], d[out_2d, 0]).sum() / length)
    ra, rb = np.hypot(a[:, 0], a[:, 1]), np.hypot(b[:, 0], b[:, 1])
    h_3d = float(np.linalg.norm(d[(ra > radius) & (rb > radius)], axis=1).sum() / length)
    counts = {}
    for dist in ZWEIGLE_DISTANCES_MM:
        line = radius + dist
        crossings = sum(int(np.count_nonzero((side * a[:, 0] - line) * (side * b[:, 0] - line)
                                             < 0)) for side in (-1, 1))
        counts[f"{dist:g}"] = round(crossings / 2 / length * MM_PER_100M, 1)
    return {"diameter_mm": round(2 * radius, 5),
            "ply_twist_tpm": round(1000 / abs(p.alpha_ply), 2),
            "twist_direction": "S" if p.alpha_ply > 0 else "Z",
            "hairiness_h": round(h_2d, 4), "hairiness_h_3d": round(h_3d, 4),
            "hairs_per_100m": counts}
