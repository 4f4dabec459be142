"""The generator against its parameters, measured with the tests' own geometry
(:mod:`geometry`: right-handed frames built from the fiber points, not the generator's)."""

import math

import numpy as np
import pytest
from geometry import co_rotating_frame, core_fibers, fiber_turn_rates, helix_about_z, ply_centres

from ipm.fibers import FiberKind, FiberSet
from ipm.frame import FRAME_WIDTH_MM, YARN_LENGTH_MM
from ipm.generator import Level, generate, hair, loop, raw_yarn
from ipm.presets import PRESET_NAMES, preset


def yarns(sampled):
    return [(name, preset(name)) for name in PRESET_NAMES] + \
        [(f"sampled{i}", p) for i, p in enumerate(sampled)]


@pytest.fixture(scope="module")
def generated(sampled_params):
    return [(name, p, generate(p, seed=7)) for name, p in yarns(sampled_params)]


def test_ply_centre_lines_are_helices_of_R_ply_and_alpha_ply(generated):
    """Eq. 6's ``(sin, cos)`` helix turns clockwise about +z for a positive pitch: the turn
    rate is ``-2 pi / alpha_ply`` (left-handed: the S ply twist of ipm/textile/fibers.py)."""
    for name, p, fs in generated:
        for c in ply_centres(*core_fibers(fs)).values():
            radius, rate = helix_about_z(c)
            assert radius == pytest.approx(p.R_ply, rel=0.01), name
            assert rate == pytest.approx(-2 * math.pi / p.alpha_ply, rel=0.01), name


def test_fibers_turn_about_their_ply_at_alpha_against_the_ply_twist(generated):
    """In the ply's own right-handed co-rotating frame a fiber turns at ``-2 pi / alpha``
    about the ply's tangent: with alpha < 0 < alpha_ply (every preset and prior sample) it
    turns against the ply's turn about the yarn axis, as in plied yarns (Z on S)."""
    for name, p, fs in generated:
        core, ply = core_fibers(fs)
        rates = fiber_turn_rates(core, ply, squeeze=p.r_y / p.r_x, min_radius=0.5 * p.r_x)
        assert len(rates) >= p.n, name
        assert np.median(rates) == pytest.approx(-2 * math.pi / p.alpha, rel=0.02), name
        _, ply_rate = helix_about_z(ply_centres(core, ply)[0])
        assert p.alpha < 0 < p.alpha_ply, name
        assert np.all(np.sign(rates) == -np.sign(ply_rate)), name


def test_same_signed_pitches_twist_the_same_way():
    """The rule is the sign of the pitches, not a fixed direction: fibers of a positive
    pitch turn with a ply of positive pitch."""
    for fiber_pitch, ply_pitch in ((2.0, 6.0), (-2.0, -6.0), (2.0, -6.0)):
        levels = [Level(40, 0.2, fiber_pitch), Level(3, 0.3, ply_pitch, squeeze=0.8)]
        core, ply = raw_yarn(levels, np.random.default_rng(0), length=12.0)
        rates = fiber_turn_rates(core, ply, squeeze=0.8, min_radius=0.1)
        _, ply_rate = helix_about_z(ply_centres(core, ply)[0])
        assert ply_rate == pytest.approx(-2 * math.pi / ply_pitch, rel=0.01)
        assert np.median(rates) == pytest.approx(-2 * math.pi / fiber_pitch, rel=0.02)
        assert np.all(np.sign(rates) == np.sign(fiber_pitch * ply_pitch) * np.sign(ply_rate))


def test_counts_kinds_and_radii(generated):
    for name, p, fs in generated:
        assert (fs.kind == FiberKind.CORE).sum() == p.n * p.m, name
        fly = fs.kind != FiberKind.CORE
        # g per 10 mm of ply (less the authors' dropped strips: 0.88), the ply's length from
        # its helix: its arc over the yarn's length
        ply_length = YARN_LENGTH_MM * math.hypot(1, 2 * math.pi * p.R_ply / p.alpha_ply)
        count = round(0.88 * p.g * ply_length / 10)
        assert fly.sum() == count, name
        loops = (fs.kind == FiberKind.LOOP).sum()
        assert abs(loops - count * p.p) <= 4 * np.sqrt(count * p.p * (1 - p.p)), name
        assert np.all(fs.radii == np.float32([p.t_x, p.t_y])), name
        assert set(np.unique(fs.ply)) == set(range(p.n)), name


def test_flyaway_roots_lie_on_a_core_fiber_of_their_ply(generated):
    for name, _, fs in generated[:6]:
        core, ply = core_fibers(fs)
        core = core.astype(np.float32)
        for f in np.flatnonzero(fs.kind != FiberKind.CORE):
            root = fs.fiber(f)[0]
            assert np.abs(core[ply == fs.ply[f]] - root).max(axis=-1).min() == 0.0, name


def straight_segment(root, length=2.0, count=41):
    """A test-made fiber segment from ``root`` straight along +z."""
    z = np.linspace(0.0, length, count)
    return np.column_stack([np.full(count, root[0]), np.full(count, root[1]), root[2] + z])


def test_loop_arches_d_mm_out_along_the_radial_direction():
    root = np.array([0.3, -0.4, 1.0])  # radial direction (0.6, -0.8)
    seg = straight_segment(root)
    out = loop(seg, d_mm=0.444)
    push = out - seg
    u = np.array([0.6, -0.8, 0.0])
    along = push @ u
    assert along.max() == pytest.approx(0.444, rel=1e-3)
    assert np.allclose(push - along[:, None] * u, 0.0, atol=1e-9)  # only radial, z untouched
    assert np.allclose(out[[0, -1]], seg[[0, -1]])  # a straight segment keeps both ends
    # the arch sin(i pi / J) over the J inner vertices, i = 0 .. J - 1 (the authors' indexing)
    inner = len(seg) - 2
    assert np.allclose(along[1:-1], 0.444 * np.sin(np.arange(inner) * np.pi / inner))


def test_loop_halves_x_about_its_first_vertex():
    seg = straight_segment([0.5, 0.0, 0.0])
    seg[:, 0] += np.linspace(0.0, 0.2, len(seg))  # drifts 0.2 mm in x
    out = loop(seg, d_mm=0.0)
    assert np.allclose(out[:, 0] - 0.5, 0.5 * (seg[:, 0] - 0.5))
    assert np.allclose(out[:, 1:], seg[:, 1:])


def test_hair_is_squeezed_mirrored_and_turned_by_beta_about_its_far_end_radial_axis():
    """The authors' hair: squeeze z and mirror x about the root, then turn every vertex after
    the root by beta about the far end's radial direction, through the vertex after the
    root."""
    root = np.array([0.0, 0.5, -2.0])
    seg = straight_segment(root, length=3.0)
    seg[:, 0] += 0.1 * np.sin(np.linspace(0.0, np.pi, len(seg)))  # bulges to +x, ends on +y
    beta, s = 0.7, 0.4
    out = hair(seg, beta, s)
    made = seg - root
    made[:, 0] *= -1
    made[:, 2] /= 1 + 1.5 * s
    assert np.allclose(out[:2] - root, made[:2], atol=1e-9)  # root and pivot stay
    d = out - out[1]
    assert np.allclose(d[:, 1], 0.0, atol=1e-9)  # a turn about the radial axis +y keeps y
    # undo the right-handed turn about +y by beta: (x, z) -> (c x - s z, s x + c z)
    c, sn = math.cos(beta), math.sin(beta)
    x, z = c * d[:, 0] - sn * d[:, 2], sn * d[:, 0] + c * d[:, 2]
    assert np.allclose(np.column_stack([x, z])[1:], (made - made[1])[1:, [0, 2]], atol=1e-9)


def test_long_flyaways_and_loop_heights_follow_the_authors_distributions():
    """4 % long flyaways: loops twice and hairs three times as long; loop arches 0.1 d mm
    with d = d_mean + |N(0, d_std)| (long: about 2 d_mean).  Measured on the polylines:
    a loop's arc length and a hair's chord before squeeze are recovered from the points."""
    p = preset("golden").replace(g=300, d_std=0.007, s=0.0, l_hair=1.0, l_loop=2.0)
    fs = generate(p, seed=4, length=40.0)
    arc = np.array([np.linalg.norm(np.diff(fs.fiber(f), axis=0), axis=1).sum()
                    for f in range(fs.num_fibers)])
    hairs, loops = fs.kind == FiberKind.HAIR, fs.kind == FiberKind.LOOP
    long_hairs = np.mean(arc[hairs] > 2.0)
    assert 0.01 < long_hairs < 0.08
    assert np.median(arc[hairs][arc[hairs] > 2.0]) == pytest.approx(3.0, rel=0.1)
    assert np.median(arc[hairs]) == pytest.approx(1.0, rel=0.1)
    # a loop's arch: the largest distance of its points from the chord of its ends
    heights = []
    for f in np.flatnonzero(loops):
        pts = fs.fiber(f).astype(np.float64)
        a, b = pts[0], pts[-1]
        t = (b - a) / np.linalg.norm(b - a)
        rel = pts - a
        heights.append(np.linalg.norm(rel - np.outer(rel @ t, t), axis=1).max())
    heights = np.array(heights)
    assert np.median(heights) == pytest.approx(0.1 * p.d_mean, rel=0.35)
    assert np.percentile(heights, 99) < 0.1 * 2.5 * p.d_mean + 0.3


def test_yarn_fills_the_frame():
    fs = generate(preset("rose"), seed=0)
    z = core_fibers(fs)[0][..., 2]
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
        core, ply = core_fibers(fs)
        z = core[..., 2].mean(axis=0)
        # the exact ply centre lines' tangents: circle pattern, phase 2 pi k / n at z = 0
        theta = 2 * np.pi * z[None] / p.alpha_ply + 2 * np.pi * np.arange(p.n)[:, None] / p.n
        for k, t in enumerate(theta):
            centre = np.column_stack([p.R_ply * np.sin(t), p.R_ply * np.cos(t), z])
            _, _, tangent = co_rotating_frame(centre)
            section = core[ply == k] - core[ply == k].mean(axis=0)  # each vertex's cross-section
            along = np.sum(section * tangent, axis=-1)[:, 1:-1]  # no ends
            tilt[mapping] = max(tilt.get(mapping, 0.0), np.abs(along).max())
    assert tilt["local"] < 0.02 * p.r_x
    assert tilt["global"] > 0.5 * p.r_x


def test_fourth_level_twists_yarns_into_a_cabled_yarn():
    p = preset("golden").replace(n_yarn=2, alpha_yarn=-12.0, R_yarn=0.7)
    fs = generate(p, seed=2)
    assert (fs.kind == FiberKind.CORE).sum() == 2 * p.n * p.m
    assert set(np.unique(fs.ply)) == set(range(2 * p.n))
    core, _ = core_fibers(fs)
    per_yarn = core.reshape(2, p.n * p.m, *core.shape[1:]).mean(axis=1)
    for c in per_yarn:
        radius, rate = helix_about_z(c)
        assert radius == pytest.approx(0.7, rel=0.02)
        assert rate == pytest.approx(-2 * math.pi / -12.0, rel=0.01)


def test_levels_of_any_depth():
    levels = [Level(30, 0.1, -1.0), Level(3, 0.2, 3.0, squeeze=0.8), Level(2, 0.5, -8.0),
              Level(2, 1.0, 20.0)]
    fibers, ply = raw_yarn(levels, np.random.default_rng(0), length=10.0)
    assert fibers.shape[0] == 30 * 3 * 2 * 2 and set(ply) == set(range(12))
    top_copy = fibers.reshape(2, -1, *fibers.shape[1:]).mean(axis=1)[0]  # centre of copy 0
    radius, rate = helix_about_z(top_copy)
    assert radius == pytest.approx(1.0, rel=0.02)
    assert rate == pytest.approx(-2 * math.pi / 20.0, rel=0.01)


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


@pytest.mark.parametrize("suffix", [".usda", ".usd"])
def test_usd_export_reads_back_with_pxr(tmp_path, suffix):
    from pxr import Usd, UsdGeom

    fs = generate(preset("golden"), seed=1)
    fs.save_usd(tmp_path / f"y{suffix}")
    stage = Usd.Stage.Open(str(tmp_path / f"y{suffix}"))
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath("/Yarn/Fibers"))
    counts = np.array(curves.GetCurveVertexCountsAttr().Get())
    assert len(counts) == fs.num_fibers and np.array_equal(counts, np.diff(fs.offsets))
    assert np.allclose(np.array(curves.GetPointsAttr().Get()), fs.points)
    widths = np.array(curves.GetWidthsAttr().Get())
    assert curves.GetWidthsInterpolation() == UsdGeom.Tokens.uniform
    assert np.allclose(widths, 2 * np.sqrt(fs.radii[:, 0] * fs.radii[:, 1]), rtol=1e-6)
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.001)
    kind = UsdGeom.PrimvarsAPI(curves).GetPrimvar("kind").Get()
    assert np.array_equal(np.array(kind), fs.kind)


def test_ply_export_reads_back_with_plyfile(tmp_path):
    from plyfile import PlyData

    fs = generate(preset("golden"), seed=1)
    fs.save_ply(tmp_path / "y.ply")
    ply = PlyData.read(str(tmp_path / "y.ply"))
    v, e, f = ply["vertex"], ply["edge"], ply["fiber"]
    assert len(v) == len(fs.points) and len(f) == fs.num_fibers
    assert len(e) == len(fs.points) - fs.num_fibers
    assert np.allclose(np.column_stack([v["x"], v["y"], v["z"]]), fs.points)
    assert np.array_equal(np.asarray(f["count"]), np.diff(fs.offsets))
    assert np.allclose(np.column_stack([f["radius_x"], f["radius_y"]]), fs.radii)
    # every edge joins two consecutive vertices of one fiber
    assert np.all(np.asarray(v["fiber"])[e["vertex1"]] == np.asarray(v["fiber"])[e["vertex2"]])

