"""Distribution-level statistics of a yarn's flyaways, independent of where each random
fiber lands: what the paper says matters about flyaways (its section on the ensemble), and
how far they stand out of the yarn (``benchmarks/flyaway_reach.py``).
"""

from __future__ import annotations

import numpy as np

from ipm.fibers import FiberKind, FiberSet

#: The core's radius for the reach: this quantile of its fibers' distances from the axis.
CORE_RADIUS_QUANTILE = 95


def core_radius(fs: FiberSet) -> float:
    """The core's radius (mm): the 95th percentile of the core fibers' vertex distances
    from the yarn axis (z)."""
    core = fs.points[: fs.offsets[int(np.sum(fs.kind == FiberKind.CORE))]].astype(np.float64)
    return float(np.percentile(np.hypot(core[:, 0], core[:, 1]), CORE_RADIUS_QUANTILE))


def flyaway_reach(fs: FiberSet, kind: FiberKind | None = None) -> np.ndarray:
    """How far each flyaway (of one ``kind``, or all) stands out of the yarn (mm): its
    largest distance from the yarn axis minus :func:`core_radius`."""
    idx = np.flatnonzero(fs.kind != FiberKind.CORE if kind is None else fs.kind == kind)
    radius = core_radius(fs)
    return np.array([np.hypot(*fs.fiber(f)[:, :2].astype(np.float64).T).max() - radius
                     for f in idx])


def flyaway_stats(fs: FiberSet) -> dict[str, float]:
    """Counts, mean arc length and mean :func:`flyaway_reach` of the hairs and the loops."""
    stats: dict[str, float] = {}
    for kind in (FiberKind.HAIR, FiberKind.LOOP):
        idx = np.flatnonzero(fs.kind == kind)
        name = kind.name.lower()
        stats[f"{name}_count"] = float(len(idx))
        lengths = [np.linalg.norm(np.diff(fs.fiber(f).astype(np.float64), axis=0), axis=1).sum()
                   for f in idx]
        reach = flyaway_reach(fs, kind)
        stats[f"{name}_length_mean"] = float(np.mean(lengths)) if lengths else 0.0
        stats[f"{name}_reach_mean"] = float(np.mean(reach)) if len(reach) else 0.0
    return stats
