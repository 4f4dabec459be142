"""refine.stats, kornia-style: smoke, cardinality, exception, gradient."""

import pytest
import torch

from ipm.refine.stats import GROUPS, YarnStatLoss, yarn_stat_loss, yarn_statistics


def stripes(angle: float, period: float = 12.0, h: int = 96, w: int = 320, shift: int = 0,
            background: float = 0.8, contrast: float = 0.4, half_width: float = 96 / 6):
    """A dark band across the middle filled with oblique stripes: a cartoon yarn."""
    y, x = torch.meshgrid(torch.arange(h, dtype=torch.float64),
                          torch.arange(w, dtype=torch.float64), indexing="ij")
    core = ((y - h / 2 - shift).abs() < half_width).double()
    phase = 2 * torch.pi * (x * torch.cos(torch.tensor(angle)) + y * torch.sin(
        torch.tensor(angle))) / period
    img = background - core * contrast * (1 + 0.5 * torch.sin(phase))
    return img[None, None].expand(1, 3, h, w).contiguous()


def noisy(img: torch.Tensor, std: float) -> torch.Tensor:
    """``img`` plus seeded Gaussian pixel noise of ``std``, clipped to [0, 1]."""
    noise = torch.randn(img.shape, generator=torch.Generator().manual_seed(0), dtype=img.dtype)
    return (img + std * noise).clamp(0, 1)


def group_distance(a: torch.Tensor, b: torch.Tensor, group: str) -> float:
    """Mean squared difference of one statistics group of two images."""
    return float((yarn_statistics(a)[group] - yarn_statistics(b)[group]).square().mean())


def test_smoke_and_cardinality():
    s = yarn_statistics(torch.rand(3, 3, 96, 320, dtype=torch.float64))
    assert set(s) == set(GROUPS)
    assert all(v.shape[0] == 3 and v.ndim == 2 and torch.isfinite(v).all() for v in s.values())
    assert yarn_stat_loss(torch.rand(4, 1, 96, 320), torch.rand(1, 1, 96, 320)).shape == (4,)


def test_zero_for_identical_and_invariant_to_vertical_shift():
    a = stripes(0.6)
    assert float(yarn_stat_loss(a, a)) == 0.0
    assert yarn_stat_loss(a, stripes(0.6, shift=7)) < 0.02 * yarn_stat_loss(a, stripes(0.65))


def test_sees_twist_angle_direction_and_period():
    a = stripes(0.6)
    near, far = yarn_stat_loss(a, stripes(0.65)), yarn_stat_loss(a, stripes(0.9))
    assert 0 < near < far
    # the opposite twist direction has the same period along the axis: only the
    # orientation moments tell it, clearly above the noise of a vertical shift
    mirrored = yarn_stat_loss(a, stripes(-0.6))
    assert mirrored > 50 * yarn_stat_loss(a, stripes(0.6, shift=7))
    assert yarn_stat_loss(a, stripes(0.6, period=14)) < yarn_stat_loss(a, stripes(0.6, period=24))


def test_core_and_flyaways_do_not_depend_on_the_capture_contrast():
    """A grey backlit photo's core (0.35 below a 0.6 background) against a render's (0.6
    below 0.8): the same yarn reads the same; a core 20% thinner does not."""
    photo = stripes(0.6, background=0.6, contrast=0.23)
    render = stripes(0.6, background=0.8, contrast=0.4)
    thinner = stripes(0.6, background=0.8, contrast=0.4, half_width=0.8 * 96 / 6)
    for group in ("core", "flyaways", "period", "stripes"):
        assert group_distance(photo, render, group) < 1e-6, group
    assert group_distance(photo, thinner, "core") > 0.01


def with_hairs(img: torch.Tensor, count: int, reach: float, h: int = 96, w: int = 320,
               half_width: float = 96 / 6) -> torch.Tensor:
    """``img`` with ``count`` dark vertical hairs 2 px wide standing ``reach`` px out of the
    band's upper edge."""
    out = img.clone()
    top = round(h / 2 - half_width)
    for i in range(count):
        x = 10 + i * (w - 20) // count
        out[..., max(0, round(top - reach)): top, x: x + 2] -= 0.3
    return out.clamp(0, 1)


def test_flyaways_see_the_hairs_not_the_cores_texture():
    """The flyaway profile: hairs twice as long or twice as many read far apart, while a core
    whose stripes are of another angle and period reads as the same hairs."""
    a = with_hairs(stripes(0.6), 8, 12)
    other_core = with_hairs(stripes(0.9, period=20), 8, 12)
    hairs = {"longer": with_hairs(stripes(0.6), 8, 24), "more": with_hairs(stripes(0.6), 16, 12),
             "none": stripes(0.6)}
    same = group_distance(a, other_core, "flyaways")
    for name, img in hairs.items():
        assert group_distance(a, img, "flyaways") > 20 * same, name


def test_sees_core_thickness():
    a = stripes(0.6)
    thick = a.clone()
    thick[..., 24:72, :] = a[..., 40:56, :].mean()
    assert yarn_stat_loss(a, thick) > yarn_stat_loss(a, stripes(0.62))


@pytest.mark.parametrize("x, match", [(torch.rand(3, 96, 320), "must be a"),
                                      (torch.rand(1, 2, 96, 320), "must be a"),
                                      (torch.rand(1, 3, 8, 320), "too small")])
def test_exceptions(x, match):
    with pytest.raises(ValueError, match=match):
        yarn_statistics(x)


def test_size_mismatch():
    with pytest.raises(ValueError, match="same size"):
        yarn_stat_loss(torch.rand(1, 3, 96, 320), torch.rand(1, 3, 96, 300))


def test_gradient_flows_and_module_twin():
    x = torch.rand(1, 3, 96, 320, dtype=torch.float64, requires_grad=True)
    target = stripes(0.6)
    loss = YarnStatLoss()(x, target)
    loss.sum().backward()
    assert x.grad is not None and torch.isfinite(x.grad).all() and x.grad.abs().sum() > 0
    assert torch.allclose(loss, yarn_stat_loss(x, target))


def test_period_sees_the_twist_period_not_the_pixel_noise():
    """The axial autocorrelation peaks at the stripes' period along the axis; strong pixel
    noise moves it far less than a 10% change of the period does (without the blur before
    the autocorrelation, the noise moves it about 10x more, past the bound)."""
    angle, period = 0.5, 14.0
    clean = stripes(angle, period)
    acf = yarn_statistics(clean, levels=1)["period"][0]
    along = period / torch.cos(torch.tensor(angle))  # the stripes' period along a row
    assert abs(int(acf[5:].argmax()) + 6 - float(along)) <= 1
    assert (group_distance(clean, noisy(clean, 0.4), "period")
            < 0.05 * group_distance(clean, stripes(angle, 1.1 * period), "period"))


def test_stripes_see_the_twist_period_not_the_pixel_noise():
    """The axial spectrum's distribution rises most in the bin of the stripes' frequency
    along the axis; pixel noise as strong as the stripes moves it far less than a 10% change
    of the period does (without the blur before the spectrum, the noise moves it past the
    bound)."""
    from ipm.refine.stats import PERIOD_BINS, PERIOD_FMAX

    angle, period, w = 0.5, 14.0, 320
    clean = stripes(angle, period, w=w)
    cdf = yarn_statistics(clean, levels=1)["stripes"][0]
    along = period / torch.cos(torch.tensor(angle))  # the stripes' period along a row
    edges = torch.logspace(torch.log10(torch.tensor(2 / w)), torch.log10(
        torch.tensor(PERIOD_FMAX)), PERIOD_BINS + 1)
    step = int(torch.diff(cdf, prepend=cdf.new_zeros(1)).argmax())
    assert edges[step] <= 1 / along < edges[step + 1]
    assert (group_distance(clean, noisy(clean, 0.2), "stripes")
            < 0.05 * group_distance(clean, stripes(angle, 1.1 * period), "stripes"))


def test_stripes_distance_grows_with_the_period_error():
    """The basin around the true period is wide: the distance grows with the error of the
    period, and stripes too fine to resolve (a far tighter twist) are farther than a 20%
    error.  The autocorrelation (``period``) fails both: phase drift at long lags makes a
    20% error cost more than erased stripes."""
    a = stripes(0.5, 14.0)
    errors = [group_distance(a, stripes(0.5, 14.0 * f), "stripes") for f in (1.05, 1.1, 1.2, 1.4)]
    assert errors == sorted(errors) and errors[0] > 0
    assert group_distance(a, stripes(0.5, 2.5), "stripes") > errors[2]


def plies(n: int, tilt: float = 0.0, wander: float = 0.0, h: int = 96, w: int = 320,
          pitch: float = 80.0, ply_radius: float = 7.0, helix_radius: float = 7.0):
    """The silhouette of ``n`` round plies of ``ply_radius`` px whose axes wind at
    ``helix_radius`` about the yarn's axis with ``pitch`` px per turn, seen from the side
    (ply i's centre at height helix_radius cos(2 pi x / pitch + 2 pi i / n)); the yarn
    tilted by ``tilt`` px per px, and each edge moved by its own smooth random wander of
    ``wander`` px standard deviation; dark on a bright background."""
    x = torch.arange(w, dtype=torch.float64)
    centres = torch.stack([helix_radius * torch.cos(2 * torch.pi * (x / pitch + i / n))
                           for i in range(n)])
    g = torch.Generator().manual_seed(n)
    freqs = (torch.rand(2, 6, 1, generator=g, dtype=torch.float64) + 0.2) * 4 / pitch
    phases = 2 * torch.pi * torch.rand(2, 6, 1, generator=g, dtype=torch.float64)
    noise = wander * torch.sin(2 * torch.pi * freqs * x + phases).sum(dim=1) / 3 ** 0.5
    axis = h / 2 + tilt * (x - w / 2)
    upper = axis - centres.amax(dim=0) - ply_radius - noise[0]  # rows point down
    lower = axis - centres.amin(dim=0) + ply_radius + noise[1]
    y = torch.arange(h, dtype=torch.float64)[:, None]
    img = 0.8 - 0.5 * ((y > upper) & (y < lower)).double()
    return img[None, None].expand(1, 3, h, w).contiguous()


def test_silhouette_tells_an_even_ply_count_from_an_odd_one():
    """Two plies: both edges move out and in together; three: one moves out as the other
    moves in; four plies swing the width less than two.  Neither a tilt of the yarn nor
    each edge's own wander (of about as much as three plies move them) changes it much."""
    two, three, four = (float(yarn_statistics(plies(n))["silhouette"][0, 0]) for n in (2, 3, 4))
    assert two > 0.5 and three < -0.15 and 0 < four < 0.3 * two
    for n, clean in ((2, two), (3, three)):
        for changed in (plies(n, tilt=0.05), plies(n, wander=1.5)):
            assert float(yarn_statistics(changed)["silhouette"][0, 0]) == pytest.approx(
                clean, abs=0.15), n


@pytest.mark.parametrize("n", [2, 3])
def test_contour_reads_the_ply_period_off_the_outline_whatever_is_inside_the_core(n):
    """A microscope's view shows about three ply periods, and a photo's core is grey with
    the fibers' texture where a render's is opaque.  The "photo" here: plies repeating
    every ``W / 3`` px, each edge wandering, the core translucent with slanted fiber stripes
    and a slow shading; the "renders": the plain opaque outline at other pitches.  The
    contour's distance is lowest within 12% of the true pitch and over twice as high at
    35% off; the core band's stripes, which read the texture, need not be."""
    w, h = 320, 96
    pitch = n * w / 3
    photo = plies(n, w=w, pitch=pitch, helix_radius=5.0, wander=0.5)
    x = torch.arange(w, dtype=torch.float64)
    y = torch.arange(h, dtype=torch.float64)[:, None]
    texture = (0.15 * torch.sin(2 * torch.pi * (x + 0.6 * y) / 9.0)
               + 0.1 * torch.sin(2 * torch.pi * x / 37.0))
    photo = torch.where(photo < 0.5, photo + 0.15 + texture, photo)
    factors = (0.6, 0.75, 0.9, 1.0, 1.12, 1.35, 1.7)
    distances = {f: group_distance(photo, plies(n, w=w, pitch=pitch * f, helix_radius=5.0),
                                   "contour") for f in factors}
    assert min(distances, key=distances.get) in (0.9, 1.0, 1.12), distances
    lowest = min(distances.values())
    assert distances[0.75] > 2 * lowest and distances[1.35] > 2 * lowest, distances


def test_core_width_is_the_drawn_band_whatever_crosses_it():
    """A dark band of 40 rows on a bright background, crossed by thin slanted lines
    (flyaways) and shifted off the middle: its core width is 40 rows."""
    from ipm.refine.stats import core_width

    h, w = 120, 320
    y = torch.arange(h, dtype=torch.float64)[:, None]
    x = torch.arange(w, dtype=torch.float64)[None, :]
    img = torch.where((y - 50).abs() < 20, 0.25, 0.8) * torch.ones(h, w, dtype=torch.float64)
    for k in range(6):
        img = torch.where((y - 0.4 * (x - 50 * k)).abs() < 0.8, 0.3, img)
    assert float(core_width(img[None, None])[0]) == pytest.approx(40, abs=1)
