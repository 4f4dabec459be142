"""The scene and the renderer: real llvm_ad_rgb images checked statistically, determinism,
photometric variation, the variant choice and the ``ipm render`` / ``ipm doctor`` CLI."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
from PIL import Image

from ipm import FiberSet, preset
from ipm.errors import UserError
from ipm.frame import pixel_size_mm
from ipm.render.photometric import (
    NO_VARIATION,
    NOMINAL,
    Photometric,
    PhotometricRanges,
    apply_to_image,
)
from ipm.render.renderer import Renderer, srgb8_to_linear, to_srgb8, world_curves
from ipm.render.scene import SceneOptions, frame_size, yarn_to_world
from ipm.render.variant import llvm_major, requested_variant


def ipm(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "ipm", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd)


@pytest.fixture(scope="module")
def renderer():
    r = Renderer()
    assert r.variant == "llvm_ad_rgb"
    return r


# -- smoke: frame, transforms, buffers ---------------------------------------------------------
def test_frame_and_pixel_pitch():
    assert frame_size(1) == (2000, 600) and frame_size(0.25) == (500, 150)
    assert pixel_size_mm(0.5) == pytest.approx(0.02)
    with pytest.raises(UserError, match="scale"):
        frame_size(0)


def test_yarn_axis_maps_to_image_horizontal():
    m = yarn_to_world()
    assert np.allclose(m[:3, :3] @ [0, 0, 1], [1, 0, 0])  # generator z -> image right
    assert np.isclose(np.linalg.det(m[:3, :3]), 1)
    shifted = yarn_to_world((0.5, -0.2), 90)
    assert np.allclose(shifted[:3, :3] @ [0, 0, 1], [0, 1, 0]) and np.allclose(
        shifted[:2, 3], [0.5, -0.2])


def test_world_curves_segments_skip_fiber_ends():
    from ipm import generate

    fs = generate(preset("grey_thin"), 0)
    points, segments = world_curves(fs, yarn_to_world())
    assert points.shape == (len(fs.points), 4)
    assert len(segments) == len(fs.points) - fs.num_fibers
    assert not np.isin(fs.offsets[1:] - 1, segments).any()
    assert np.allclose(points[:, 3], np.repeat(fs.round_radii(), np.diff(fs.offsets)))


def test_srgb_roundtrip():
    x = np.linspace(0, 1, 256, dtype=np.float32)[None, :, None].repeat(3, -1)
    assert np.abs(srgb8_to_linear(to_srgb8(x)) - x).max() < 0.01


# -- variants -----------------------------------------------------------------------------------
def test_variant_choice():
    assert requested_variant() in ("llvm_ad_rgb", "cuda_ad_rgb", "scalar_rgb")
    assert requested_variant("cuda_ad_rgb") == "cuda_ad_rgb"
    with pytest.raises(UserError, match="unknown Mitsuba variant 'llvm_rgb'"):
        requested_variant("llvm_rgb")
    assert llvm_major("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1") == 19
    assert llvm_major("/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1") == 15
    assert llvm_major("/usr/lib/llvm-14/lib/libLLVM.so") == 14


# -- a real image, checked statistically ----------------------------------------------------------
def yarn_rows(image: np.ndarray) -> tuple[np.ndarray, float]:
    """Rows where most pixels are yarn (brighter than 2.5x the backdrop) and the centroid of
    the per-row yarn fraction."""
    lum = image.mean(-1)
    backdrop = np.median(np.concatenate([lum[:4], lum[-4:]]))
    fraction = (lum > 2.5 * backdrop).mean(1)
    centroid = float((fraction * np.arange(len(fraction))).sum() / fraction.sum())
    return np.flatnonzero(fraction > 0.5), centroid


@pytest.mark.parametrize("name", ["light", "golden", "pink_6ply"])
def test_real_render_core_thickness_centre_contrast(renderer, name):
    """The core's band; the fewest flyaways the intervals allow (g = 30 per 10 mm), since
    the hairiest presets (light: 223 per 10 mm, loops arching 1.3 mm) fill the rows around
    the core with more than half their pixels."""
    p, scale = preset(name).replace(g=30), 0.25
    image = renderer.render(p, seed=0, scale=scale, spp=4)
    assert image.shape == (150, 500, 3) and image.dtype == np.float32
    assert np.isfinite(image).all()
    rows, centroid = yarn_rows(image)
    # the core is one band, centred (the scene puts the yarn axis on the middle row)
    assert len(rows) and rows.max() - rows.min() + 1 == len(rows)
    assert abs(centroid - (image.shape[0] - 1) / 2) < 2.5
    # its thickness in pixels matches the parameters via pixel_size_mm: about
    # 2 (R_ply + r_y) .. 2 (R_ply + r_x); the sparse outer fibers of the plies thin it a bit
    px = pixel_size_mm(scale)
    lo, hi = 2 * (p.R_ply + p.r_y) / px, 2 * (p.R_ply + p.r_x) / px
    assert 0.85 * lo <= len(rows) <= 1.1 * hi, (len(rows), lo, hi)
    # yarn against backdrop: the core is several times brighter than the card
    lum = image.mean(-1)
    backdrop = np.median(np.concatenate([lum[:4], lum[-4:]]))
    assert lum[rows].mean() > 4 * backdrop
    # and has the yarn's hue: its mean colour correlates with the albedo
    assert np.corrcoef(image[rows].mean((0, 1)), p.color)[0, 1] > 0.9


def test_same_settings_same_image(renderer):
    p = preset("grey_thin")
    a = renderer.render(p, seed=3, scale=0.2, spp=2, render_seed=7)
    renderer.render(preset("rose"), seed=1, scale=0.2, spp=2)  # swap buffers in between
    b = renderer.render(p, seed=3, scale=0.2, spp=2, render_seed=7)
    c = renderer.render(p, seed=3, scale=0.2, spp=2, render_seed=8)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    assert abs(a.mean() - c.mean()) < 0.05 * a.mean()  # another sampler seed: same statistics


def test_scene_shapes_keep_the_dict_order(renderer):
    """The soft boxes' order decides which lamp the emitter sampling gives each random
    number to; Mitsuba's default loading ordered them differently from process to process."""
    scene, _ = renderer._scene(0.1)
    assert [s.id() for s in scene.shapes()] == ["yarn", "backdrop", "key_left", "key_right"]


def noise_and_mean(r: Renderer, spp: int) -> tuple[float, np.ndarray]:
    """Pixel noise (std of the difference of two sampler seeds) and the per-channel mean of
    the golden preset rendered by ``r`` at scale 0.2."""
    a, b = (r.render(preset("golden"), seed=1, scale=0.2, spp=spp, render_seed=s)
            for s in (1, 2))
    return float(np.std(a - b)), a.mean(axis=(0, 1))


def test_stratified_samples_are_cleaner_than_independent(renderer):
    """The scene's multijitter sampler: less pixel noise than independent samples at the
    same count (fiber coverage of a pixel is estimated better), same mean image."""
    independent = Renderer(options=SceneOptions(sampler="independent"))
    (n_mj, m_mj), (n_ind, m_ind) = noise_and_mean(renderer, 4), noise_and_mean(independent, 4)
    m_mj, m_ind = m_mj.mean(), m_ind.mean()
    assert n_mj < 0.9 * n_ind, (n_mj, n_ind)
    assert abs(m_mj - m_ind) < 0.03 * m_ind
    with pytest.raises(UserError, match="unknown sampler 'sobol'"):
        SceneOptions(sampler="sobol")


def test_weighted_light_choice_is_cleaner_than_uniform():
    """Mitsuba's path integrator with the scene's light sampling weights: less noise than
    picking the lights with equal probability, the same expected image."""
    weighted = Renderer(options=SceneOptions(integrator="path"))
    uniform = Renderer(options=SceneOptions(integrator="path", light_sampling="uniform"))
    (n_w, m_w), (n_u, m_u) = noise_and_mean(weighted, 8), noise_and_mean(uniform, 8)
    assert n_w < 0.9 * n_u, (n_w, n_u)
    assert np.allclose(m_w, m_u, rtol=0.01), (m_w, m_u)
    with pytest.raises(UserError, match="unknown light sampling 'random'"):
        SceneOptions(light_sampling="random")


def block_means(image: np.ndarray, k: int = 16) -> np.ndarray:
    h, w = image.shape[0] // k * k, image.shape[1] // k * k
    return image[:h, :w].reshape(h // k, k, w // k, k, 3).mean(axis=(1, 3))


def test_lamp_reach_integrator_renders_paths_image_with_less_noise(renderer):
    """ipm_path (the scene's integrator): Mitsuba's path integrator's image with less noise.

    Rendered with path's sampler seed, it has path's pixel positions, so 16 x 16 blocks
    differ by shading noise only: well under another seed of path (measured 0.49 of it;
    0.97 times the light of each lamp sample gives 1.03 and a 2 % darker image)."""
    path = Renderer(options=SceneOptions(integrator="path"))
    (n_ipm, _), (n_path, _) = noise_and_mean(renderer, 8), noise_and_mean(path, 8)
    assert n_ipm < 0.9 * n_path, (n_ipm, n_path)
    ipm, path_a, path_b = (r.render(preset("golden"), seed=1, scale=0.2, spp=16, render_seed=s)
                           for r, s in ((renderer, 3), (path, 3), (path, 4)))
    between = np.sqrt(np.mean((block_means(ipm) - block_means(path_a)) ** 2))
    within = np.sqrt(np.mean((block_means(path_b) - block_means(path_a)) ** 2))
    assert between < 0.8 * within, (between, within)
    assert np.allclose(ipm.mean(axis=(0, 1)), path_a.mean(axis=(0, 1)), rtol=0.01)
    with pytest.raises(UserError, match="unknown integrator 'volpath'"):
        SceneOptions(integrator="volpath")


def test_sample_count_is_what_the_sampler_takes(renderer):
    assert [renderer.sample_count(0.1, n) for n in (4, 6, 7, 13)] == [4, 6, 8, 15]
    orthogonal = Renderer(options=SceneOptions(sampler="orthogonal"))
    assert orthogonal.sample_count(0.1, 16) == 25


# -- photometric variation ---------------------------------------------------------------
def test_photometric_draw_is_seeded_and_recorded():
    ranges = PhotometricRanges()
    a = ranges.draw(np.random.default_rng(1))
    assert a == ranges.draw(np.random.default_rng(1)) != ranges.draw(np.random.default_rng(2))
    assert Photometric.from_dict(json.loads(json.dumps(a.to_dict()))) == a
    assert abs(a.exposure_stops) <= ranges.exposure_stops
    assert np.mean(a.white_balance) == pytest.approx(1)
    assert NO_VARIATION.draw(np.random.default_rng(0)) == Photometric(
        noise_seed=NO_VARIATION.draw(np.random.default_rng(0)).noise_seed)


def test_photometric_image_effects():
    image = np.full((20, 30, 3), 0.2, np.float32)
    assert apply_to_image(image, NOMINAL) == pytest.approx(image)
    brighter = apply_to_image(image, Photometric(exposure_stops=1.0))
    assert brighter == pytest.approx(2 * image)
    noisy = apply_to_image(image, Photometric(noise=(1e-3, 1e-5), noise_seed=4))
    assert noisy.std() == pytest.approx(np.sqrt(1e-3 * 0.2 + 1e-5), rel=0.2)
    assert np.array_equal(noisy, apply_to_image(image, Photometric(noise=(1e-3, 1e-5),
                                                                   noise_seed=4)))


def test_photometric_shift_moves_the_yarn(renderer):
    p = preset("golden")
    up = renderer.render(p, 0, 0.2, 2, photometric=Photometric(shift_mm=(0.0, 0.6)))
    _, c_up = yarn_rows(up)
    _, c0 = yarn_rows(renderer.render(p, 0, 0.2, 2))
    assert c0 - c_up == pytest.approx(0.6 / pixel_size_mm(0.2), abs=2)  # image rows go down


# -- CLI ----------------------------------------------------------------------------------------
def test_cli_render_writes_png_and_record(tmp_path):
    r = ipm("render", "--preset", "grey_thin", "-o", tmp_path / "yarn.png", "--scale", 0.1,
            "--spp", 2, "--seed", 4)
    assert r.returncode == 0, r.stderr
    img = Image.open(tmp_path / "yarn.png")
    assert img.mode == "RGB" and img.size == (200, 60)
    rec = json.loads((tmp_path / "yarn.json").read_text())
    assert rec["seed"] == 4 and rec["spp"] == 2 and rec["scale"] == 0.1
    assert rec["pixel_size_mm"] == pytest.approx(0.1)
    assert rec["params"] == preset("grey_thin").to_dict()
    # same bytes from another process: tests/test_generate.py
    # test_samples_are_the_same_bytes_across_processes (slow, intermittent)


def test_cli_render_xml_scene_loads(tmp_path):
    r = ipm("render", "--preset", "grey_thin", "-o", tmp_path / "yarn.xml", "--format", "xml")
    assert r.returncode == 0, r.stderr
    from ipm.render.variant import mitsuba

    mi = mitsuba()
    scene = mi.load_file(str(tmp_path / "yarn.xml"))
    assert np.array(mi.render(scene, spp=1)).shape == (150, 500, 3)


def test_cli_render_bad_input_one_line_exit_2(tmp_path):
    keep = tmp_path / "yarn.png"
    keep.write_bytes(b"precious")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({**preset("rose").to_dict(), "n": 9}))
    not_a_folder = tmp_path / "file"
    not_a_folder.write_text("x")
    cases = [(("render", bad, "-o", keep), "n = 9"),
             (("render", "--preset", "rose", "-o", not_a_folder / "y.png"), "does not exist"),
             (("render", "--preset", "rose", "-o", keep, "--variant", "llvm_rgb"),
              "unknown Mitsuba variant")]
    for args, message in cases:
        r = ipm(*args)
        assert r.returncode == 2, (args, r.stderr)
        assert r.stderr.count("\n") == 1 and message in r.stderr, r.stderr
    assert keep.read_bytes() == b"precious"


def test_cli_doctor():
    r = ipm("doctor")
    assert r.returncode == 0
    assert "llvm_ad_rgb  renders" in r.stdout and "libLLVM" in r.stdout and "torch" in r.stdout


def _straight_fibers(ys_mm: list[float], radius_mm: float) -> FiberSet:
    """Straight fibers along the generator axis z (the image's horizontal), at generator
    x = y_mm (the image's vertical), built here without the generator."""
    z = np.linspace(-8.0, 8.0, 9)
    points = np.concatenate([np.column_stack([np.full_like(z, y), np.zeros_like(z), z])
                             for y in ys_mm]).astype(np.float32)
    k = len(ys_mm)
    return FiberSet(points, np.arange(k + 1, dtype=np.int64) * len(z),
                    np.full((k, 2), radius_mm, np.float32), np.zeros(k, np.uint8),
                    np.zeros(k, np.int16))


def test_backlit_setup_is_a_grey_translucent_silhouette_on_the_panel():
    """The backlit scene, measured on straight fibers placed by hand: the background is the
    panel's radiance; a fiber lets about ``1 - opacity`` of it through (plus the little light
    it reflects), and two fibers one behind the other about ``(1 - opacity)^2``; a yarn
    render is grey and its record names the setup."""
    from ipm.render.scene import setup_options

    opts = setup_options("backlit")
    r = Renderer(options=opts)
    scale = 0.5  # 0.02 mm per pixel: a 0.1 mm thick fiber covers 5 rows
    fibers = _straight_fibers([0.0], 0.05)
    image = r.render_fibers(fibers, (0.6, 0.3, 0.2), scale, spp=16).mean(-1)
    h = image.shape[0]
    panel = np.median(image[:10])
    assert abs(panel - opts.panel) < 0.02 * opts.panel
    centre = image[h // 2 - 1:h // 2 + 1, 50:-50].mean() / panel
    assert 1 - opts.opacity <= centre <= 1 - opts.opacity + 0.15, centre
    # a second fiber behind the first (generator y is the depth axis: world z)
    pair = FiberSet(*(np.concatenate(a) for a in (
        [fibers.points, fibers.points + np.float32([0, -0.3, 0])],
        [fibers.offsets, fibers.offsets[1:] + fibers.offsets[-1]],
        [fibers.radii] * 2, [fibers.kind] * 2, [fibers.ply] * 2)))
    both = r.render_fibers(pair, (0.6, 0.3, 0.2), scale, spp=16).mean(-1)
    centre2 = both[h // 2 - 1:h // 2 + 1, 50:-50].mean() / panel
    assert (1 - opts.opacity) ** 2 <= centre2 < centre - 0.1, (centre2, centre)
    # a yarn: grey, its core a dark band as thick as the parameters say (few flyaways)
    p = preset("golden").replace(g=30)
    yarn = r.render(p, seed=0, scale=0.25, spp=4, photometric=PhotometricRanges().draw(
        np.random.default_rng(0)))
    assert np.array_equal(yarn[..., 0], yarn[..., 1]) and np.array_equal(yarn[..., 1],
                                                                          yarn[..., 2])
    lum = yarn[..., 0]
    rows = np.flatnonzero((lum < 0.5 * np.median(lum[:4])).mean(1) > 0.5)
    assert len(rows) and rows.max() - rows.min() + 1 == len(rows)
    px = pixel_size_mm(0.25)
    lo, hi = 2 * (p.R_ply + p.r_y) / px, 2 * (p.R_ply + p.r_x) / px
    assert 0.85 * lo <= len(rows) <= 1.1 * hi, (len(rows), lo, hi)
    assert r.settings(0.25, 4, 0)["setup"] == "backlit"


def test_look_variations_are_off_unless_asked_and_leave_the_other_draws_alone():
    """--vary-look draws its variations after the others, so a dataset made without them
    keeps every earlier value, and its settings record nothing new."""
    from ipm.render.dataset import GenerateOptions
    from ipm.render.photometric import LAMPS, LOOK

    plain = PhotometricRanges().draw(np.random.default_rng(3))
    varied = PhotometricRanges(look=True).draw(np.random.default_rng(3))
    assert (plain.light_gain, plain.blur_mm, plain.gamma, plain.jpeg_quality) == (1, 0, 1, 0)
    assert (plain.lamp_turn_deg, plain.lamp_tilt_deg, plain.fill_share) == (0, 0, 0)
    assert replace(varied, **{k: getattr(plain, k) for k in {**LOOK, **LAMPS}}) == plain
    for k, (lo, hi) in {**LOOK, **LAMPS}.items():
        if k != "jpeg_quality":
            assert lo <= getattr(varied, k) <= hi, k
    for k in ("exposure_stops", "white_balance", "shift_mm", "noise", "noise_seed"):
        assert getattr(varied, k) == getattr(plain, k), k
    settings = GenerateOptions(count=1).settings()
    assert "look" not in settings["photometric"] and "setup" not in settings["scene"]
    assert GenerateOptions(count=1, photometric=PhotometricRanges(look=True)).settings()[
        "photometric"]["look"] is True


def test_material_variations_are_drawn_after_the_look_and_off_unless_asked():
    """--vary-material draws after --vary-look's lights, card and image, so those of a
    dataset made without it stay (the frontlit lamps' places come last of all, so that
    backlit datasets made before them keep their material); its values lie in their ranges
    and its setting is recorded only when on."""
    from ipm.render.dataset import GenerateOptions
    from ipm.render.photometric import LAMPS, MATERIAL

    look = PhotometricRanges(look=True).draw(np.random.default_rng(4))
    both = PhotometricRanges(look=True, material=True).draw(np.random.default_rng(4))
    assert (look.fiber_opacity, look.room_gain) == (0.0, 1.0)
    assert replace(both, **{k: getattr(look, k) for k in {**MATERIAL, **LAMPS}}) == look
    for k, (lo, hi) in MATERIAL.items():
        assert lo <= getattr(both, k) <= hi, k
    assert "material" not in GenerateOptions(count=1).settings()["photometric"]
    assert GenerateOptions(count=1, photometric=PhotometricRanges(material=True)).settings()[
        "photometric"]["material"] is True


@pytest.mark.slow
def test_fiber_opacity_sets_what_one_fiber_lets_through_and_the_scene_resets():
    """A fiber of opacity o in front of the panel passes 1 - o of its light, whatever the
    scene's own opacity; the room light greys it; the next render is the scene's again."""
    from ipm.render.scene import setup_options

    opts = setup_options("backlit")
    r = Renderer(options=opts)
    fibers = _straight_fibers([0.0], 0.05)

    def through(**look) -> float:
        image = r.render_fibers(fibers, (0.3, 0.3, 0.3), 0.5, spp=16,
                                look=Photometric(**look)).mean(-1)
        h = image.shape[0]
        return float(image[h // 2 - 1:h // 2 + 1, 50:-50].mean() / np.median(image[:10]))

    nominal = through()
    for o in (0.25, 0.85):
        assert 1 - o <= through(fiber_opacity=o) <= 1 - o + 0.12, o
    assert through(room_gain=4.0) > nominal + 0.02
    assert through() == pytest.approx(nominal, abs=1e-6)


def test_soft_boxes_turn_and_tilt_about_the_yarn_keeping_their_distance():
    """Measured on the returned centres by their own angles: the azimuth about the view
    direction moves by the turn, the angle above the image plane by the tilt (held within
    5-85 degrees), the distance stays; untouched, the centres are the scene's exactly."""
    from ipm.render.scene import SOFT_BOXES, soft_boxes

    nominal = SceneOptions()
    assert [c for _, c, _, _ in soft_boxes(nominal)] == [c for _, c, _ in SOFT_BOXES]
    assert [r for *_, r in soft_boxes(nominal)] == [nominal.key_light, 0.6 * nominal.key_light]

    def angles(c):
        c = np.asarray(c)
        return (np.degrees(np.arctan2(c[1], c[0])), np.degrees(np.arcsin(c[2] / np.linalg.norm(c))),
                np.linalg.norm(c))

    for turn, tilt in ((90.0, 0.0), (-30.0, 20.0), (0.0, -25.0), (10.0, 60.0)):
        moved = soft_boxes(replace(nominal, lamp_turn=turn, lamp_tilt=tilt, fill_share=0.3))
        assert moved[1][3] == pytest.approx(0.3 * nominal.key_light)
        for (_, c0, _), (_, c1, _, _) in zip(SOFT_BOXES, moved, strict=True):
            (az0, el0, d0), (az1, el1, d1) = angles(c0), angles(c1)
            assert (az1 - az0 - turn + 180) % 360 - 180 == pytest.approx(0, abs=1e-9)
            assert el1 == pytest.approx(min(max(el0 + tilt, 5), 85), abs=1e-9)
            assert d1 == pytest.approx(d0)
    with pytest.raises(UserError, match="fill_share"):
        SceneOptions(fill_share=0.0)


def test_turned_lamps_light_the_side_of_a_fiber_they_face(renderer):
    """A thick straight fiber along the image's horizontal, its key lamp turned to stand
    below the yarn (+90 degrees from the scene's left: the lamps turn counter-clockwise) and
    then above it (-90), lowered towards the image plane, the second lamp dimmed: the
    fiber's lower half is the brighter one, then its upper half; the next render without a
    look is the scene's again."""
    fibers = _straight_fibers([0.0], 0.3)

    def halves(**look) -> tuple[float, float]:
        image = renderer.render_fibers(fibers, (0.6, 0.6, 0.6), 0.5, spp=16,
                                       look=Photometric(**look)).mean(-1)
        h = image.shape[0]
        band = image[:, 100:-100].mean(1)
        return float(band[h // 2 - 4:h // 2 - 1].mean()), float(band[h // 2 + 2:h // 2 + 5].mean())

    base = renderer.render_fibers(fibers, (0.6, 0.6, 0.6), 0.5, spp=16)
    up, down = halves(lamp_turn_deg=90.0, lamp_tilt_deg=-25.0, fill_share=0.1)
    assert down > 1.3 * up, (up, down)
    up, down = halves(lamp_turn_deg=-90.0, lamp_tilt_deg=-25.0, fill_share=0.1)
    assert up > 1.3 * down, (up, down)
    assert np.array_equal(renderer.render_fibers(fibers, (0.6, 0.6, 0.6), 0.5, spp=16), base)


def test_look_variations_act_on_scene_and_image(renderer):
    """Lamps 1.5x brighten the yarn about 1.5x, a card 3x as light lifts the background
    about 3x; vignetting darkens the corners by its amount, defocus removes fine detail, a
    tone curve below 1 lifts the mid-tones and JPEG changes the bytes only a little."""
    from ipm.render.photometric import encode

    p = preset("golden").replace(g=30)
    base = renderer.render(p, 0, 0.2, 8).mean(-1)
    lamps = renderer.render(p, 0, 0.2, 8, photometric=Photometric(light_gain=1.5)).mean(-1)
    card = renderer.render(p, 0, 0.2, 8, photometric=Photometric(backdrop_gain=3.0)).mean(-1)
    h = base.shape[0]
    core = slice(h // 2 - 3, h // 2 + 3)
    assert 1.35 < lamps[core].mean() / base[core].mean() < 1.6
    assert 2.5 < np.median(card[:5]) / np.median(base[:5]) < 3.2
    assert np.array_equal(renderer.render(p, 0, 0.2, 8).mean(-1), base)  # the scene resets
    flat = np.full((60, 100, 3), 0.5, np.float32)
    vign = apply_to_image(flat, Photometric(vignetting=0.3))
    assert vign[0, 0, 0] == pytest.approx(0.5 * 0.7, rel=0.02) and vign[30, 50, 0] > 0.49
    sharp = renderer.render(p, 0, 0.2, 8)
    blurred = apply_to_image(sharp, Photometric(blur_mm=0.05), pixel_size_mm=0.05)
    assert np.abs(np.diff(blurred, axis=1)).mean() < 0.6 * np.abs(np.diff(sharp, axis=1)).mean()
    mid = np.full((8, 8, 3), 0.2, np.float32)
    assert encode(mid, Photometric(gamma=0.8)).mean() > encode(mid, NOMINAL).mean() + 10
    jpeg = encode(sharp, Photometric(jpeg_quality=70)).astype(float)
    png = encode(sharp, NOMINAL).astype(float)
    assert not np.array_equal(jpeg, png) and np.abs(jpeg - png).mean() < 4
