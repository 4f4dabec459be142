"""The hierarchical procedural yarn generator (paper Alg. 1 and Alg. 2), vectorised numpy.

A level twists ``N`` copies of the previous level's template (a set of polylines around the
``z`` axis) into a new template: Alg. 1 ``buildlevel``.  Level 0 is a straight polyline
``v_i = (0, 0, i alpha_f)``; ``fibers -> plies -> yarn`` are the paper's three levels and a
fourth (cabled yarn) is one more :class:`Level`.  Every stochastic step draws from the
``numpy.random.Generator`` passed in, in a fixed order: same parameters + same seed =
bit-identical fibers.

Conventions and deviations (the paper leaves these open; where the paper authors' public
Blender script settles a point, we follow it so that a parameter means what it means there):

* Placement (Eq. 2-5): ``p_i = r_i (sin theta_i, cos theta_i) + j_xy (R, R')`` with
  independent ``R, R'`` per component (the paper's ``R (1, 1)^T`` would only jitter along
  the diagonal).  The circle pattern (``i = 0 .. N-1``) is used for ``N <= 7`` instances,
  the sunflower disc beyond, with ``i = 1 .. N`` as in the authors' script (``r_i > 0``, the
  outermost instance on the rim).  Only the fiber level is jittered (``j_xy`` is a fiber
  parameter, and the paper uses "more structure on the ply level").
* Helix (Eq. 6-9): ``theta(z) = 2 pi z / alpha_h + phi_0`` with ``phi_0 = arctan2(p_x, p_y)``
  so that vertex 0 coincides with ``p`` under the ``(sin, cos)`` parametrisation.  A level
  above the fibers carries its template along the helix by arc length (the authors' script
  bends each bundle with Blender's curve modifier): a fiber turns once per ``|alpha|`` mm of
  its ply's own length, not of the yarn axis, which is ``sqrt(1 + (2 pi R_ply /
  alpha_ply)^2)`` times shorter.  Migration
  as in the authors' script: the helix radius is scaled by ``1 + A cos(phi_m + v z)`` with
  ``A = max(0, j R)``, ``phi_m ~ U(0, 2 pi)`` and ``v ~ U(0, 2)`` rad/mm drawn once per
  fiber (Eq. 8 omits ``j``; Table 1 makes it the migration amplitude); only fibers migrate.
  The z jitter moves each fiber vertex along the axis by ``U(-1/2, 1/2) |alpha| j_z``, so
  ``j_z`` is a fraction of the fiber pitch, as in the script.
* Handedness: a template point ``(x, y, z)`` goes to ``c(z) + x e_1(z) + y e_2(z)`` where
  ``c`` is the helix centre line, ``T = c'/|c'|``, ``e_1`` the radial direction made
  orthogonal to ``T`` and ``e_2 = T x e_1``: ``(e_1, e_2, T)`` is right-handed like the
  template's ``(x, y, z)``, so a level's twist keeps its sense when the template is carried
  along the next level's helix.  A fiber of pitch ``alpha`` < 0 therefore turns about its ply
  against a ply of pitch ``alpha_ply`` > 0 (the paper: opposite signs, opposite directions,
  as in plied knitting yarns, S on Z).  With the ``(sin, cos)`` placement a positive pitch
  turns left-handed: ``alpha_ply > 0`` plies S, ``alpha < 0`` twists the fibers Z, the
  common knitting yarn of Z singles plied S.  The cross-section stays orthogonal to its own centre
  line and turns with the helix (Eq. 6), so the squeezed (smaller) radius of the ellipse
  always faces the centre.  ``mapping="global"`` is Zhao et al.'s shift orthogonal to the
  global axis (``e_1`` radial, ``e_2 = e_z x e_1`` in the xy plane), kept for comparison
  (paper Fig. 5).
* Flyaways (Alg. 2), as in the authors' script.  Their number is ``0.88 g`` per 10 mm of
  ply: the script tries ``int(4 g)`` strips along its 40 mm fiber template and drops each
  that runs past a fiber's end (the share kept is measured on the reference fibers);
  ipm makes the kept ones, so ``g`` means the same density whatever the length generated.
  A segment is found by arc length along a source fiber (rejection sampling; one that
  cannot be found in 64 rounds is clipped to its fiber), its first vertex the root.
  Loops: length ``l_loop + 0.01 R``; the segment's x is halved about its root, then its
  ``J`` inner vertices are pushed along the unit radial direction ``u`` of its last vertex by
  ``0.1 d sin(i pi / J) u``, ``i = 0 .. J - 1`` (``d`` in units of 0.1 mm, both ends stay
  on the yarn); ``d = d_mean + |d_std R|``.  4 % are long loops: ``2 l_loop`` long with
  ``d = |2 d_mean + d_std R|`` (the script's ``N(2 d_mean, d_std)``; the absolute value keeps
  the rare negative draw from pushing a loop through the yarn).
  Hairs: length ``l_hair + 0.05 R`` (4 % are ``3 l_hair`` long); the segment is squeezed
  along the axis about its root by ``1 / (1 + 1.5 s)``, mirrored in x about its root, and
  every vertex after the root turned by ``beta`` about the unit radial direction of the
  segment's far end, through the vertex after the root (turning about the root's own radial
  direction instead stands hairs far further out than the script's).
* Measured against the authors' fibers for four presets (``tests/test_reference_fibers.py``,
  [the report](../benchmarks/results/reference_fibers.md)).
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
#: Flyaways per mm of ply and unit of ``g``: the authors' script tries ``4 g`` strips on a
#: 40 mm fiber template and drops each that runs past a fiber's end, so ``0.1 g`` per mm
#: less the dropped share (measured on the reference fibers, benchmarks/results/).
FLYAWAYS_PER_MM_AND_G = 0.1 * 0.88
#: Unit of the loop amplitude ``d`` in mm, and the share and scale of long loops and hairs.
LOOP_D_UNIT_MM = 0.1
LONG_SHARE = 0.04
LONG_LOOP_FACTOR = 2.0
LONG_HAIR_FACTOR = 3.0


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
        theta, r = 2 * np.pi * 0.137 * (i + 1), level.radius * ((i + 1) / n) ** 0.3
    p = r[:, None] * np.column_stack([np.sin(theta), np.cos(theta)])
    if level.jitter > 0:
        p += level.jitter * rng.standard_normal((n, 2))
    return p


def arc_stretch(level: Level) -> float:
    """Length of a turn of the level's helix centre line over its pitch: the template's ``z``
    is arc length along that centre line, so it spans this many times the yarn axis."""
    return math.sqrt(1 + (2 * math.pi * level.radius / level.pitch) ** 2)


def twist(template: np.ndarray, level: Level, rng: np.random.Generator,
          mapping: Mapping = "local", along_arc: bool = False) -> np.ndarray:
    """Map ``N`` copies of the template points (P, 3) onto helices: (N, P, 3).

    Each copy is squeezed along x by ``level.squeeze``, turned with the helix so its x axis
    points away from the centre, and carried along the helix.  ``along_arc``: the template's
    ``z`` is arc length along the helix centre line (a bundle carried along the helix, as
    Blender's curve modifier does in the authors' script), else height on the axis.
    """
    pos = instance_positions(level, rng)
    n = len(pos)
    r_h = np.hypot(pos[:, 0], pos[:, 1])[:, None]
    phi0 = np.arctan2(pos[:, 0], pos[:, 1])[:, None]
    if level.migration > 0:  # per instance: amplitude A, phase phi_m, speed v (rad/mm)
        amp = np.maximum(0, level.migration * rng.standard_normal(n))[:, None]
        phase = rng.uniform(0, 2 * np.pi, n)[:, None]
        speed = rng.uniform(0, 2, n)[:, None]

    x, y, z = level.squeeze * template[:, 0], template[:, 1], template[:, 2]
    if along_arc:
        z = z / arc_stretch(level)
    k = 2 * np.pi / level.pitch  # d theta / dz
    theta = k * z[None, :] + phi0
    sin, cos = np.sin(theta), np.cos(theta)
    rad, drad = r_h, 0.0  # (N, 1): without migration the frame is constant per instance
    if level.migration > 0:
        arg = phase + speed * z[None, :]
        rad = r_h * (1 + amp * np.cos(arg))
        drad = -r_h * amp * np.sin(arg) * speed
    height = np.broadcast_to(z, theta.shape)
    if level.z_jitter > 0:
        height = height + level.z_jitter * abs(level.pitch) * rng.uniform(-0.5, 0.5, theta.shape)
    # Work in the helix's cylindrical basis (u_r, u_t, e_z), u_r = (sin, cos, 0),
    # u_t = (cos, -sin, 0): the centre line is rad u_r + height e_z, its derivative
    # c'(z) = drad u_r + rad k u_t + e_z.  o_r, o_t, o_z: the template offset x e_1 + y e_2.
    # The basis is left-handed (u_r x u_t = -e_z): the right-handed e_2 has o_t = -y.
    if mapping == "global" or not (np.any(x) or np.any(y)):
        o_r, o_t, o_z = x, -y, 0.0
    else:
        a, b = drad, rad * k
        inv_n = 1 / np.sqrt(a * a + b * b + 1)
        t_r, t_t, t_z = a * inv_n, b * inv_n, inv_n  # tangent T
        norm1 = 1 / np.sqrt(1 - t_r * t_r)  # e_1 = (u_r - t_r T) / |.|
        e1_r, e1_t, e1_z = (1 - t_r * t_r) * norm1, -t_r * t_t * norm1, -t_r * t_z * norm1
        # e_2 = T x e_1, which in the left-handed basis has the components of e_1 x T
        e2_r = e1_t * t_z - e1_z * t_t
        e2_t = e1_z * t_r - e1_r * t_z
        e2_z = e1_r * t_t - e1_t * t_r
        o_r, o_t, o_z = x * e1_r + y * e2_r, x * e1_t + y * e2_t, x * e1_z + y * e2_z
    radial = rad + o_r
    return np.stack([radial * sin + o_t * cos, radial * cos - o_t * sin, height + o_z], axis=-1)


def raw_yarn(levels: list[Level], rng: np.random.Generator, length: float = YARN_LENGTH_MM,
             mapping: Mapping = "local") -> tuple[np.ndarray, np.ndarray]:
    """Alg. 1: the raw yarn as (F, V, 3) fiber vertices, and (F,) ply index per fiber.

    Every level maps vertex for vertex, so all fibers share the vertex count ``V``.  Above the
    fibers a level's template ``z`` is arc length along its helix (a fiber turns once per
    ``|alpha|`` mm of its ply, as in the authors' generator), so the fiber template is made
    long enough that the finished yarn spans ``length`` mm of the axis.
    """
    spacing = vertex_spacing(levels)
    span = length * math.prod(arc_stretch(level) for level in levels[1:])
    v = int(math.ceil(span / spacing)) + 1
    z = np.linspace(-span / 2, span / 2, v)
    fibers = np.column_stack([np.zeros(v), np.zeros(v), z])[None]  # (1, V, 3)
    ply = np.zeros(1, dtype=np.int64)
    for depth, level in enumerate(levels):
        f = len(fibers)
        fibers = twist(fibers.reshape(-1, 3), level, rng, mapping,
                       along_arc=depth > 0).reshape(level.count * f, v, 3)
        # fibers of one ply share the instance index of the ply level; above it, copy k of a
        # template with P plies numbers its plies k P .. k P + P - 1
        inst = np.repeat(np.arange(level.count), f)
        ply = inst * (ply.max() + 1) + np.tile(ply, level.count) if depth else 0 * inst
    return fibers, ply


def _find_segments(cum: np.ndarray, lengths: np.ndarray, rng: np.random.Generator):
    """Rejection sampling of fiber segments of the given arc lengths (Alg. 2, line 9).

    cum: (F, V) arc length along each fiber.  Returns fiber, start and end vertex per
    flyaway (start is the root; end may be below start: the chain was followed backwards).
    Each search reads its fiber's row in place (no copy per flyaway), so memory stays
    linear in the yarn's length.
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
        at_s = cum[f, s]
        target = np.where(forward, at_s + lengths[todo], at_s - lengths[todo])
        idx = np.array([np.searchsorted(cum[fi], t) for fi, t in zip(f, target, strict=True)],
                       dtype=np.int64)
        e = np.where(forward, idx, idx - 1)
        ok = (target <= cum[f, -1]) & (target >= 0) & (np.abs(e - s) >= 2)
        fib[todo[ok]], start[todo[ok]], end[todo[ok]] = f[ok], s[ok], e[ok]
        todo = todo[~ok]
    if len(todo):  # longer than any fiber chain we tried: clip to the fiber
        f = rng.integers(f_count, size=len(todo))
        fib[todo], start[todo], end[todo] = f, 0, v - 1
    return fib, start, end


def _rotations_about(axes: np.ndarray, angle: float) -> np.ndarray:
    """(K, 3, 3) rotations by ``angle`` about the unit vectors ``axes`` (K, 3) (right-hand
    rule, Rodrigues)."""
    kx = np.zeros((len(axes), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -axes[:, 2], axes[:, 1], -axes[:, 0]
    kx -= kx.transpose(0, 2, 1)
    return np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx


def _unit_radials(points: np.ndarray) -> np.ndarray:
    """(K, 3) unit directions from the yarn axis to ``points`` (K, 3) in the xy plane (x on
    the axis)."""
    radial = points * np.array([1.0, 1.0, 0.0])
    norm = np.linalg.norm(radial, axis=1, keepdims=True)
    return np.where(norm > 1e-12, radial / np.maximum(norm, 1e-12), [1.0, 0.0, 0.0])


def _segments(points: np.ndarray, sizes: np.ndarray):
    """Per vertex of segments laid end to end: its segment and its index in it; per segment
    the offset of its first vertex."""
    first = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    owner = np.repeat(np.arange(len(sizes)), sizes)
    return owner, np.arange(len(points)) - first[owner], first


def hairs(points: np.ndarray, sizes: np.ndarray, beta: float, s: float) -> np.ndarray:
    """Hair flyaways from fiber segments laid end to end in ``points`` (``sizes`` vertices
    each, at least two), each starting at its root on the yarn: squeezed along the axis by
    ``1 / (1 + 1.5 s)`` and mirrored in x, both about the root, then every vertex after the
    root turned by ``beta`` about the unit radial direction of the segment's far end, through
    the vertex after the root (the authors' script)."""
    owner, index, first = _segments(points, sizes)
    root = points[first][owner]
    out = points - root
    out[:, 2] /= 1 + 1.5 * s
    out[:, 0] *= -1
    out += root
    pivot = out[first + 1][owner]
    turn = _rotations_about(_unit_radials(points[first + sizes - 1]), beta)[owner]
    moved = pivot + np.einsum("kij,kj->ki", turn, out - pivot)
    return np.where((index >= 1)[:, None], moved, out)


def loops(points: np.ndarray, sizes: np.ndarray, d_mm: np.ndarray) -> np.ndarray:
    """Loop flyaways from segments laid end to end: each segment's x halved about its first
    vertex, then the arch ``d_mm sin(i pi / J) u`` added to its ``J`` inner vertices
    (``i = 0 .. J - 1``) along the unit radial direction ``u`` of its last vertex (Eq. 10 as
    the authors' script makes it; ``d_mm`` (K,) the arch heights in mm); both ends stay."""
    owner, index, first = _segments(points, sizes)
    out = points.copy()
    out[:, 0] = out[first, 0][owner] + 0.5 * (out[:, 0] - out[first, 0][owner])
    inner = np.maximum(sizes - 2, 1)[owner]
    arch = np.where((index >= 1) & (index <= sizes[owner] - 2),
                    np.sin((index - 1) * np.pi / inner), 0.0)
    return out + (d_mm[owner] * arch)[:, None] * _unit_radials(points[first + sizes - 1])[owner]


def hair(segment: np.ndarray, beta: float, s: float) -> np.ndarray:
    """One hair flyaway (:func:`hairs`) from a (J, 3) segment whose first vertex is the root."""
    return hairs(segment, np.array([len(segment)]), beta, s)


def loop(segment: np.ndarray, d_mm: float) -> np.ndarray:
    """One loop flyaway (:func:`loops`) of arch height ``d_mm`` from a (J, 3) segment."""
    return loops(segment, np.array([len(segment)]), np.array([d_mm]))


def flyaway_count(g: int, ply_length: float) -> int:
    """Number of flyaways on ``ply_length`` mm of ply: ``g`` per 10 mm less the strips the
    authors' script drops (see the module notes)."""
    return int(round(g * FLYAWAYS_PER_MM_AND_G * ply_length))


def flyaways(params: YarnParams, fibers: np.ndarray, rng: np.random.Generator,
             length: float = YARN_LENGTH_MM):
    """Alg. 2: flyaways copied from the raw yarn's fibers (see the module notes).

    Returns their polylines laid end to end (P, 3), the vertices of each, their kinds and
    their source fibers.
    """
    count = flyaway_count(params.g, length * arc_stretch(levels_of(params)[1]))
    is_loop = rng.random(count) < params.p
    is_long = rng.random(count) < LONG_SHARE
    noise = rng.standard_normal(count)
    lengths = np.where(is_loop,
                       params.l_loop * np.where(is_long, LONG_LOOP_FACTOR, 1) + 0.01 * noise,
                       params.l_hair * np.where(is_long, LONG_HAIR_FACTOR, 1) + 0.05 * noise)
    step = np.linalg.norm(np.diff(fibers, axis=1), axis=-1)
    cum = np.concatenate([np.zeros((len(fibers), 1)), np.cumsum(step, axis=1)], axis=1)
    lengths = np.maximum(lengths, 2 * step.mean())
    fib, start, end = _find_segments(cum, lengths, rng)
    spread = params.d_std * rng.standard_normal(count)
    d = np.where(is_long, np.abs(LONG_LOOP_FACTOR * params.d_mean + spread),
                 params.d_mean + np.abs(spread))
    forward = end >= start
    sizes = np.abs(end - start) + 1
    owner, index, _ = _segments(np.empty((sizes.sum(), 0)), sizes)
    points = fibers[fib[owner], start[owner] + np.where(forward[owner], index, -index)]
    shaped = np.empty_like(points)
    at_loop = is_loop[owner]
    shaped[at_loop] = loops(points[at_loop], sizes[is_loop], LOOP_D_UNIT_MM * d[is_loop])
    shaped[~at_loop] = hairs(points[~at_loop], sizes[~is_loop], params.beta, params.s)
    kinds = np.where(is_loop, FiberKind.LOOP, FiberKind.HAIR).astype(np.uint8)
    return shaped, sizes, kinds, fib


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
    curves, curve_sizes, kinds, source = flyaways(params, core, rng, length)
    f, v = core.shape[:2]
    sizes = np.concatenate([np.full(f, v), curve_sizes])
    points = np.concatenate([core.reshape(-1, 3), curves]).astype(np.float32)
    count = len(sizes)
    return FiberSet(
        points=points,
        offsets=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
        radii=np.tile(np.float32([params.t_x, params.t_y]), (count, 1)),
        kind=np.concatenate([np.zeros(f, np.uint8), kinds]),
        ply=np.concatenate([core_ply, core_ply[source]]).astype(np.int16),
    )
