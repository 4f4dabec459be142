"""The net-free photo analysis (ipm/textile/image.py, the yardstick of
benchmarks/photo_measures.py) on images built here."""

import numpy as np
import pytest

from ipm.textile.image import (
    core_diameter_px,
    fiber_width_px,
    hairiness,
    levelled,
    stripe_period_px,
    yarn_signal,
)


def striped_band(width_px=60.0, period_px=37.0, tilt_px=6.0, h=240, w=600):
    """A dark yarn of a given half-contrast width on a light panel: a flat-topped band with
    soft edges, tilted by ``tilt_px`` over the frame, with diagonal stripes of the period."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    axis = (h - 1) / 2 + tilt_px * (x / (w - 1) - 0.5)
    edge = np.abs(y - axis) - width_px / 2
    band = 1 / (1 + np.exp(edge / 2.0))  # 0.5 exactly at +-width/2
    stripes = 0.15 * np.cos(2 * np.pi * (x + 0.8 * (y - axis)) / period_px)
    return 0.8 - 0.6 * band * (0.85 + stripes)


def test_core_diameter_and_stripe_period_of_a_tilted_striped_band():
    img = striped_band()
    sig = levelled(yarn_signal(img, backlit=True))
    d = core_diameter_px(sig)
    assert d == pytest.approx(60.0, rel=0.03)
    assert stripe_period_px(sig, d) == pytest.approx(37.0, rel=0.02)


def test_no_stripes_no_period():
    img = striped_band()
    flat = 0.8 - 0.6 * (img < 0.6)  # the band without its stripes
    sig = levelled(yarn_signal(flat.astype(np.float64), backlit=True))
    assert np.isnan(stripe_period_px(sig, core_diameter_px(sig)))


def test_flyaway_fiber_width():
    """Curved dark fibers 7 px wide (half contrast) above and below a yarn band."""
    img = striped_band(h=400, w=800)
    y, x = np.mgrid[0:400, 0:800].astype(np.float64)
    for y0, amp in ((60.0, 20.0), (330.0, 15.0)):
        dist = np.abs(y - (y0 + amp * np.sin(x / 90.0)))
        img -= 0.4 / (1 + np.exp((dist - 3.5) / 0.6))
    sig = levelled(yarn_signal(img, backlit=True))
    width, support = fiber_width_px(sig, core_diameter_px(sig))
    assert support > 500
    assert width == pytest.approx(7.0, abs=1.0)


def test_hairiness_counts_the_fibers_that_reach_each_distance_sharp_or_blurred():
    """16 straight fibers 4 px (0.02 mm) wide stand out of a 0.3 mm core over 4 mm of
    yarn at 0.005 mm per pixel: 8 above reaching 0.3 mm beyond its edge, 8 below reaching
    0.15 mm.  Per mm of yarn, both sides averaged: 2 at 0.05 and 0.1 mm, 1 at 0.2 mm, 0 at
    0.4 mm; a defocus blur of 3 px does not change the counts."""
    from scipy import ndimage

    pitch, h, w = 0.005, 360, 800
    img = striped_band(width_px=60.0, tilt_px=0.0, h=h, w=w)
    edge = 30.0
    for i in range(8):
        x = 50 + 100 * i
        img[round(h / 2 - edge - 0.3 / pitch): round(h / 2 - edge + 2), x: x + 4] -= 0.35
        img[round(h / 2 + edge - 2): round(h / 2 + edge + 0.15 / pitch), x + 20: x + 24] -= 0.35
    for image in (img, ndimage.gaussian_filter(img, 3.0)):
        counts = hairiness(image, pitch)
        assert [counts[d] for d in (0.05, 0.1, 0.2, 0.4)] == pytest.approx([2, 2, 1, 0],
                                                                           abs=0.15)


def test_real_photo_measures_in_mm_and_the_readme_ply_counts(tmp_path):
    """benchmarks/real_photos.py: the yardstick in mm at a photo's pixel size, and the ply
    counts read from the photos' README rows (only rows that state one)."""
    from ipm.benchmarks.real_photos import measures, readme_ply_counts

    d, period = measures(striped_band(), 0.002)
    assert d == pytest.approx(0.12, rel=0.03) and period == pytest.approx(0.074, rel=0.02)
    (tmp_path / "README.md").write_text(
        "| file | source | res | description |\n| --- | --- | --- | --- |\n"
        "| a.png | x | 1440x1080 | 2-ply spun yarn, ply twist visible |\n"
        "| b.png | x | 1440x1080 | thinner 2-ply spun yarn, long fibres |\n"
        "| c.png | x | 1440x1080 | spun yarn, ply count unclear (faint plied structure) |\n")
    assert readme_ply_counts(tmp_path) == {"a.png": 2, "b.png": 2}
    assert readme_ply_counts(tmp_path / "missing") == {}
