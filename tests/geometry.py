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
    """Turn rate (rad/mm of yarn length) of each core fiber about its ply's tangent, in the
    ply's co-rotating frame with the ply's x squeeze undone, for fibers at least
    ``min_radius`` from the ply centre."""
    rates = []
    for k, c in ply_centres(core, ply).items():
        e1, e2, _ = co_rotating_frame(c)
        for fiber in core[ply == k]:
            d = fiber - c
            a, b = np.sum(d * e1, -1) / squeeze, np.sum(d * e2, -1)
            if np.median(np.hypot(a, b)) >= min_radius:
                rates.append(turn_rate(a, b, c[:, 2]))
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
