"""The commands that use a fitted yarn and set a photo's scale (ipm edit, knit, curves
--format usd|ply, calibrate, and fit's pixel size), as a user runs them, bad input included:
one line, exit 2, no output file."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def ipm(*args):
    return subprocess.run([sys.executable, "-m", "ipm", *map(str, args)], capture_output=True,
                          text=True)


def one_line_error(r, words):
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], r.stderr


@pytest.fixture
def golden(tmp_path):
    assert ipm("sample", "--preset", "golden", "-o", tmp_path / "p.json").returncode == 0
    return tmp_path / "p.json"


def test_edit_sets_and_scales(golden, tmp_path):
    r = ipm("edit", golden, "--set", "alpha_ply=*0.5", "--set", "g=*2", "-o", tmp_path / "e.json")
    assert r.returncode == 0, r.stderr
    before, after = json.loads(golden.read_text()), json.loads((tmp_path / "e.json").read_text())
    assert after["alpha_ply"] == pytest.approx(before["alpha_ply"] / 2)
    assert after["g"] == 2 * before["g"]


@pytest.mark.parametrize("args, words", [
    (("--set", "twist=2"), "unknown parameter 'twist'"),
    (("--set", "alpha_ply=*100"), "outside its allowed range"),
    (("--set", "g=abc"), "not a number")])
def test_edit_bad_input(golden, tmp_path, args, words):
    one_line_error(ipm("edit", golden, *args, "-o", tmp_path / "e.json"), words)
    assert not (tmp_path / "e.json").exists()


@pytest.mark.parametrize("args, words", [
    (("--pattern", "moss"), "unknown pattern 'moss'"), (("--stitches", "8by6"), "WALESxCOURSES"),
    (("--stitches", "0x6"), "must be in 1-40"), (("--size", "10x10"), "must be in 16-8000")])
def test_knit_bad_input(golden, tmp_path, args, words):
    one_line_error(ipm("knit", golden, "-o", tmp_path / "k.png", *args), words)
    assert not (tmp_path / "k.png").exists() and not (tmp_path / "k.json").exists()


@pytest.mark.parametrize("fmt, name", [("usd", "y.usda"), ("ply", "y.ply")])
def test_curves_exports(golden, tmp_path, fmt, name):
    r = ipm("curves", golden, "-o", tmp_path / name, "--format", fmt)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / name).stat().st_size > 1000


def test_calibrate_the_bundled_ruler(tmp_path):
    r = ipm("calibrate", ROOT / "examples" / "ruler.png", "-o", tmp_path / "c.json")
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "c.json").read_text())["pixel_size_mm"] == \
        pytest.approx(0.0125, rel=0.005)


def test_calibrate_refuses_an_image_without_a_scale(tmp_path):
    one_line_error(ipm("calibrate", ROOT / "examples" / "golden.png", "-o", tmp_path / "c.json"),
                   "no millimetre scale found")
    assert not (tmp_path / "c.json").exists()


def test_fit_needs_a_pixel_size(tmp_path):
    photo = tmp_path / "yarn.png"
    shutil.copy(ROOT / "examples" / "golden.png", photo)  # without its sidecar
    one_line_error(ipm("fit", photo, "--out", tmp_path / "fit"), "pixel size is unknown")
    assert not (tmp_path / "fit").exists()
    (tmp_path / "bad.json").write_text("{}")
    one_line_error(ipm("fit", photo, "--calibration", tmp_path / "bad.json", "--out",
                       tmp_path / "fit"), "not an ipm calibration file")


def test_every_command_that_reads_a_photo_needs_its_pixel_size(tmp_path):
    """No silent default anywhere: predict, saliency and compare (a folder of photos) refuse
    a photo without --pixel-size, calibration or sidecar in one line."""
    photos = tmp_path / "photos"
    photos.mkdir()
    shutil.copy(ROOT / "examples" / "golden.png", photos / "yarn.png")  # without its sidecar
    for args in (("predict", photos / "yarn.png"),
                 ("saliency", photos / "yarn.png", "--param", "n", "-o", tmp_path / "s.png"),
                 ("compare", photos, "--out", tmp_path / "cmp")):
        one_line_error(ipm(*args), "yarn.png: its pixel size is unknown")
    assert not (tmp_path / "cmp").exists() and not (tmp_path / "s.png").exists()
    one_line_error(ipm("predict", photos / "missing.png"), "missing.png: no such file")


@pytest.mark.slow
def test_a_photo_is_read_at_its_sidecars_pixel_size(tmp_path):
    photos = tmp_path / "photos"
    photos.mkdir()
    shutil.copy(ROOT / "examples" / "golden.png", photos / "yarn.png")
    (photos / "yarn.json").write_text(json.dumps({"pixel_size_mm": 0.02}))
    # the sidecar it reads is an input: not overwritten by the prediction
    one_line_error(ipm("predict", photos / "yarn.png", "-o", photos / "yarn.json"),
                   "is an input of this command")
    r = ipm("predict", photos / "yarn.png")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout) == json.loads(ipm("predict", ROOT / "examples" / "golden.png",
                                                  "--pixel-size", "0.02").stdout)


@pytest.mark.slow
def test_fit_a_backlit_photo_with_frontlit_nets_is_one_line(tmp_path):
    """`--setup backlit` reads the photo as backlit and asks for backlit nets: the frontlit
    ones are refused in one line, before any folder is made; an unknown setup too."""
    from ipm.nets.ensemble import SHIPPED

    one_line_error(ipm("fit", ROOT / "examples" / "golden.png", "--setup", "backlit",
                       "--models", SHIPPED, "--out", tmp_path / "fit"),
                   "trained on frontlit renders, not backlit")
    assert not (tmp_path / "fit").exists()
    one_line_error(ipm("fit", ROOT / "examples" / "golden.png", "--setup", "sideways",
                       "--out", tmp_path / "fit"), "unknown capture setup 'sideways'")


@pytest.mark.slow
def test_a_pixel_size_in_the_wrong_unit_is_refused_before_any_allocation():
    """8.5 (micrometres typed as mm) would resample the bundled photo to gigapixels (the code
    before grew to 24 GB in 12 s).  The call runs under a wrapper that reports its own
    child's peak memory, so earlier tests' processes do not count."""
    measured = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:]); "
                "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); "
                "sys.exit(r.returncode)")
    r = subprocess.run([sys.executable, "-c", measured, sys.executable, "-m", "ipm", "predict",
                        str(ROOT / "examples" / "golden.png"), "--pixel-size", "8.5"],
                       capture_output=True, text=True)
    *lines, peak_kib = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and "is the pixel size in mm?" in lines[0]
    assert int(peak_kib) < 1_000_000  # the refused call stays under 1 GB


def test_photos_without_a_yarn_are_refused(tmp_path):
    from PIL import Image

    Image.new("RGB", (1000, 300), (128, 128, 128)).save(tmp_path / "grey.png")
    Image.new("RGBA", (1000, 300), (200, 150, 40, 0)).save(tmp_path / "clear.png")
    for name in ("grey.png", "clear.png"):
        one_line_error(ipm("predict", tmp_path / name, "--pixel-size", "0.02"), "no yarn found")


@pytest.mark.slow
def test_a_vertical_yarn_is_turned(tmp_path):
    """The bundled photo turned upright and padded to a square: the same yarn, said so."""
    import numpy as np
    from PIL import Image

    img = np.asarray(Image.open(ROOT / "examples" / "golden.png").convert("RGB"))
    upright = np.ascontiguousarray(np.rot90(img, -1))  # 300 x 1000 -> 1000 x 300, vertical
    square = np.empty((1000, 1000, 3), np.uint8)
    square[:] = np.median(img[0], axis=0)
    square[:, 350:650] = upright
    Image.fromarray(square).save(tmp_path / "vertical.png")
    r = ipm("predict", tmp_path / "vertical.png", "--pixel-size", "0.02")
    assert r.returncode == 0 and "turned by 90 degrees" in r.stderr, r.stderr
    h = ipm("predict", ROOT / "examples" / "golden.png", "--pixel-size", "0.02")
    turned, straight = json.loads(r.stdout), json.loads(h.stdout)
    assert turned["n"] == straight["n"]
    assert turned["R_ply"] == pytest.approx(straight["R_ply"], rel=0.15)


def test_render_writes_png_only(golden, tmp_path):
    one_line_error(ipm("render", golden, "-o", tmp_path / "x.jpg"), "writes PNG images")
    assert not list(tmp_path.glob("x.*"))


@pytest.mark.slow
def test_render_on_a_white_card(golden, tmp_path):
    import numpy as np
    from skimage.io import imread

    def card_level(*args):
        out = tmp_path / f"c{len(args)}.png"
        r = ipm("render", golden, "-o", out, "--scale", "0.1", "--spp", "4", *args)
        assert r.returncode == 0, r.stderr
        assert json.loads(out.with_suffix(".json").read_text())["scene"]["backdrop"] == (
            float(args[1]) if args else 0.03)
        return float(np.median(imread(out)[:4, :, :3]))  # the top rows: the card

    dark, white = card_level(), card_level("--card", "1")
    assert white > 150 and dark < 60, (dark, white)
    one_line_error(ipm("render", golden, "-o", tmp_path / "b.png", "--setup", "backlit",
                       "--card", "1"), "light panel")
    assert not (tmp_path / "b.png").exists()


def test_unknown_parameter_keys_are_named(golden, tmp_path):
    d = json.loads(golden.read_text())
    d["twsit"] = 3
    (tmp_path / "typo.json").write_text(json.dumps(d))
    r = ipm("curves", tmp_path / "typo.json", "-o", tmp_path / "y.npz")
    assert r.returncode == 0 and "warning: ignored unknown parameter(s): twsit" in r.stderr


@pytest.mark.slow
def test_a_late_fit_error_leaves_no_empty_folder(tmp_path):
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "ensemble.json").write_text("{not json")
    r = ipm("fit", ROOT / "examples" / "golden.png", "--models", tmp_path / "models",
            "--out", tmp_path / "fit")
    assert r.returncode == 2, r.stderr
    assert not (tmp_path / "fit").exists()


@pytest.mark.slow
def test_fit_without_refine_drops_an_earlier_refined_render(tmp_path):
    out = tmp_path / "fit"
    out.mkdir()
    (out / "refined.png").write_bytes(b"from an earlier fit")
    r = ipm("fit", ROOT / "examples" / "golden.png", "--out", out)
    assert r.returncode == 0, r.stderr
    assert (out / "params.json").is_file() and not (out / "refined.png").exists()


@pytest.mark.slow
def test_compare_reports_an_unreadable_photo_and_goes_on(tmp_path):
    photos = tmp_path / "photos"
    photos.mkdir()
    shutil.copy(ROOT / "examples" / "golden.png", photos / "a.png")
    (photos / "b.png").write_bytes(b"not an image")
    r = ipm("compare", photos, "--out", tmp_path / "cmp", "--pixel-size", "0.02", "--budget", 4)
    assert r.returncode == 1, r.stderr  # every good photo fitted, the bad one listed
    assert "not fitted" in r.stderr and "b.png" in r.stderr
    report = (tmp_path / "cmp" / "index.md").read_text()
    assert "a.png" in report and "b.png" in report
