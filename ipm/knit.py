"""Knitted patches made of a yarn: the centre lines of a stitch pattern, and the yarn's
fibers swept along them.

The centre line is a closed-form model of weft-knitted loops in the spirit of Peirce's
(1947, "Geometrical principles applicable to the design of functional fabrics", Textile
Research Journal 17) plain-knit loop: each stitch is an Omega-shaped loop (a needle loop, or
head, on top of two legs that narrow into a neck, joined to the next stitch by a sinker
loop below), and the loops of one course are drawn through the heads of the course below.
A stitch is 10 control points (:func:`stitch_points`) in units of the yarn diameter ``D``,
joined course by course by a natural cubic spline (C2, so the swept frame turns smoothly):
legs in front (+z, towards the camera) and heads and sinkers behind on the knit face, so
that a leg passes in front of the head below it and a sinker behind the legs below it.
The proportions (wale 5.5 D, course 2.8 D, neck 1.2 D, head 4.2 D, depth +-0.9 D) keep
every two centre lines at least 0.85 D apart in knit and purl, 0.7 D where courses of both
faces meet (garter, rib): real yarn flattens where it crosses (``tests/test_knit.py``).
A purl stitch has its legs behind, and the side a head or sinker passes follows from the
stitch it wraps (:func:`course_centreline`); the patterns set the face per course and
wale: ``knit`` (stockinette, knit face), ``purl`` (its back), ``garter`` (courses
alternate) and ``rib`` (1x1: wales alternate).

The sweep carries the straight yarn of :func:`ipm.generator.generate` along a centre line as
a further hierarchy level would (the yarn's axis becomes the curve): a fiber point
``(x, y, z)`` goes to ``c(z) + x e_1(z) + y e_2(z)``, with ``z`` the arc length along the
centre line, ``T`` its tangent and ``(e_1, e_2, T)`` a right-handed rotation-minimising
frame (double reflection, Wang et al. 2008), so the yarn's own twist is neither added to nor
taken from: its ply pitch along the curve stays ``alpha_ply``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ipm.fibers import FiberSet
from ipm.generator import generate
from ipm.params import YarnParams

Pattern = Literal["knit", "purl", "garter", "rib"]
PATTERNS: tuple[str, ...] = ("knit", "purl", "garter", "rib")

#: Loop proportions in yarn diameters (see the module notes).
WALE, COURSE, NECK, HEAD, DEPTH = 5.5, 2.8, 1.2, 4.2, 0.9
#: Centre-line samples per yarn diameter of arc length before the sweep.
SAMPLES_PER_D = 20


def arc_length(curve: np.ndarray) -> np.ndarray:
    """(N,) cumulative arc length (mm) along a polyline (N, 3), from 0."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(curve, axis=0), axis=1))])


def yarn_diameter(params: YarnParams) -> float:
    """``D`` (mm): the plies' envelope, ``2 (R_ply + max(r_x, r_y))``."""
    return 2 * (params.R_ply + max(params.r_x, params.r_y))


def stitch_points(leg: float, head: float, sinker: float) -> np.ndarray:
    """(10, 3) control points of one stitch in yarn diameters, from the sinker bottom at the
    stitch's left edge (x = 0) to just before the next stitch's (x = WALE).  The signs say
    which side (+1 front, -1 back) the legs, the head and the sinker at the left edge pass."""
    xc, n, h, d, c = WALE / 2, NECK / 2, HEAD / 2, DEPTH, COURSE
    left = [(0.0, 0.0, sinker * d), (xc - n - 0.12 * WALE, 0.32 * c, 0.0),
            (xc - n, 0.75 * c, leg * d), (xc - h, 1.35 * c, 0.6 * leg * d),
            (xc - h + 0.05 * WALE, 1.75 * c, 0.6 * head * d)]
    top = [(xc, 1.95 * c, head * d)]
    right = [(WALE - x, y, z) for x, y, z in left[1:][::-1]]
    return np.array(left + top + right)


def faces(pattern: Pattern, wales: int, courses: int) -> np.ndarray:
    """(courses, wales) of +1 (knit stitch) or -1 (purl stitch) as seen from the front."""
    if pattern not in PATTERNS:
        from ipm.errors import UserError

        raise UserError(f"unknown pattern {pattern!r}; choose one of: {', '.join(PATTERNS)}")
    r, w = np.mgrid[0:courses, 0:wales]
    return {"knit": np.ones_like(r), "purl": -np.ones_like(r),
            "garter": np.where(r % 2, -1, 1), "rib": np.where(w % 2, -1, 1)}[pattern]


def course_centreline(face: np.ndarray, row: int, diameter: float) -> np.ndarray:
    """(N, 3) the centre line (mm) of course ``row`` of a (courses, wales) ``face`` array.

    A stitch's legs pass on its own side, its head behind the legs of the stitch above it
    (in front of them when that one is a purl stitch) and its sinker on the side away from
    the legs of the stitch below, which is what draws a loop through the one below."""
    from scipy.interpolate import CubicSpline

    own = face[row].astype(np.float64)
    above = face[row + 1] if row + 1 < len(face) else own
    below = face[row - 1] if row > 0 else own
    sinker = -below
    edge = np.concatenate([[sinker[0]], (sinker[:-1] + sinker[1:]) / 2, [sinker[-1]]])
    pts = [stitch_points(own[k], -above[k], edge[k]) + [k * WALE, 0.0, 0.0]
           for k in range(len(own))]
    end = np.array([[len(own) * WALE, 0.0, edge[-1] * DEPTH]])
    ctrl = np.concatenate([*pts, end]) + [0.0, row * COURSE, 0.0]
    s = np.arange(len(ctrl), dtype=np.float64)
    spline = CubicSpline(s, ctrl, bc_type="natural")
    fine = spline(np.linspace(0, s[-1], 64 * len(ctrl)))
    arc = arc_length(fine)
    samples = np.interp(np.linspace(0, arc[-1], int(arc[-1] * SAMPLES_PER_D) + 1), arc,
                        np.linspace(0, s[-1], len(fine)))
    return spline(samples) * diameter


def rotation_minimising_frames(curve: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(e_1, e_2, T), each (N, 3), along a polyline: T its unit tangent, e_1 carried from the
    start by double reflection (Wang et al. 2008, no twist about T), e_2 = T x e_1."""
    t = np.gradient(curve, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    e1 = np.empty_like(curve)
    start = np.cross(t[0], [0.0, 0.0, 1.0])
    if np.linalg.norm(start) < 1e-6:
        start = np.cross(t[0], [0.0, 1.0, 0.0])
    e1[0] = start / np.linalg.norm(start)
    for i in range(len(curve) - 1):
        v1 = curve[i + 1] - curve[i]
        c1 = v1 @ v1
        r_l = e1[i] - (2 / c1) * (v1 @ e1[i]) * v1
        t_l = t[i] - (2 / c1) * (v1 @ t[i]) * v1
        v2 = t[i + 1] - t_l
        c2 = v2 @ v2
        e1[i + 1] = r_l - (2 / c2) * (v2 @ r_l) * v2 if c2 > 1e-18 else r_l
    e1 -= np.sum(e1 * t, axis=1, keepdims=True) * t
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(t, e1), t


def sweep(fibers: FiberSet, curve: np.ndarray) -> FiberSet:
    """The fibers of a straight yarn (axis z, centred on 0) carried along ``curve``: a
    point's z is its arc length from the curve's middle (see the module notes)."""
    e1, e2, t = rotation_minimising_frames(curve)
    arc = arc_length(curve)
    p = fibers.points.astype(np.float64)
    s = np.clip(p[:, 2] + arc[-1] / 2, 0.0, arc[-1])
    k = np.clip(np.searchsorted(arc, s) - 1, 0, len(arc) - 2)
    u = ((s - arc[k]) / np.maximum(arc[k + 1] - arc[k], 1e-12))[:, None]

    def at(a: np.ndarray) -> np.ndarray:
        return (1 - u) * a[k] + u * a[k + 1]

    moved = at(curve) + p[:, :1] * at(e1) + p[:, 1:2] * at(e2)
    return FiberSet(points=moved.astype(np.float32), offsets=fibers.offsets, radii=fibers.radii,
                    kind=fibers.kind, ply=fibers.ply)


@dataclass(frozen=True)
class Patch:
    """A knitted patch: its fibers (mm, the fabric in the xy plane, the knit face towards
    +z) and the centre lines they follow."""

    fibers: FiberSet
    centrelines: list[np.ndarray]
    diameter: float


def knit_patch(params: YarnParams, pattern: Pattern = "knit", wales: int = 8,
               courses: int = 6, seed: int = 0, extra_bytes_per_vertex: int = 0) -> Patch:
    """The yarn ``params`` knitted into ``wales`` x ``courses`` stitches of ``pattern``,
    each course a yarn of its own (fiber seed ``seed`` + course), centred on the origin.

    A patch whose fibers would not fit in memory is refused before any fiber is made
    (:func:`check_patch_memory`; ``extra_bytes_per_vertex``: what the caller needs per
    vertex on top, e.g. a renderer's buffers).  Courses are made one at a time and gathered
    into one array, each released as it is copied, so the peak is about the patch itself
    plus one course's work."""
    d = yarn_diameter(params)
    face = faces(pattern, wales, courses)
    lines = [course_centreline(face, r, d) for r in range(courses)]
    check_patch_memory(params, lines, f"{pattern} {wales}x{courses}", extra_bytes_per_vertex)
    centre = np.concatenate(lines).mean(axis=0) * [1.0, 1.0, 0.0]
    lines = [c - centre for c in lines]
    parts = []
    for r, line in enumerate(lines):
        part = sweep(generate(params, seed + r, length=float(arc_length(line)[-1])), line)
        parts.append(part)
    return Patch(fibers=concatenate(parts, release=True), centrelines=lines, diameter=d)


#: Bytes per fiber vertex: kept in the patch (float32 x, y, z), and the generator's and the
#: sweep's float64 work arrays for the course being made (a dozen (F, V) arrays at the
#: plies' level of :func:`ipm.generator.twist`, the fibers, their arc lengths, the frames).
PATCH_BYTES_PER_VERTEX = 12
COURSE_BYTES_PER_VERTEX = 160


def estimated_vertices(params: YarnParams, length: float) -> int:
    """About how many vertices :func:`ipm.generator.generate` makes for ``length`` mm of
    the yarn: every core fiber at the generator's vertex spacing, and each flyaway's
    length at that spacing (an upper estimate: a fiber's step is at least the spacing)."""
    from ipm.generator import (
        LONG_HAIR_FACTOR,
        LONG_LOOP_FACTOR,
        LONG_SHARE,
        flyaway_count,
        levels_of,
        vertex_spacing,
    )

    levels = levels_of(params)
    spacing = vertex_spacing(levels)
    fibers = int(np.prod([lv.count for lv in levels]))
    core = fibers * (int(np.ceil(length / spacing)) + 1)
    loop = params.l_loop * (1 + LONG_SHARE * (LONG_LOOP_FACTOR - 1))
    hair = params.l_hair * (1 + LONG_SHARE * (LONG_HAIR_FACTOR - 1))
    mean = params.p * loop + (1 - params.p) * hair
    return core + int(flyaway_count(params.g, length) * (mean / spacing + 2))


def available_memory() -> int:
    """Bytes this process may still take: the system's available memory (``MemAvailable``),
    or less under an address-space limit (``ulimit -v``)."""
    import resource

    avail = None
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    avail = int(line.split()[1]) * 1024
    except OSError:
        pass
    if avail is None:
        avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    soft = resource.getrlimit(resource.RLIMIT_AS)[0]
    return avail if soft == resource.RLIM_INFINITY else min(avail, soft)


def check_patch_memory(params: YarnParams, lines: list[np.ndarray], what: str,
                       extra_bytes_per_vertex: int = 0) -> None:
    """Refuse, in one line and before any fiber is made, a patch whose fibers would need
    more memory than :func:`available_memory`."""
    per_course = [estimated_vertices(params, float(arc_length(c)[-1])) for c in lines]
    total = sum(per_course)
    need = (total * (PATCH_BYTES_PER_VERTEX + extra_bytes_per_vertex)
            + max(per_course) * COURSE_BYTES_PER_VERTEX)
    limit = available_memory()
    if need > limit:
        from ipm.errors import UserError

        raise UserError(f"a {what} patch of this yarn would have about {total / 1e6:,.0f} "
                        f"million fiber vertices and need about {need / 1e9:.1f} GB; "
                        f"{limit / 1e9:.1f} GB of memory is available: use fewer "
                        "--stitches (or a yarn with fewer fibers)")


def concatenate(parts: list[FiberSet], release: bool = False) -> FiberSet:
    """One fiber set of several (offsets shifted, fibers in order).  ``release``: empty
    ``parts`` while copying, so that each part's points are freed once copied and the
    peak stays near the result's size (not twice it)."""
    sizes = np.concatenate([np.diff(p.offsets) for p in parts])
    radii = np.concatenate([p.radii for p in parts])
    kind = np.concatenate([p.kind for p in parts])
    ply = np.concatenate([p.ply for p in parts])
    points = np.empty((int(sizes.sum()), 3), dtype=np.float32)  # pages taken as written
    at = 0
    for i in range(len(parts)):
        part = parts[i]
        points[at:at + len(part.points)] = part.points
        at += len(part.points)
        if release:
            parts[i] = None
        del part
    if release:
        parts.clear()
    return FiberSet(points=points, offsets=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                    radii=radii, kind=kind, ply=ply)
