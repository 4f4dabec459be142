"""The hierarchical procedural yarn generator (paper Alg. 1 and Alg. 2), vectorised numpy.

A level twists ``N`` copies of the previous level's template (a set of polylines around the
``z`` axis) into a new template: Alg. 1 ``buildlevel``.  Level 0 is a straight polyline
``v_i = (0, 0, i alpha_f)``; ``fibers -> plies -> yarn`` are the paper's three levels and a
fourth (cabled yarn) is one more :class:`Level`.  Every stochastic step draws from the
``numpy.random.Generator`` passed in, in a fixed order: same parameters + same seed =
bit-identical fibers.

Conventions and deviations (the paper leaves these open):

* Placement (Eq. 2-5): ``p_i = r_i (sin theta_i, cos theta_i) + j_xy (R, R')`` with
  independent ``R, R'`` per component (the paper's ``R (1, 1)^T`` would only jitter along
  the diagonal).  The circle pattern is used for ``N <= 7`` instances, the sunflower disc
  beyond.  Only the fiber level is jittered (``j_xy`` is a fiber parameter, and the paper uses
  "more structure on the ply level").
* Helix (Eq. 6-9): ``theta(z) = 2 pi z / alpha_h + phi_0`` with ``phi_0 = arctan2(p_x, p_y)``
  so that vertex 0 coincides with ``p`` under the ``(sin, cos)`` parametrisation (the paper's
  ``arctan2(p_y, p_x)`` would not).  Migration ``s(z) = 1 + j max(0, R_1) cos(2 R_2 +
  2 pi R_3 z / alpha_h)``: Table 1 makes ``j`` the migration amplitude, which Eq. 8 omits;
  only fibers migrate.  The z jitter ``j_z R_i`` moves each fiber vertex along the axis.
* Local-frame mapping: a template point ``(x, y, z)`` goes to ``c(z) + x e_1(z) + y e_2(z)``
  where ``c`` is the helix centre line, ``e_1`` the radial direction made orthogonal to the
  tangent ``T = c'(z) / |c'(z)|`` and ``e_2 = e_1 x T``: the cross-section stays orthogonal to
  its own centre line and turns with the helix (Eq. 6), so the squeezed (smaller) radius of
  the ellipse always faces the centre.  ``mapping="global"`` is Zhao et al.'s shift
  orthogonal to the global axis (``e_1`` radial, ``e_2`` tangential in the xy plane), kept
  for comparison (paper Fig. 5).
* Flyaways (Alg. 2): the segment length is arc length along the source fiber; a segment that
  cannot be found in 64 rejection rounds is clipped to its fiber.  Loops use
  ``o_i = d sin(i pi / (J - 1)) (v_x, v_y, 0)`` so both end vertices stay put, with
  ``d = |d_mean + d_std R|``.  Eq. 10 writes ``v`` without a vertex index; we read it as one
  radial vector per loop, the segment's middle vertex, so a loop is an arch pulled out of
  the yarn.  (With each vertex's own ``v_i`` the copied helix balloons into a spiral around
  the yarn that, seen from the side, is a sine wave, unlike the loops of real yarns.)
  Hairs are squeezed along the axis about their root by
  ``1 - s / 2`` (the paper gives no formula; ``s = 0`` must leave the hair unsqueezed, Fig. 6
  f) and then rotated about the root so that the root-to-tip chord makes the angle ``beta``
  with the yarn axis, leaning outwards.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ipm.fibers import FiberKind, FiberSet
from ipm.frame import YARN_LENGTH_MM
from ipm.params import YarnParams

Mapping = Literal["local", "global"]

#: Vertices per helix turn of the tighter twist (``H``), and the bounds of the spacing.
VERTICES_PER_TURN = 16
SPACING_BOUNDS_MM = (0.02, 0.1)
CIRCLE_PATTERN_MAX = 7
FLYAWAY_TRIES = 64


@dataclass(frozen=True)
class Level:
    """One hierarchy level: ``count`` copies of the template on helices around ``z``.

    radius: placement radius ``r`` (circle pattern, or the sunflower disc's outer radius).
    pitch: signed helix pitch ``alpha_h`` (mm per turn).  squeeze: ``e``, the factor on the
    template's x axis (ellipse).  jitter: ``j_xy``.  migration: ``j``.  z_jitter: ``j_z``.
    """

    count: int
    radius: float
    pitch: float
    squeeze: float = 1.0
    jitter: float = 0.0
    migration: float = 0.0
    z_jitter: float = 0.0


def levels_of(params: YarnParams) -> list[Level]:
    """The paper's levels for ``params``: fibers in a ply, plies in a yarn, and optionally
    yarns in a cabled yarn."""
    levels = [
        Level(params.m, params.r_x, params.alpha, jitter=params.j_xy, migration=params.j,
              z_jitter=params.j_z),
        Level(params.n, params.R_ply, params.alpha_ply, squeeze=params.r_y / params.r_x),
    ]
    if params.n_yarn > 1:
        levels.append(Level(params.n_yarn, params.R_yarn, params.alpha_yarn))
    return levels


def vertex_spacing(levels: list[Level]) -> float:
    """``alpha_f``: ``VERTICES_PER_TURN`` vertices on a turn of the tightest helix."""
    tightest = min(abs(lv.pitch) for lv in levels)
    return float(np.clip(tightest / VERTICES_PER_TURN, *SPACING_BOUNDS_MM))


def instance_positions(level: Level, rng: np.random.Generator) -> np.ndarray:
    """(N, 2) start positions ``p_i``: circle pattern (Eq. 2) or sunflower disc (Eq. 3-5)."""
    n = level.count
    i = np.arange(n)
    if n <= CIRCLE_PATTERN_MAX:
        theta, r = 2 * np.pi * i / n, np.full(n, level.radius)
    else:
        theta, r = 2 * np.pi * 0.137 * i, level.radius * (i / n) ** 0.3
    p = r[:, None] * np.column_stack([np.sin(theta), np.cos(theta)])
    if level.jitter > 0:
        p += level.jitter * rng.standard_normal((n, 2))
    return p


def twist(template: np.ndarray, level: Level, rng: np.random.Generator,
          mapping: Mapping = "local") -> np.ndarray:
    """Map ``N`` copies of the template points (P, 3) onto helices: (N, P, 3).

    Each copy is squeezed along x by ``level.squeeze``, turned with the helix so its x axis
    points away from the centre, and carried along the helix at the template point's height.
    """
    pos = instance_positions(level, rng)
    n = len(pos)
    r_h = np.hypot(pos[:, 0], pos[:, 1])[:, None]
    phi0 = np.arctan2(pos[:, 0], pos[:, 1])[:, None]
    if level.migration > 0:
        amp, offset, speed = level.migration * np.maximum(0, rng.standard_normal(n)), \
            2 * rng.standard_normal(n), rng.standard_normal(n)
        amp, offset, speed = amp[:, None], offset[:, None], speed[:, None]

    x, y, z = level.squeeze * template[:, 0], template[:, 1], template[:, 2]
    k = 2 * np.pi / level.pitch  # d theta / dz
    theta = k * z[None, :] + phi0
    sin, cos = np.sin(theta), np.cos(theta)
    rad, drad = r_h, 0.0  # (N, 1): without migration the frame is constant per instance
    if level.migration > 0:
        arg = offset + speed * k * z[None, :]
        rad = r_h * (1 + amp * np.cos(arg))
        drad = -r_h * amp * np.sin(arg) * speed * k
    height = np.broadcast_to(z, theta.shape)
    if level.z_jitter > 0:
        height = height + level.z_jitter * rng.standard_normal(theta.shape)
    # Work in the helix's cylindrical basis (u_r, u_t, e_z), u_r = (sin, cos, 0),
    # u_t = (cos, -sin, 0): the centre line is rad u_r + height e_z, its derivative
    # c'(z) = drad u_r + rad k u_t + e_z.  o_r, o_t, o_z: the template offset x e_1 + y e_2.
    if mapping == "global" or not (np.any(x) or np.any(y)):
        o_r, o_t, o_z = x, y, 0.0
    else:
        a, b = drad, rad * k
        inv_n = 1 / np.sqrt(a * a + b * b + 1)
        t_r, t_t, t_z = a * inv_n, b * inv_n, inv_n  # tangent T
        norm1 = 1 / np.sqrt(1 - t_r * t_r)  # e_1 = (u_r - t_r T) / |.|
        e1_r, e1_t, e1_z = (1 - t_r * t_r) * norm1, -t_r * t_t * norm1, -t_r * t_z * norm1
        # e_2 = e_1 x T; the cylindrical basis is left-handed (u_r x u_t = -e_z)
        e2_r = -(e1_t * t_z - e1_z * t_t)
        e2_t = -(e1_z * t_r - e1_r * t_z)
        e2_z = -(e1_r * t_t - e1_t * t_r)
        o_r, o_t, o_z = x * e1_r + y * e2_r, x * e1_t + y * e2_t, x * e1_z + y * e2_z
    radial = rad + o_r
    return np.stack([radial * sin + o_t * cos, radial * cos - o_t * sin, height + o_z], axis=-1)


def raw_yarn(levels: list[Level], rng: np.random.Generator, length: float = YARN_LENGTH_MM,
             mapping: Mapping = "local") -> tuple[np.ndarray, np.ndarray]:
    """Alg. 1: the raw yarn as (F, V, 3) fiber vertices, and (F,) ply index per fiber.

    Every level maps vertex for vertex, so all fibers share the vertex count ``V``.
    """
    spacing = vertex_spacing(levels)
    v = int(math.ceil(length / spacing)) + 1
    z = np.linspace(-length / 2, length / 2, v)
    fibers = np.column_stack([np.zeros(v), np.zeros(v), z])[None]  # (1, V, 3)
    ply = np.zeros(1, dtype=np.int64)
    for depth, level in enumerate(levels):
        f = len(fibers)
        fibers = twist(fibers.reshape(-1, 3), level, rng, mapping).reshape(level.count * f, v, 3)
        # fibers of one ply share the instance index of the ply level; above it, copy k of a
        # template with P plies numbers its plies k P .. k P + P - 1
        inst = np.repeat(np.arange(level.count), f)
        ply = inst * (ply.max() + 1) + np.tile(ply, level.count) if depth else 0 * inst
    return fibers, ply


def _find_segments(cum: np.ndarray, lengths: np.ndarray, rng: np.random.Generator):
    """Rejection sampling of fiber segments of the given arc lengths (Alg. 2, line 9).

    cum: (F, V) arc length along each fiber.  Returns fiber, start and end vertex per
    flyaway (start is the root; end may be below start: the chain was followed backwards).
    """
    f_count, v = cum.shape
    g = len(lengths)
    fib, start, end = (np.zeros(g, dtype=np.int64) for _ in range(3))
    todo = np.arange(g)
    for _ in range(FLYAWAY_TRIES):
        if not len(todo):
            break
        f = rng.integers(f_count, size=len(todo))
        s = rng.integers(v, size=len(todo))
        forward = rng.random(len(todo)) < 0.5
        c = cum[f]
        target = np.where(forward, c[np.arange(len(todo)), s] + lengths[todo],
                          c[np.arange(len(todo)), s] - lengths[todo])
        idx = np.array([np.searchsorted(row, t) for row, t in zip(c, target, strict=True)])
        e = np.where(forward, idx, idx - 1)
        ok = (target <= c[:, -1]) & (target >= 0) & (np.abs(e - s) >= 2)
        fib[todo[ok]], start[todo[ok]], end[todo[ok]] = f[ok], s[ok], e[ok]
        todo = todo[~ok]
    if len(todo):  # longer than any fiber chain we tried: clip to the fiber
        f = rng.integers(f_count, size=len(todo))
        fib[todo], start[todo], end[todo] = f, 0, v - 1
    return fib, start, end


def _rotation_taking(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """3x3 rotation taking unit vector ``a`` to unit vector ``b`` (Rodrigues)."""
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(np.dot(a, b))
    if s < 1e-12:
        return np.eye(3)
    k = axis / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * kx @ kx


def hair(segment: np.ndarray, beta: float, s: float) -> np.ndarray:
    """A hair flyaway from a fiber segment whose first vertex is the root on the yarn."""
    root = segment[0]
    seg = segment - root
    seg[:, 2] *= 1 - s / 2
    chord = seg[-1] / np.linalg.norm(seg[-1])
    radial = np.array([root[0], root[1], 0.0])
    radial /= max(np.linalg.norm(radial), 1e-12)
    if np.linalg.norm(radial) < 0.5:  # root on the axis: any horizontal direction
        radial = np.array([1.0, 0.0, 0.0])
    axis = np.array([0.0, 0.0, 1.0 if chord[2] >= 0 else -1.0])
    target = math.cos(beta) * axis + math.sin(beta) * radial
    return root + seg @ _rotation_taking(chord, target).T


def loop(segment: np.ndarray, d: float) -> np.ndarray:
    """A loop flyaway: half-sine offset ``d sin(i pi / (J - 1)) (v_x, v_y, 0)`` along the
    radial vector ``v`` of the segment's middle vertex (Eq. 10), ends fixed."""
    i = np.arange(len(segment))
    radial = segment[len(segment) // 2, :2]
    out = segment.copy()
    out[:, :2] += d * np.sin(i * np.pi / (len(segment) - 1))[:, None] * radial
    return out


def flyaways(params: YarnParams, fibers: np.ndarray, rng: np.random.Generator):
    """Alg. 2: ``g`` flyaways copied from the raw yarn's fibers.

    Returns a list of (J, 3) polylines, their kinds and their source fibers.
    """
    g = params.g
    is_loop = rng.random(g) < params.p
    noise = rng.standard_normal(g)
    lengths = np.where(is_loop, params.l_loop + 0.01 * noise, params.l_hair + 0.05 * noise)
    step = np.linalg.norm(np.diff(fibers, axis=1), axis=-1)
    cum = np.concatenate([np.zeros((len(fibers), 1)), np.cumsum(step, axis=1)], axis=1)
    lengths = np.maximum(lengths, 2 * step.mean())
    fib, start, end = _find_segments(cum, lengths, rng)
    d = np.abs(params.d_mean + params.d_std * rng.standard_normal(g))
    curves = []
    for k in range(g):
        sl = slice(start[k], end[k] + 1) if end[k] > start[k] else slice(start[k], end[k] - 1
                                                                          if end[k] else None, -1)
        seg = fibers[fib[k], sl]
        curves.append(loop(seg, d[k]) if is_loop[k] else hair(seg, params.beta, params.s))
    kinds = np.where(is_loop, FiberKind.LOOP, FiberKind.HAIR).astype(np.uint8)
    return curves, kinds, fib


def generate(params: YarnParams, seed: int, length: float = YARN_LENGTH_MM,
             mapping: Mapping = "local") -> FiberSet:
    """All fibers of the yarn ``params`` describes, for the given seed.

    >>> from ipm.presets import preset
    >>> fs = generate(preset("golden"), seed=1)
    >>> int((fs.kind == 0).sum()) == 3 * 43
    True
    """
    rng = np.random.default_rng(seed)
    core, core_ply = raw_yarn(levels_of(params), rng, length, mapping)
    curves, kinds, source = flyaways(params, core, rng)
    f, v = core.shape[:2]
    sizes = np.concatenate([np.full(f, v), [len(c) for c in curves]])
    points = np.concatenate([core.reshape(-1, 3), *curves]).astype(np.float32)
    count = len(sizes)
    return FiberSet(
        points=points,
        offsets=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
        radii=np.tile(np.float32([params.t_x, params.t_y]), (count, 1)),
        kind=np.concatenate([np.zeros(f, np.uint8), kinds]),
        ply=np.concatenate([core_ply, core_ply[source]]).astype(np.int16),
    )
