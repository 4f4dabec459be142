"""Measurements on generated fibers: helix fits, ply frames and flyaway statistics.

They check the generator against its parameters (tests) and describe a yarn's flyaways at
the level of distributions (benchmarks), independent of where each random fiber lands.
"""

from __future__ import annotations

import numpy as np

from ipm.fibers import FiberKind, FiberSet


def core_fibers(fs: FiberSet) -> np.ndarray:
    """(F, V, 3) the raw yarn's fibers (every level maps vertex for vertex, so they share V)."""
    core = np.flatnonzero(fs.kind == FiberKind.CORE)
    sizes = np.diff(fs.offsets)[core]
    if not len(core) or np.any(sizes != sizes[0]) or np.any(np.diff(core) != 1) or core[0]:
        raise ValueError("core fibers must come first and share one vertex count")
    return fs.points[: fs.offsets[len(core)]].reshape(len(core), sizes[0], 3).astype(np.float64)


def fit_helix(points: np.ndarray) -> tuple[float, float]:
    """(radius, signed pitch) of a helix ``r (sin theta, cos theta, z)`` around the z axis
    through the points (V, 3): median radius and the slope of the unwrapped angle in z."""
    theta = np.unwrap(np.arctan2(points[:, 0], points[:, 1]))
    slope = np.polyfit(points[:, 2], theta, 1)[0]
    return float(np.median(np.hypot(points[:, 0], points[:, 1]))), float(2 * np.pi / slope)


def ply_centerlines(fs: FiberSet) -> dict[int, np.ndarray]:
    """Centre line (V, 3) of each ply: the mean of its core fibers vertex by vertex."""
    core = core_fibers(fs)
    ply = fs.ply[: len(core)]
    return {int(k): core[ply == k].mean(axis=0) for k in np.unique(ply)}


def ply_frames(center: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Co-rotating frame along a ply centre line (V, 3): tangent T, e_1 (away from the yarn
    axis, orthogonal to T) and e_2 = e_1 x T, each (V, 3)."""
    t = np.gradient(center, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    radial = center * [1.0, 1.0, 0.0]
    e1 = radial - np.sum(radial * t, axis=1, keepdims=True) * t
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return t, e1, np.cross(e1, t)


def fiber_offsets_in_ply(fs: FiberSet, centers: dict[int, np.ndarray] | None = None
                         ) -> dict[int, np.ndarray]:
    """Per ply, the (F_p, V, 3) coordinates of its fibers in the co-rotating frame
    ``(along e_1, along e_2, along T)`` around the ply centre line (by default the one
    :func:`ply_centerlines` estimates; pass exact ones to avoid its small bias)."""
    core = core_fibers(fs)
    ply = fs.ply[: len(core)]
    out = {}
    for k, c in (centers or ply_centerlines(fs)).items():
        t, e1, e2 = ply_frames(c)
        d = core[ply == k] - c
        out[k] = np.stack([np.sum(d * e1, -1), np.sum(d * e2, -1), np.sum(d * t, -1)], -1)
    return out


def fiber_pitches_in_ply(fs: FiberSet, squeeze: float, min_radius: float) -> np.ndarray:
    """Signed pitch of every core fiber around its ply centre, in the ply's co-rotating
    frame (the ply's x squeeze undone), for fibers at least ``min_radius`` from the centre."""
    centers = ply_centerlines(fs)
    pitches = []
    for k, local in fiber_offsets_in_ply(fs).items():
        z = centers[k][:, 2]
        a, b = local[..., 0] / squeeze, local[..., 1]
        for fa, fb in zip(a, b, strict=True):
            if np.median(np.hypot(fa, fb)) >= min_radius:
                pitches.append(fit_helix(np.column_stack([fa, fb, z]))[1])
    return np.array(pitches)


def flyaway_stats(fs: FiberSet) -> dict[str, float]:
    """Distribution-level description of the flyaways: counts, arc lengths, how far they
    reach from the yarn axis and the hair angles."""
    stats: dict[str, float] = {}
    for kind in (FiberKind.HAIR, FiberKind.LOOP):
        idx = np.flatnonzero(fs.kind == kind)
        name = kind.name.lower()
        stats[f"{name}_count"] = float(len(idx))
        lengths, reach = [], []
        for f in idx:
            pts = fs.fiber(f).astype(np.float64)
            lengths.append(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
            reach.append(np.hypot(pts[:, 0], pts[:, 1]).max())
        stats[f"{name}_length_mean"] = float(np.mean(lengths)) if lengths else 0.0
        stats[f"{name}_reach_mean"] = float(np.mean(reach)) if reach else 0.0
    return stats


def hair_angles(fs: FiberSet) -> np.ndarray:
    """Angle between each hair's root-to-tip chord and the yarn axis (radians)."""
    out = []
    for f in np.flatnonzero(fs.kind == FiberKind.HAIR):
        chord = (fs.fiber(f)[-1] - fs.fiber(f)[0]).astype(np.float64)
        out.append(np.arccos(abs(chord[2]) / np.linalg.norm(chord)))
    return np.array(out)
