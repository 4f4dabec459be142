"""Knitted patches: the swept yarn keeps its parameters, measured along the yarn's own
centre (the mean of its fibers, not ipm's centre line) in a frame the test transports
itself; the centre lines keep clear of each other; bad patterns are refused."""

import math

import numpy as np
import pytest
from geometry import transported_frame, turn_rate

from ipm.errors import UserError
from ipm.fibers import FiberKind
from ipm.knit import PATTERNS, knit_patch
from ipm.presets import preset


def course_fibers(patch, params, course):
    """(F, V, 3) core fibers of one course and (F,) their plies: the courses come one after
    the other, each n m core fibers first, then its flyaways."""
    core = np.flatnonzero(patch.fibers.kind == FiberKind.CORE)
    per = params.n * params.m
    idx = core[course * per:(course + 1) * per]
    v = np.diff(patch.fibers.offsets)[idx[0]]
    pts = np.stack([patch.fibers.fiber(f) for f in idx]).astype(np.float64)
    assert pts.shape[1] == v
    return pts, patch.fibers.ply[idx]


@pytest.fixture(scope="module")
def golden_patch():
    p = preset("golden").replace(g=30)
    return p, knit_patch(p, "knit", wales=4, courses=2, seed=3)


def test_the_ply_twist_is_kept_along_the_stitches(golden_patch):
    p, patch = golden_patch
    pts, ply = course_fibers(patch, p, 0)
    centre = pts.mean(axis=0)  # the yarn's own centre line
    inner = slice(len(centre) // 20, -len(centre) // 20)  # away from the yarn's ends
    e1, e2, t = transported_frame(centre)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(centre, axis=0), axis=1))])
    for k in range(p.n):
        d = pts[ply == k].mean(axis=0) - centre
        a, b = np.sum(d * e1, -1), np.sum(d * e2, -1)
        rate = turn_rate(a[inner], b[inner], arc[inner])
        assert 2 * math.pi / abs(rate) == pytest.approx(p.alpha_ply, rel=0.02)
        assert np.median(np.hypot(a, b)[inner]) == pytest.approx(p.R_ply, rel=0.02)


def test_the_cross_section_is_kept(golden_patch):
    from ipm.generator import generate

    p, patch = golden_patch
    pts, _ = course_fibers(patch, p, 1)
    centre = pts.mean(axis=0)
    e1, e2, t = transported_frame(centre)
    d = pts - centre
    radial = np.hypot(np.sum(d * e1, -1), np.sum(d * e2, -1))
    length = float(np.linalg.norm(np.diff(centre, axis=0), axis=1).sum())
    straight = generate(p, seed=4, length=length)
    core = straight.points[: straight.offsets[p.n * p.m]].astype(np.float64)
    core = core.reshape(p.n * p.m, -1, 3)
    ref = core - core.mean(axis=0)
    assert np.percentile(radial, 95) == pytest.approx(
        np.percentile(np.hypot(ref[..., 0], ref[..., 1]), 95), rel=0.03)
    # a cross-section stays as flat along the curve as along the straight axis
    along = np.percentile(np.abs(np.sum(d * t, -1)), 95)
    assert along == pytest.approx(np.percentile(np.abs(ref[..., 2]), 95), rel=0.25)


@pytest.mark.parametrize("pattern", PATTERNS)
def test_centre_lines_keep_clear_of_each_other(pattern):
    """0.85 D in knit and purl, 0.7 D where courses of both faces meet (garter, rib): real
    yarn flattens where it crosses."""
    from scipy.spatial import cKDTree

    p = preset("rose").replace(g=30)
    patch = knit_patch(p, pattern, wales=4, courses=4, seed=0)
    d = patch.diameter * (0.85 if pattern in ("knit", "purl") else 0.7)
    lines = patch.centrelines
    for i in range(len(lines)):
        for j in range(i + 1, len(lines)):
            assert cKDTree(lines[j]).query(lines[i])[0].min() > d, (pattern, i, j)
        arc = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(lines[i], axis=0), axis=1))])
        pairs = cKDTree(lines[i]).query_pairs(d, output_type="ndarray")
        assert np.all(np.abs(arc[pairs[:, 0]] - arc[pairs[:, 1]]) < 2.5 * patch.diameter)


def test_unknown_pattern_is_refused():
    with pytest.raises(UserError, match="unknown pattern"):
        knit_patch(preset("golden"), "moss")
