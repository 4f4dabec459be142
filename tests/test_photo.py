"""ipm.photo: every common still-image flavour decodes to (H, W, 3) float32 sRGB in [0, 1];
bad files are one-line UserErrors; rescaling lands on the scene's pixel pitch."""

import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from ipm.errors import UserError
from ipm.photo import (
    MAX_PIXELS,
    Photo,
    linear_to_srgb,
    read_image,
    srgb_to_linear,
    to_scene_pitch,
)

RGB = np.random.default_rng(0).integers(0, 256, (30, 40, 3), dtype=np.uint8)


def save(tmp_path, name, img: Image.Image, **kw):
    path = tmp_path / name
    img.save(path, **kw)
    return path


@pytest.mark.parametrize("name, make", [
    ("rgb.png", lambda: Image.fromarray(RGB)),
    ("rgb.jpg", lambda: Image.fromarray(RGB)),
    ("rgb.tif", lambda: Image.fromarray(RGB)),
    ("gray.png", lambda: Image.fromarray(RGB[..., 0])),
    ("gray16.png", lambda: Image.fromarray(RGB[..., 0].astype(np.uint16) * 257)),
    ("gray16.tif", lambda: Image.fromarray(RGB[..., 0].astype(np.uint16) * 257)),
    ("rgba.png", lambda: Image.fromarray(np.dstack([RGB, np.full((30, 40), 255, np.uint8)]))),
    ("palette.png", lambda: Image.fromarray(RGB).convert("P")),
    ("la.png", lambda: Image.fromarray(RGB[..., 0]).convert("LA")),
    ("bw.png", lambda: Image.fromarray(RGB[..., 0] > 128)),
    ("cmyk.jpg", lambda: Image.fromarray(RGB).convert("CMYK")),
])
def test_read_image_flavours(tmp_path, name, make):
    img = read_image(save(tmp_path, name, make()))
    assert img.shape == (30, 40, 3) and img.dtype == np.float32
    assert 0 <= img.min() and img.max() <= 1


def test_read_image_values(tmp_path):
    np.testing.assert_allclose(read_image(save(tmp_path, "a.png", Image.fromarray(RGB))),
                               RGB / 255, atol=1e-6)
    g16 = RGB[..., 0].astype(np.uint16) * 257
    np.testing.assert_allclose(read_image(save(tmp_path, "b.png", Image.fromarray(g16)))[..., 1],
                               g16 / 65535, atol=1e-6)


def write_png16(path, a: np.ndarray) -> None:
    """A 16-bit RGB(A) PNG (Pillow cannot write one)."""
    h, w, c = a.shape
    raw = b"".join(b"\x00" + a[y].astype(">u2").tobytes() for y in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    ihdr = struct.pack(">IIBBBBB", w, h, 16, {3: 2, 4: 6}[c], 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
                     + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


@pytest.mark.parametrize("alpha", [False, True])
def test_16bit_colour(tmp_path, alpha):
    a = (np.random.default_rng(2).random((30, 40, 3)) * 65535).astype(np.uint16)
    if alpha:
        a = np.dstack([a, np.full((30, 40), 65535, np.uint16)])
    write_png16(tmp_path / "c.png", a)
    # Pillow reads 16-bit colour at 8-bit precision; the nets see 8-bit renders anyway.
    np.testing.assert_allclose(read_image(tmp_path / "c.png"), a[..., :3] / 65535, atol=1 / 255)


def test_alpha_composited_over_black(tmp_path):
    rgba = np.zeros((4, 4, 4), np.uint8)
    rgba[..., :3] = 200
    rgba[..., 3] = 0
    rgba[0, 0, 3] = 255
    img = read_image(save(tmp_path, "t.png", Image.fromarray(rgba)))
    assert img[0, 0, 0] == pytest.approx(200 / 255) and img[1, 1].max() == 0


def test_exif_orientation_applied(tmp_path):
    exif = Image.Exif()
    exif[0x0112] = 6  # rotate 90 degrees clockwise on display
    path = tmp_path / "r.jpg"
    Image.fromarray(RGB).save(path, exif=exif)
    assert read_image(path).shape == (40, 30, 3)


@pytest.mark.parametrize("setup, message", [
    (lambda p: p.write_text("not an image"), "is not an image"),
    (lambda p: p.write_bytes(b""), "is not an image"),
    (lambda p: None, "no such file"),
    (lambda p: p.mkdir(), "is a folder"),
])
def test_bad_files(tmp_path, setup, message):
    path = tmp_path / "x.png"
    setup(path)
    with pytest.raises(UserError, match=message):
        read_image(path)


def test_truncated_file(tmp_path):
    path = save(tmp_path, "full.png", Image.fromarray(RGB))
    data = path.read_bytes()
    cut = tmp_path / "cut.png"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(UserError, match="cannot decode"):
        read_image(cut)
    cut.write_bytes(save(tmp_path, "f.jpg", Image.fromarray(RGB)).read_bytes()[:300])
    with pytest.raises(UserError, match="cannot decode"):
        read_image(cut)


def test_huge_refused_before_decoding(tmp_path):
    path = save(tmp_path, "big.png", Image.new("1", (200, 100)))
    with pytest.raises(UserError, match="too large"):
        read_image(path, max_pixels=10_000)
    assert MAX_PIXELS >= 100_000_000


def test_to_scene_pitch_sizes():
    img = np.random.default_rng(1).random((600, 2000, 3), dtype=np.float32)
    assert to_scene_pitch(img, 0.01, 0.25).shape == (150, 500, 3)
    assert to_scene_pitch(img, 0.02, 0.25).shape == (300, 1000, 3)  # upsampled
    assert to_scene_pitch(img, 0.01, 1.0).shape == img.shape
    mean = to_scene_pitch(img, 0.01, 0.1).mean()
    assert mean == pytest.approx(img.mean(), abs=1e-3)  # box filter keeps the mean
    with pytest.raises(UserError, match="pixel size"):
        to_scene_pitch(img, 0.0)


def test_photo_min_size(tmp_path):
    """A view smaller than MIN_VIEW_MM is refused in one line naming the pixels needed."""
    photo = Photo.read(save(tmp_path, "a.png", Image.fromarray(RGB)), 0.01)  # 0.4 x 0.3 mm
    assert photo.at_pitch(1.0).shape == (30, 40, 3)
    with pytest.raises(UserError, match=r"a.png \(40x30 px\) is too small: .* shows 0.4 x "
                       r"0.3 mm .* at least 3 x 1 mm \(300x100 px\)"):
        photo.at_pitch(1.0, min_size=(30, 40))


def test_a_tight_crop_is_padded_across_and_kept_narrow_along():
    """The issue's example: 800x240 px at 0.0167 mm (13.3 x 4 mm, less than the nets'
    12 x 5.84 mm in height) is padded above and below with its background; a 4 mm wide
    photo stays 4 mm wide and gives one crop of its width."""
    from ipm.nets.data import centre_crops

    rng = np.random.default_rng(0)
    img = np.full((240, 800, 3), 0.1, np.float32) + 0.01 * rng.random((240, 800, 3), np.float32)
    img[100:140] = 0.8  # the yarn's core
    padded = Photo(img, 0.0167).at_pitch(0.25, (146, 300))
    assert padded.shape == (146, 334, 3)
    core = np.flatnonzero(padded[..., 0].mean(1) > 0.5)
    assert abs((core.min() + core.max()) / 2 - 72.5) < 1.5  # the yarn stays centred
    assert np.allclose(padded[:20], np.median(img[:24].reshape(-1, 3), 0), atol=0.006)
    narrow = Photo(img[:, :240], 0.0167).at_pitch(0.25, (146, 300))  # 4 mm of yarn
    assert narrow.shape == (146, 100, 3)
    assert centre_crops(narrow, (146, 300), 3).shape == (1, 3, 146, 100)


def test_photo_inverted_and_defocused():
    img = np.random.default_rng(0).random((20, 30, 3)).astype(np.float32)
    photo = Photo(img, 0.02)
    assert np.array_equal(photo.inverted().image, 1 - img)
    assert photo.inverted().pixel_size_mm == 0.02 and photo.setup == "frontlit"
    assert photo.defocused(0) is photo
    blurred = photo.defocused(0.04).image  # 2 px
    assert blurred.shape == img.shape and blurred.std() < img.std()


def test_srgb_round_trip():
    x = np.linspace(0, 1, 101, dtype=np.float32)
    np.testing.assert_allclose(linear_to_srgb(srgb_to_linear(x)), x, atol=1e-5)


@pytest.mark.parametrize("card", [0.004, 0.016, 0.2, 0.6])
def test_the_nets_read_any_card_as_the_scenes(card):
    # a yarn band (rows 40-60, a warm colour) with a few flyaways over a grey card of linear
    # level `card`; the nets' view brings the card to the scene's level, the yarn kept
    from ipm.setups import DEFAULT_SETUP, setup_of

    level = setup_of(DEFAULT_SETUP).card_linear
    rng = np.random.default_rng(1)
    yarn = np.array([0.35, 0.25, 0.15])
    linear = np.full((100, 300, 3), card) + rng.normal(0, card * 0.02, (100, 300, 3))
    linear[40:60] = yarn
    linear[20:40, ::37] = yarn  # hairs
    photo = Photo(linear_to_srgb(np.clip(linear, 0, 1)).astype(np.float32))
    seen = srgb_to_linear(photo.scene_view())  # at its own pitch
    assert np.median(seen[:10]) == pytest.approx(level, rel=0.05)
    assert np.median(seen[45:55], axis=(0, 1)) == pytest.approx(yarn, rel=0.02)
    assert seen[30, 37] == pytest.approx(yarn, rel=0.05)


def test_a_coloured_yarn_on_a_light_card_is_lit_from_the_front():
    # a band of fibers on a light background: coloured (a yarn lit in front on a white card)
    # or grey (a silhouette on a light panel)
    from ipm.photo import detect_setup

    rng = np.random.default_rng(2)
    for colour, setup in (((0.6, 0.45, 0.2), "frontlit"), ((0.3, 0.3, 0.3), "backlit")):
        img = np.full((150, 500, 3), 0.8)
        band = rng.random((40, 500)) < 0.7  # fibers and the gaps between them
        img[55:95][band] = colour
        assert detect_setup(img.astype(np.float32))[0] == setup, colour
