"""The generator against its parameters (issue: geometry matches parameters)."""

import numpy as np
import pytest

from ipm.fibers import FiberKind, FiberSet
from ipm.frame import FRAME_WIDTH_MM
from ipm.generator import Level, generate, raw_yarn
from ipm.measure import (
    core_fibers,
    fiber_offsets_in_ply,
    fiber_pitches_in_ply,
    fit_helix,
    hair_angles,
    ply_centerlines,
)
from ipm.presets import PRESET_NAMES, preset


def yarns(sampled):
    return [(name, preset(name)) for name in PRESET_NAMES] + \
        [(f"sampled{i}", p) for i, p in enumerate(sampled)]


@pytest.fixture(scope="module")
def generated(sampled_params):
    return [(name, p, generate(p, seed=7)) for name, p in yarns(sampled_params)]


def test_ply_centre_lines_are_helices_of_R_ply_and_alpha_ply(generated):
    for name, p, fs in generated:
        for c in ply_centerlines(fs).values():
            radius, pitch = fit_helix(c)
            assert radius == pytest.approx(p.R_ply, rel=0.01), name
            assert pitch == pytest.approx(p.alpha_ply, rel=0.005), name


def test_fibers_wind_around_their_ply_with_alpha_in_the_opposite_direction(generated):
    for name, p, fs in generated:
        pitches = fiber_pitches_in_ply(fs, squeeze=p.r_y / p.r_x, min_radius=0.5 * p.r_x)
        assert len(pitches) >= p.n, name
        assert np.median(pitches) == pytest.approx(p.alpha, rel=0.005), name
        assert np.all(np.sign(pitches) == -np.sign(p.alpha_ply)), name


def test_counts_kinds_and_radii(generated):
    for name, p, fs in generated:
        assert (fs.kind == FiberKind.CORE).sum() == p.n * p.m, name
        fly = fs.kind != FiberKind.CORE
        assert fly.sum() == p.g, name
        loops = (fs.kind == FiberKind.LOOP).sum()
        assert abs(loops - p.g * p.p) <= 4 * np.sqrt(p.g * p.p * (1 - p.p)), name
        assert np.all(fs.radii == np.float32([p.t_x, p.t_y])), name
        assert set(np.unique(fs.ply)) == set(range(p.n)), name


def test_loops_keep_both_ends_on_their_source_fiber(generated):
    for name, _, fs in generated[:6]:
        core = core_fibers(fs).astype(np.float32)
        for f in np.flatnonzero(fs.kind == FiberKind.LOOP):
            pts = fs.fiber(f)
            same_ply = core[fs.ply[: len(core)] == fs.ply[f]]
            for end in (pts[0], pts[-1]):
                dist = np.abs(same_ply - end).max(axis=-1)
                assert dist.min() == 0.0, name
            # both ends on one fiber: that fiber holds the first and the last point
            hits0 = {i for i, fib in enumerate(same_ply) if np.any(np.all(fib == pts[0], -1))}
            hits1 = {i for i, fib in enumerate(same_ply) if np.any(np.all(fib == pts[-1], -1))}
            assert hits0 & hits1, name


def test_hairs_leave_at_beta_leaning_outwards(generated):
    for name, p, fs in generated:
        assert np.allclose(hair_angles(fs), p.beta, atol=1e-4), name
        for f in np.flatnonzero(fs.kind == FiberKind.HAIR):
            pts = fs.fiber(f).astype(np.float64)
            root, tip = pts[0], pts[-1]
            assert np.hypot(*tip[:2]) >= np.hypot(*root[:2]) - 1e-4, name


def test_yarn_fills_the_frame():
    fs = generate(preset("rose"), seed=0)
    z = core_fibers(fs)[..., 2]
    assert z.min(axis=1).max() < -FRAME_WIDTH_MM / 2 - 1
    assert z.max(axis=1).min() > FRAME_WIDTH_MM / 2 + 1


def test_same_seed_same_bytes_other_seed_other_fibers():
    p = preset("pink_4ply")
    assert generate(p, 3).to_npz_bytes() == generate(p, 3).to_npz_bytes()
    a, b = generate(p, 3), generate(p, 4)
    assert a.points.shape != b.points.shape or not np.array_equal(a.points, b.points)


def test_local_frame_keeps_ply_cross_sections_orthogonal_to_the_centre_line():
    """Paper Fig. 5 on an exaggerated case: local-frame mapping vs Zhao et al.'s global-axis
    shift.  Without fiber-level jitter every ply cross-section lies in the plane normal to
    its centre line with the local mapping, and is sheared by the ply's tilt with the global
    one."""
    p = preset("grey_thick").replace(R_ply=1.0, alpha_ply=3.0, r_x=0.5, r_y=0.45, j=0.0,
                                     j_xy=0.0, j_z=0.0)
    tilt = {}
    for mapping in ("local", "global"):
        fs = generate(p, seed=1, mapping=mapping)
        z = core_fibers(fs)[0, :, 2]
        # the exact ply centre lines: circle pattern, phase 2 pi k / n at z = 0
        theta = 2 * np.pi * z[None] / p.alpha_ply + 2 * np.pi * np.arange(p.n)[:, None] / p.n
        centers = {k: np.column_stack([p.R_ply * np.sin(t), p.R_ply * np.cos(t), z])
                   for k, t in enumerate(theta)}
        offsets = fiber_offsets_in_ply(fs, centers)
        tilt[mapping] = max(np.abs(o[:, 1:-1, 2]).max() for o in offsets.values())  # no ends
    assert tilt["local"] < 0.02 * p.r_x
    assert tilt["global"] > 0.5 * p.r_x


def test_fourth_level_twists_yarns_into_a_cabled_yarn():
    p = preset("golden").replace(n_yarn=2, alpha_yarn=-12.0, R_yarn=0.7)
    fs = generate(p, seed=2)
    assert (fs.kind == FiberKind.CORE).sum() == 2 * p.n * p.m
    assert set(np.unique(fs.ply)) == set(range(2 * p.n))
    core = core_fibers(fs)
    per_yarn = core.reshape(2, p.n * p.m, *core.shape[1:]).mean(axis=1)
    for c in per_yarn:
        radius, pitch = fit_helix(c)
        assert radius == pytest.approx(0.7, rel=0.02) and pitch == pytest.approx(-12.0, rel=0.01)


def test_levels_of_any_depth():
    levels = [Level(30, 0.1, -1.0), Level(3, 0.2, 3.0, squeeze=0.8), Level(2, 0.5, -8.0),
              Level(2, 1.0, 20.0)]
    fibers, ply = raw_yarn(levels, np.random.default_rng(0), length=10.0)
    assert fibers.shape[0] == 30 * 3 * 2 * 2 and set(ply) == set(range(12))
    top_copy = fibers.reshape(2, -1, *fibers.shape[1:]).mean(axis=1)[0]  # centre of copy 0
    radius, pitch = fit_helix(top_copy)
    assert radius == pytest.approx(1.0, rel=0.02) and pitch == pytest.approx(20.0, rel=0.01)


def test_fiberset_npz_roundtrip(tmp_path):
    fs = generate(preset("golden"), seed=1)
    fs.save_npz(tmp_path / "y.npz")
    back = FiberSet.load_npz(tmp_path / "y.npz")
    for k in ("points", "offsets", "radii", "kind", "ply"):
        assert np.array_equal(getattr(back, k), getattr(fs, k))
    assert back.points.dtype == np.float32 and back.offsets.dtype == np.int64
    assert back.kind.dtype == np.uint8 and back.ply.dtype == np.int16


def test_mitsuba_curve_file_has_one_block_per_fiber(tmp_path):
    fs = generate(preset("golden"), seed=1)
    fs.save_mitsuba(tmp_path / "y.txt")
    blocks = (tmp_path / "y.txt").read_text().strip().split("\n\n")
    assert len(blocks) == fs.num_fibers
    first = np.loadtxt(blocks[0].splitlines())
    assert first.shape == (np.diff(fs.offsets)[0], 4)
    assert np.allclose(first[:, 3], np.sqrt(fs.radii[0, 0] * fs.radii[0, 1]), rtol=1e-5)
