"""The tests' own yarn geometry: right-handed frames and helix measurements built here from
the fiber points alone, so that a geometry test does not reuse the generator's frame code
(or any convention it might share with it).

Angles are measured about an axis by the right-hand rule: ``atan2(b, a)`` in a basis
``(a, b, axis)`` with ``a x b = axis``.
"""

import numpy as np

from ipm.fibers import FiberKind, FiberSet


def core_fibers(fs: FiberSet) -> tuple[np.ndarray, np.ndarray]:
    """(F, V, 3) the core fibers, which come first and share one vertex count, and (F,)
    their plies."""
    core = np.flatnonzero(fs.kind == FiberKind.CORE)
    v = np.diff(fs.offsets)[core[0]]
    points = fs.points[: fs.offsets[len(core)]].reshape(len(core), v, 3).astype(np.float64)
    return points, fs.ply[: len(core)]


def ply_centres(core: np.ndarray, ply: np.ndarray) -> dict[int, np.ndarray]:
    """Centre line (V, 3) of each ply: the mean of its core fibers vertex by vertex."""
    return {int(k): core[ply == k].mean(axis=0) for k in np.unique(ply)}


def turn_rate(a: np.ndarray, b: np.ndarray, z: np.ndarray) -> float:
    """d(angle)/dz in rad/mm of the point (a, b) about the axis of the basis, by a line fit
    to the unwrapped angle: positive is counter-clockwise seen from the axis' tip."""
    return float(np.polyfit(z, np.unwrap(np.arctan2(b, a)), 1)[0])


def helix_about_z(points: np.ndarray) -> tuple[float, float]:
    """(median radius, turn rate about +z in rad/mm) of a centre line (V, 3)."""
    x, y, z = points.T
    return float(np.median(np.hypot(x, y))), turn_rate(x, y, z)


def co_rotating_frame(centre: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Right-handed frame (e_1, e_2, T) along a ply centre line (V, 3): T its unit tangent,
    e_1 the direction away from the yarn axis made orthogonal to T, e_2 = T x e_1."""
    t = np.gradient(centre, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    radial = centre * np.array([1.0, 1.0, 0.0])
    e1 = radial - np.sum(radial * t, axis=1, keepdims=True) * t
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(t, e1)
    assert np.allclose(np.sum(np.cross(e1, e2) * t, axis=1), 1.0)  # right-handed
    return e1, e2, t


def fiber_turn_rates(core: np.ndarray, ply: np.ndarray, squeeze: float, min_radius: float
                     ) -> np.ndarray:
    """Turn rate (rad per mm of the ply's own length, its centre line's arc) of each core
    fiber about its ply's tangent, in the ply's co-rotating frame with the ply's x squeeze
    undone, for fibers at least ``min_radius`` from the ply centre."""
    rates = []
    for k, c in ply_centres(core, ply).items():
        e1, e2, _ = co_rotating_frame(c)
        arc = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(c, axis=0), axis=1))])
        for fiber in core[ply == k]:
            d = fiber - c
            a, b = np.sum(d * e1, -1) / squeeze, np.sum(d * e2, -1)
            if np.median(np.hypot(a, b)) >= min_radius:
                rates.append(turn_rate(a, b, arc))
    return np.array(rates)


def transported_frame(centre: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Right-handed frame (e_1, e_2, T) along any curve (V, 3) with no twist about T:
    e_1 is carried from vertex to vertex by projecting it onto the next normal plane
    (parallel transport to first order), e_2 = T x e_1."""
    t = np.gradient(centre, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    e1 = np.empty_like(centre)
    a = np.array([1.0, 0.0, 0.0]) if abs(t[0, 0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1[0] = a - (a @ t[0]) * t[0]
    e1[0] /= np.linalg.norm(e1[0])
    for i in range(1, len(centre)):
        v = e1[i - 1] - (e1[i - 1] @ t[i]) * t[i]
        e1[i] = v / np.linalg.norm(v)
    return e1, np.cross(t, e1), t


# --- fibers as polylines (any generator's): the reference comparison -------------------------

def polylines(points: np.ndarray, offsets: np.ndarray) -> list[np.ndarray]:
    """Each fiber of a (points, offsets) pair as a (V, 3) float64 array."""
    return [points[offsets[i]:offsets[i + 1]].astype(np.float64)
            for i in range(len(offsets) - 1)]


def on_grid(fiber: np.ndarray, z: np.ndarray) -> np.ndarray:
    """(len(z), 3) the fiber's x and y linearly interpolated at the heights ``z``."""
    order = np.argsort(fiber[:, 2], kind="stable")
    fz = fiber[order, 2]
    return np.column_stack([np.interp(z, fz, fiber[order, 0]),
                            np.interp(z, fz, fiber[order, 1]), z])


def cluster_plies(core: list[np.ndarray], n: int, z: np.ndarray) -> np.ndarray:
    """(F,) ply of each core fiber, told apart by its angle about the axis once the yarn's
    own rotation (the median turn rate of the fibers' angle about z) is taken out."""
    grids = [on_grid(f, z) for f in core]
    angles = [np.unwrap(np.arctan2(g[:, 1], g[:, 0])) for g in grids]
    rate = np.median([np.polyfit(z, a, 1)[0] for a in angles])
    psi = np.array([np.angle(np.mean(np.exp(1j * (a - rate * z)))) for a in angles])
    phase = np.angle(np.mean(np.exp(1j * n * psi))) / n
    return np.round((psi - phase) / (2 * np.pi / n)).astype(int) % n


def yarn_measures(points: np.ndarray, offsets: np.ndarray, is_flyaway: np.ndarray, n: int,
                  squeeze: float, r_x: float) -> dict[str, float]:
    """The measures the reference comparison needs, from fiber polylines alone.

    ply_pitch, fiber_pitch (mm per turn, the fiber's turn about its ply's centre line per mm
    of that centre line's arc), core_p95 (95th-percentile radius of the core fibers' points),
    reach (median over flyaways of the largest distance from the axis minus core_p95),
    beyond (share of flyaway length more than 0.2 mm beyond core_p95), per_10mm (flyaways per
    10 mm of the core's extent along the axis)."""
    fibers = polylines(points, offsets)
    core = [f for f, fly in zip(fibers, is_flyaway, strict=True) if not fly]
    fly = [f for f, fly in zip(fibers, is_flyaway, strict=True) if fly]
    lo = max(f[:, 2].min() for f in core)
    hi = min(f[:, 2].max() for f in core)
    z = np.linspace(lo + 0.5, hi - 0.5, int((hi - lo) / 0.02))
    ply = cluster_plies(core, n, z)
    grids = np.array([on_grid(f, z) for f in core])
    ply_pitches, fiber_pitches = [], []
    for k in range(n):
        centre = grids[ply == k].mean(axis=0)
        ply_pitches.append(2 * np.pi / abs(helix_about_z(centre)[1]))
        e1, e2, _ = co_rotating_frame(centre)
        arc = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(centre, axis=0), axis=1))])
        for g in grids[ply == k]:
            d = g - centre
            a, b = np.sum(d * e1, -1) / squeeze, np.sum(d * e2, -1)
            if np.median(np.hypot(a, b)) >= 0.5 * r_x:
                fiber_pitches.append(2 * np.pi / abs(turn_rate(a, b, arc)))
    radius = np.hypot(*np.concatenate(core)[:, :2].T)
    p95 = float(np.percentile(radius, 95))
    reach = [np.hypot(f[:, 0], f[:, 1]).max() - p95 for f in fly]
    seg_len = np.concatenate([np.linalg.norm(np.diff(f, axis=0), axis=1) for f in fly])
    mid_r = np.concatenate([np.hypot(*(0.5 * (f[1:] + f[:-1]))[:, :2].T) for f in fly])
    extent = max(f[:, 2].max() for f in core) - min(f[:, 2].min() for f in core)
    return {"ply_pitch": float(np.median(ply_pitches)),
            "fiber_pitch": float(np.median(fiber_pitches)), "core_p95": p95,
            "reach": float(np.median(reach)),
            "beyond": float(seg_len[mid_r > p95 + 0.2].sum() / seg_len.sum()),
            "per_10mm": 10 * len(fly) / extent}
