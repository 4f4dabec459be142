"""``ipm measure`` (ipm/textile) on images built here with known answers: the twist
direction of a helix projected by the test's own camera, H of drawn fibers of known length,
the diameter's CV of a band of known widths, and the command's files and refusals."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from ipm.textile.image import measure_photo


def helix_photo(handed: int, plies: int = 2, radius_px: float = 40.0, pitch_px: float = 300.0,
                h: int = 300, w: int = 900, fibers: bool = True) -> np.ndarray:
    """A frontlit (light on dark) photo of ``plies`` round plies on a helix of the given
    handedness (+1 right: Z), projected by this test's own camera: the helix axis to the
    right, the helix's x up, the camera on its +y side (right, up, towards the camera form a
    right-handed frame); only the surface facing the camera is drawn, each ply's pixels
    shaded by how squarely they face it, with fine random stripes of surface fibers slanting
    the other way."""
    r_ply = radius_px / 2  # plies touching at the axis
    t = np.linspace(0, 2 * np.pi * w / pitch_px, 4 * w)
    phi = np.linspace(0, 2 * np.pi, 120, endpoint=False)
    cols, rows, depths, shades = [], [], [], []
    for k in range(plies):
        theta = handed * t + 2 * np.pi * k / plies
        # the ply's surface: circles of radius r_ply about its centre line, across the axis
        x = (r_ply * np.cos(theta))[:, None] + r_ply * np.cos(phi)[None, :]
        y = (r_ply * np.sin(theta))[:, None] + r_ply * np.sin(phi)[None, :]
        cols.append(np.broadcast_to((t * pitch_px / (2 * np.pi))[:, None], x.shape).ravel())
        rows.append(((h - 1) / 2 - x).ravel())
        depths.append(y.ravel())
        shades.append(np.broadcast_to(np.sin(phi)[None, :], x.shape).ravel())
    col, row = (np.round(np.concatenate(v)).astype(int) for v in (cols, rows))
    depth, shade = np.concatenate(depths), np.concatenate(shades)
    ok = (col >= 0) & (col < w) & (row >= 0) & (row < h)
    col, row, depth, shade = col[ok], row[ok], depth[ok], shade[ok]
    nearest = np.argsort(-depth, kind="stable")  # the camera sees the nearest point
    pixel = (row * w + col)[nearest]
    _, first = np.unique(pixel, return_index=True)
    img = np.zeros(h * w)
    img[pixel[first]] = 0.15 + 0.7 * np.maximum(shade[nearest][first], 0.0)
    # the surface fibers: fine stripes slanting 20 degrees against the plies
    if not fibers:
        return img.reshape(h, w)
    from scipy import ndimage

    y, x = np.mgrid[0:h, 0:w].astype(float)
    across = y + handed * x * np.tan(np.radians(20))  # constant along a fiber
    noise = ndimage.gaussian_filter1d(np.random.default_rng(0).standard_normal(2 * (h + w)), 1.0)
    fibers = 0.75 + 0.25 * np.clip(noise[np.round(across).astype(int) + w] / noise.std(), -1, 1)
    return img.reshape(h, w) * fibers


def test_twist_direction_of_helices_seen_by_our_own_camera():
    """A right-handed ply helix is Z, a left-handed one S (the letters' middle strokes with
    the yarn upright), two to four plies, whatever the surface fibers' slant; without them,
    the ply period and turns per metre too."""
    for plies in (2, 3, 4):
        for handed, letter in ((1, "Z"), (-1, "S")):
            m = measure_photo(helix_photo(handed, plies), 0.01, backlit=False, plies=plies)
            assert m.twist_direction == letter, (plies, handed, m.twist_slant)
            bare = measure_photo(helix_photo(handed, plies, fibers=False), 0.01, False, plies)
            assert bare.twist_direction == letter
            assert bare.ply_period_mm == pytest.approx(3.0 / plies, rel=0.1)
            assert bare.ply_twist_tpm == pytest.approx(1000 / 3.0, rel=0.1)


def band(h=400, w=1000, width=(60.0,), pitch=0.01):
    """A dark band on a light panel (backlit) whose width steps through ``width`` (px) in
    equal runs along it."""
    y = np.arange(h)[:, None].astype(float)
    widths = np.repeat(np.asarray(width), math.ceil(w / len(width)))[:w][None, :]
    inside = np.abs(y - (h - 1) / 2) < widths / 2
    return np.where(inside, 0.2, 0.8)


def test_diameter_and_its_cv_of_a_band_of_two_widths():
    """Runs of 50 and 70 px (0.5 and 0.7 mm) of 300 px each, windows of 30 px: the
    diameter's profile follows the runs, its CV that of the runs."""
    widths = [50.0, 70.0] * 5
    img = band(w=3000, width=widths)
    m = measure_photo(img, 0.01, backlit=True)
    prof = np.asarray(m.diameter_profile_mm)
    assert len(prof) == 100
    assert np.median(np.abs(prof - np.repeat([0.5, 0.7] * 5, 10))) < 0.015
    truth_cv = 100 * np.std([0.5, 0.7]) / 0.6
    assert m.diameter_cv_pct == pytest.approx(truth_cv, rel=0.15)


def test_hairiness_h_is_the_length_of_fiber_beyond_the_core_per_length():
    """Straight dark fibers of known lengths and angles drawn out of a 0.6 mm core over 10
    mm of yarn at 0.005 mm per pixel (3 px wide, at 30-90 degrees to the axis): H is their
    projected length beyond the core's edge per mm, within 10%, sharp or blurred."""
    from scipy import ndimage

    pitch, h, w = 0.005, 700, 2000
    img = band(h=h, w=w, width=(120.0,))
    edge = 60.0
    drawn = []
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    rng = np.random.default_rng(3)
    for i in range(12):
        x0 = 80 + 160 * i
        side = 1 if i % 2 else -1
        length = rng.uniform(40, 200)  # px beyond the edge
        angle = math.radians(rng.uniform(30, 90))
        y0 = (h - 1) / 2 + side * edge
        x1, y1 = x0 + length * math.cos(angle), y0 + side * length * math.sin(angle)
        # distance of every pixel to the segment
        px, py = xx - x0, yy - y0
        dx, dy = x1 - x0, y1 - y0
        u = np.clip((px * dx + py * dy) / (dx * dx + dy * dy), 0, 1)
        dist = np.hypot(px - u * dx, py - u * dy)
        img = np.where(dist < 1.5, 0.25, img)
        drawn.append(length * pitch)
    truth = sum(drawn) / (w * pitch)
    for image in (img, ndimage.gaussian_filter(img, 1.0)):
        m = measure_photo(image, pitch, backlit=True)
        assert m.hairiness_h == pytest.approx(truth, rel=0.1)
        assert len(m.hair_lengths_mm) == 12
        # each piece is counted from 2 px of 0.01 mm beyond the core's edge, and a
        # skeleton stops short of its fiber's ends
        assert sorted(m.hair_lengths_mm) == pytest.approx(sorted(drawn), rel=0.1, abs=0.05)


def ipm(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "ipm", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd)


def test_measure_a_folder_writes_each_photo_and_a_report_and_lists_the_bad(tmp_path):
    """Two good photos and one that is not an image: JSON and drawing for each good one, a
    CSV and plots for the folder, the bad one in one line, exit 1; the photos' sidecars are
    not written over."""
    photos = tmp_path / "photos"
    photos.mkdir()
    for name in ("a", "b"):
        Image.fromarray(np.round(band(w=600) * 255).astype(np.uint8)).save(photos / f"{name}.png")
    (photos / "c.png").write_text("not an image")
    out = tmp_path / "out"
    r = ipm("measure", photos, "--pixel-size", "0.01", "--setup", "backlit", "-o", out)
    assert r.returncode == 1, r.stderr
    assert [ln for ln in r.stderr.splitlines() if ln.startswith("error:")] == [
        f"error: {photos / 'c.png'} is not an image Pillow can read"]
    for name in ("a", "b"):
        d = json.loads((out / f"{name}.json").read_text())
        assert d["diameter_mm"] == pytest.approx(0.6, rel=0.05)
        assert (out / f"{name}.png").stat().st_size > 0
    rows = (out / "measures.csv").read_text().splitlines()
    assert rows[0].startswith("photo,") and len(rows) == 3
    assert (out / "measures.png").stat().st_size > 0
    (photos / "c.png").unlink()
    (photos / "a.json").write_text(json.dumps({"pixel_size_mm": 0.01}))
    r = ipm("measure", photos, "--setup", "backlit", "-o", photos)
    assert r.returncode == 2 and "is an input of this command" in r.stderr
