"""ipm calibrate on rulers drawn by the tests (tests/rulers.py), and on images with no scale."""

from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from rulers import ruler

from ipm.calibrate import Calibration, calibrate
from ipm.errors import UserError

ROOT = Path(__file__).resolve().parent.parent
REAL = ROOT.parent / "shared" / "real-yarns"


@pytest.mark.parametrize("pixel_size_mm, angle, size", [
    (0.0125, 0.0, (1200, 500)), (0.02, 7.0, (1200, 500)), (0.0085, -3.0, (1200, 500)),
    (0.04, 30.0, (1200, 500)), (0.005, 2.0, (1200, 500)), (0.01, 90.0, (500, 1200))])
def test_pixel_size_of_drawn_rulers(pixel_size_mm, angle, size):
    cal = calibrate(ruler(pixel_size_mm, angle, size), "ruler")
    assert cal.pixel_size_mm == pytest.approx(pixel_size_mm, rel=0.005)
    assert abs((cal.angle_deg - angle + 90) % 180 - 90) < 3.0  # a diagnostic: a bin is ~1 deg


def test_the_bundled_ruler_is_at_0_0125_mm_per_pixel():
    gray = np.asarray(Image.open(ROOT / "examples" / "ruler.png"), dtype=np.float64) / 255
    assert calibrate(gray, "ruler.png").pixel_size_mm == pytest.approx(0.0125, rel=0.005)


@pytest.mark.slow
def test_images_without_a_scale_are_refused():
    rng = np.random.default_rng(0)
    images = {"noise": rng.random((400, 900)), "grey": np.full((300, 1000), 0.5),
              "edge": np.tile((np.arange(900) > 450).astype(float), (400, 1))}
    images.update({p.name: np.asarray(Image.open(p), dtype=np.float64) / 255
                   for p in sorted(REAL.glob("*.png"))[:6]})
    for name, gray in images.items():
        with pytest.raises(UserError, match="no millimetre scale found"):
            calibrate(gray, name)


def test_calibration_file_roundtrip_and_bad_files(tmp_path):
    cal = calibrate(ruler(0.02), "r.png")
    (tmp_path / "c.json").write_text(cal.to_json())
    assert Calibration.load(tmp_path / "c.json") == cal
    (tmp_path / "bad.json").write_text('{"pixel_size_mm": -1}')
    for path in (tmp_path / "bad.json", tmp_path / "missing.json"):
        with pytest.raises(UserError):
            Calibration.load(path)
