"""`ipm fit` end to end on a synthetic photo with a tiny trained model and a tiny budget."""

import json
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from ipm.params import PARAM_ORDER, YarnParams
from ipm.photo import linear_to_srgb, write_png
from ipm.presets import preset


def ipm(*args):
    return subprocess.run([sys.executable, "-m", "ipm", *map(str, args)], capture_output=True,
                          text=True)


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    from ipm.nets.config import TrainConfig
    from ipm.nets.sketchdata import write_sketch_dataset
    from ipm.nets.train import train

    root = tmp_path_factory.mktemp("fit-models")
    write_sketch_dataset(root / "train", 8, seed=0, scale=0.1)
    write_sketch_dataset(root / "val", 4, seed=1, scale=0.1, split="val")
    cfg = TrainConfig(data=root / "train", val=root / "val", out=root / "run", preset="reg",
                      width=0.125, input_scale=0.1, epochs=1, steps_per_epoch=2, batch_size=4)
    train(cfg, log=lambda line: None)
    return root / "run"


@pytest.fixture(scope="module")
def photo(tmp_path_factory):
    """The golden preset rendered at scale 0.25 (0.04 mm per pixel), as an sRGB PNG."""
    from ipm.render.renderer import Renderer

    path = tmp_path_factory.mktemp("photo") / "golden.png"
    write_png(path, linear_to_srgb(Renderer().render(preset("golden"), 5, 0.25, 8)))
    return path


def test_fit_refine_writes_everything_and_does_not_get_worse(models, photo, tmp_path):
    out = tmp_path / "fit"
    r = ipm("fit", photo, "--refine", "--models", models, "--pixel-size", 0.04, "--budget", 12,
            "--params", "r_y,alpha_ply", "--detail", 1, "--out", out)
    assert r.returncode == 0, r.stderr
    # these nets have no detail nets: the loss goes without a window, and says so
    assert "no detail nets read photos of 0.04 mm" in r.stderr, r.stderr
    for name in ("params.json", "neural.png", "refined.png", "compare.png"):
        assert (out / name).is_file(), name
    result = json.loads((out / "params.json").read_text())
    neural, refined = (YarnParams.from_dict(result[k]) for k in ("neural", "refined"))
    # the terminal shows the fitted yarn: each raw parameter's value and interval as saved
    said = {line.split()[0]: line.split() for line in r.stderr.splitlines()
            if line.startswith("  ")}
    assert int(said["n"][1]) == refined.n
    for k in ("R_ply", "alpha_ply", "r_x", "r_y", "alpha", "m"):
        assert float(said[k][1]) == pytest.approx(getattr(refined, k), rel=6e-3), k
        lo = float(said[k][3 if k != "m" else 2].strip("[,"))
        assert lo == pytest.approx(result["intervals"][k][0], rel=6e-3, abs=1e-3), k
    # the renders are shown in the photo's capture; the photo is a render of the scene's own
    assert result["capture"]["exposure_stops"] == 0.0
    assert result["capture"]["backdrop_gain"] == pytest.approx(1.0, rel=0.1)
    assert result["capture"]["blur_mm"] < 0.02  # the display's pitch
    assert set(PARAM_ORDER) <= set(result["refined"])
    assert result["loss"]["refined"] <= result["loss"]["neural"]
    assert result["settings"]["pixel_size_mm"] == 0.04 and result["evaluations"] <= 12
    assert neural.n == refined.n and neural.m == refined.m  # discrete parameters: the nets'
    assert [s["params"] for s in result["plan"]["stages"]] == [["r_y", "alpha_ply"]]
    assert result["settings"]["params"] == "r_y,alpha_ply"
    assert neural.R_ply == refined.R_ply and neural.r_x == refined.r_x  # not searched
    # an 80% interval per continuous parameter, holding the refined value
    intervals = result["intervals"]
    assert intervals["level"] == 0.8
    for k in ("m", "alpha", "r_x", "r_y", "alpha_ply", "R_ply"):
        lo, hi, source = intervals[k]
        assert lo <= getattr(refined, k) <= hi, k
        assert source == ("search profile and nets' validation error"
                          if k in ("r_y", "alpha_ply") else "nets' validation error"), k


def test_a_dry_run_prints_the_stages_and_writes_nothing(models, photo, tmp_path):
    out = tmp_path / "dry"
    r = ipm("fit", photo, "--refine", "--models", models, "--pixel-size", 0.04, "--dry-run",
            "--params", "R_ply,r_x;alpha_ply", "--out", out)
    assert r.returncode == 0, r.stderr
    assert "1. thickness  search R_ply,r_x: 30 evaluations" in r.stdout, r.stdout
    assert "2. ply twist  search alpha_ply" in r.stdout and "period, stripes" in r.stdout
    assert not out.exists()


def test_a_searched_interval_is_the_profile_joined_with_the_nets():
    """The profile measures only the loss's seed noise: the interval of a searched
    parameter is its hull with the nets' interval around their value (profile alone, held
    to the refined value, without the nets' error)."""
    from ipm.refine.fit import nets_interval, search_interval

    nets = nets_interval("alpha_ply", 6.0, 1.0)
    assert search_interval("alpha_ply", 6.4, (6.3, 6.5), 6.0, 1.0) == nets
    assert search_interval("alpha_ply", 9.0, (8.9, 9.2), 6.0, 1.0) == (nets[0], 9.2)
    assert search_interval("alpha_ply", 9.3, (8.9, 9.2), 6.0, None) == (8.9, 9.3)


def test_bad_search_params_one_line(models, photo, tmp_path):
    r = ipm("fit", photo, "--refine", "--models", models, "--params", "r_y,n", "--out",
            tmp_path / "fit")
    assert r.returncode == 2 and "cannot search ['n']" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / "fit").exists()


def test_a_photo_without_a_yarn_is_refused(models, tmp_path):
    """Refused in one line before any output, as ipm predict refuses it (it used to be fitted
    and its neural result kept)."""
    flat = tmp_path / "flat.png"
    write_png(flat, np.full((150, 500, 3), 0.4, np.float32))
    r = ipm("fit", flat, "--refine", "--models", models, "--pixel-size", 0.04, "--budget", 12,
            "--out", tmp_path / "fit")
    assert r.returncode == 2 and "no yarn found" in r.stderr and r.stderr.count("\n") == 1
    assert not (tmp_path / "fit").exists()


@pytest.mark.parametrize("content, message", [(b"not an image", "not an image"),
                                              (b"", "")])
def test_bad_photo_one_line(models, tmp_path, content, message):
    bad = tmp_path / "bad.png"
    bad.write_bytes(content)
    r = ipm("fit", bad, "--models", models, "--pixel-size", 0.04, "--out", tmp_path / "fit")
    assert r.returncode == 2 and r.stderr.startswith("error: ") and r.stderr.count("\n") == 1
    assert message in r.stderr and not (tmp_path / "fit" / "params.json").exists()


def test_missing_models_one_line(photo, tmp_path):
    r = ipm("fit", photo, "--models", tmp_path / "none", "--pixel-size", 0.04, "--out",
            tmp_path / "fit")
    assert r.returncode == 2 and "holds no trained models" in r.stderr


@pytest.mark.parametrize("degrees", [-1.2, 0.0, 1.5])
def test_photo_tilt_is_the_rendered_rotation(degrees):
    """The tilt measured on a real render is the yarn's rotation in the scene (the search
    renders at it), counter-clockwise positive."""
    from ipm.refine.measure import photo_tilt
    from ipm.render.photometric import Photometric
    from ipm.render.renderer import Renderer

    image = Renderer().render(preset("golden"), 1, 0.2, 4, 0, Photometric(rotation_deg=degrees))
    assert photo_tilt(linear_to_srgb(image)) == pytest.approx(degrees, abs=0.3)


def test_the_nets_readings_enter_the_loss_at_their_weight(photo):
    """--learned: the shipped regression nets' readings of the photo and of each render are
    groups of the loss (none for the class nets), at the weight asked; a render of a
    thicker yarn reads further from the photo's R_ply than one of the true yarn."""
    from ipm.nets.ensemble import Ensemble
    from ipm.photo import Photo
    from ipm.refine.objective import RenderObjective
    from ipm.render.renderer import Renderer

    small = Photo.read(photo, 0.04).at_pitch(0.2)
    renderer, readings = Renderer(), Ensemble.load().readings
    plain = RenderObjective(renderer, small, 0.2, 4)
    learned = RenderObjective(renderer, small, 0.2, 4, readings=readings, readings_weight=5.0)
    nets = {k for k in learned.photo_stats if k.startswith("net_")}
    assert nets == {"net_alpha", "net_m", "net_r_x", "net_r_y", "net_alpha_ply", "net_R_ply",
                    "net_flyaways", "net_raw"}
    golden = preset("golden")
    d = learned.group_distances(golden, 1)
    assert learned(golden, 1) == pytest.approx(plain(golden, 1) + 5 * sum(d[k] for k in nets))
    thick = learned.group_distances(golden.replace(R_ply=1.4 * golden.R_ply), 1)
    assert thick["net_R_ply"] > 4 * d["net_R_ply"]


def test_a_stage_of_flyaways_is_scored_by_the_flyaway_profile_alone(photo):
    """RenderObjective.for_stage: a stage of flyaway parameters alone is the flyaways group's
    distance and nothing else; the real render of a yarn with three times the flyaways and
    long hairs reads further from the photo than the true yarn; the pitch alone, with or
    without the thickness before it, is the stripes' period groups alone frontlit and those
    and the core's contour backlit, the thickness before the pitch every group but the
    contour; any other stage is the objective itself, whose weights count the flyaways once
    a search moves them."""
    from ipm.photo import Photo
    from ipm.refine.objective import DEFAULT_WEIGHTS, RenderObjective, search_weights
    from ipm.refine.plan import stage_for
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options

    small = Photo.read(photo, 0.04).at_pitch(0.2)
    objective = RenderObjective(Renderer(), small, 0.2, 4,
                                weights=search_weights(["R_ply", "g"]))
    golden = preset("golden")
    stage = objective.for_stage(stage_for(("g", "l_hair"), "frontlit"))
    assert stage(golden, 1) == pytest.approx(objective.group_distances(golden, 1)["flyaways"])
    hairy = golden.replace(g=min(300, 3 * golden.g), l_hair=3 * golden.l_hair)
    assert stage(hairy, 1) > 3 * stage(golden, 1)
    assert objective.for_stage(stage_for(("alpha_ply", "g"), "frontlit")) is objective
    d = objective.group_distances(golden, 1)
    pitch = objective.for_stage(stage_for(("alpha_ply",), "frontlit"))
    assert pitch(golden, 1) == pytest.approx(d["period"] + 2 * d["stripes"])
    backlit = RenderObjective(Renderer(options=setup_options("backlit")), small, 0.2, 4)
    assert {k: w for k, w in backlit.stage_weights(stage_for(("alpha_ply",), "backlit")).items()
            if w} == {"period": 1.0, "stripes": 2.0, "contour": DEFAULT_WEIGHTS["contour"]}
    thickness = objective.for_stage(stage_for(("R_ply", "r_x", "r_y"), "frontlit"))
    assert thickness(golden, 1) == pytest.approx(sum(w * d[k] for k, w in
                                                     objective.weights.items()
                                                     if k != "contour"))
    assert d["contour"] > 0
    assert objective.weights["flyaways"] > 0 == search_weights(["R_ply"])["flyaways"]
    assert search_weights(["R_ply"]) == DEFAULT_WEIGHTS


def test_a_detail_window_enters_the_loss_through_the_detail_nets_alone(photo):
    """A Detail view: each evaluation also renders a window at the detail nets' pitch, and
    only those nets' readings of it and of the photo's window are groups of the loss, at the
    weight asked; a yarn of four times as many fibers reads further from the photo's m than
    the true yarn."""
    from functools import partial

    from ipm.nets.ensemble import Ensemble
    from ipm.photo import Photo
    from ipm.refine.objective import Detail, RenderObjective
    from ipm.render.renderer import Renderer
    from ipm.render.scene import Frame

    ensemble, renderer, golden = Ensemble.load(), Renderer(), preset("golden")
    names, pitch = ensemble.detail_nets(0.01)
    assert set(names) == {"alpha-detail", "m-detail"} and pitch == pytest.approx(0.01)
    assert ensemble.detail_nets(0.04) == ((), 0.0)
    frame = Frame(320, 320, pitch)
    window = linear_to_srgb(renderer.render(golden, 5, 1.0, 16, frame=frame))
    small = Photo.read(photo, 0.04).at_pitch(0.2)
    plain = RenderObjective(renderer, small, 0.2, 4)
    detail = RenderObjective(renderer, small, 0.2, 4, detail=Detail(
        window, frame, partial(ensemble.readings, names=names), weight=3.0, spp=8))
    groups = {k for k in detail.photo_stats if k.startswith("detail_")}
    assert groups == {"detail_net_alpha-detail", "detail_net_m-detail"}
    d = detail.group_distances(golden, 1)
    assert detail(golden, 1) == pytest.approx(plain(golden, 1) + 3 * sum(d[k] for k in groups))
    dense = detail.group_distances(golden.replace(m=4 * golden.m), 1)
    assert dense["detail_net_m-detail"] > 2 * d["detail_net_m-detail"]


def test_a_small_fine_photo_is_searched_over_its_own_view_at_a_finer_pitch():
    """A microscope's 3 x 2.3 mm at 0.0021 mm per pixel: searched over that view with as
    many pixels as the yarn frame has at the search's scale (not 60 x 45 px); a photo as
    large as the frame keeps the frame; the view renders the yarn where the frame does."""
    from ipm.photo import Photo
    from ipm.refine.measure import search_view
    from ipm.render.renderer import Renderer
    from ipm.render.scene import frame_size

    small = Photo(np.zeros((1080, 1440, 3), np.float32), 0.0021)
    scale, frame = search_view(small, 0.2)
    assert frame.width * frame.pixel_size_mm == pytest.approx(1440 * 0.0021, rel=0.01)
    assert frame.height * frame.pixel_size_mm == pytest.approx(1080 * 0.0021, rel=0.01)
    assert frame.width * frame.height <= np.prod(frame_size(0.2)) * 1.01
    assert 0.01 <= frame.pixel_size_mm < 0.05 and scale == pytest.approx(0.01 / frame.pixel_size_mm)
    assert search_view(Photo(np.zeros((600, 2000, 3), np.float32), 0.01), 0.2) == (0.2, None)
    assert search_view(Photo(np.zeros((150, 500, 3), np.float32), 0.04), 0.2) == (0.2, None)

    renderer, golden = Renderer(), preset("golden")
    full = renderer.render(golden, 0, 0.5, 16).mean(axis=2)  # 1000 x 300 px at 0.02 mm
    _, view = search_view(Photo(np.zeros((400, 600, 3), np.float32), 0.005), 0.2)
    part = renderer.render(golden, 0, 0.01 / view.pixel_size_mm, 16, frame=view).mean(axis=2)
    assert part.shape == (view.height, view.width)
    # the same rows hold the core: the column-mean profiles, at the frame's pitch, agree
    rows_mm = (np.arange(view.height) - (view.height - 1) / 2) * view.pixel_size_mm
    full_rows_mm = (np.arange(full.shape[0]) - (full.shape[0] - 1) / 2) * 0.02
    expected = np.interp(rows_mm, full_rows_mm, full.mean(axis=1))
    assert np.corrcoef(part.mean(axis=1), expected)[0, 1] > 0.95


def test_a_microscope_photo_is_shown_at_its_own_pixels():
    """The photo and its renders a fit writes are shown at the photo's own pixels over its
    field (not at the search's coarser pitch), one pixel for one, so a fiber can be judged
    side by side; a photo of more than MAX_DISPLAY_PIXELS is shown coarser over the same
    field; a photo as large as the yarn frame keeps the display scale."""
    from types import SimpleNamespace

    from ipm.photo import Photo
    from ipm.refine.display import MAX_DISPLAY_PIXELS, display_renders, display_view
    from ipm.refine.plan import FitConfig
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options

    config = FitConfig()
    photo = Photo(np.full((240, 320, 3), 0.8, np.float32), 0.0021, setup="backlit")
    yarn = preset("golden").replace(R_ply=0.08, r_x=0.06, r_y=0.05)
    result = SimpleNamespace(refined=yarn, neural=yarn, tilt_deg=0.0)
    shown, neural, refined, _ = display_renders(
        Renderer(options=setup_options("backlit")), photo, result, config)
    assert shown.shape == neural.shape == refined.shape == (240, 320, 3)
    np.testing.assert_array_equal(shown, photo.image)
    darkness = 1 - refined.mean(axis=2)  # the yarn across the middle rows, not the outer
    assert darkness[110:130].mean() > 3 * darkness[:20].mean() + 0.05

    big = Photo(np.zeros((3000, 4000, 3), np.float32), 0.0021)
    _, frame = display_view(big, config)
    assert frame.width * frame.height <= MAX_DISPLAY_PIXELS
    assert frame.width * frame.pixel_size_mm == pytest.approx(4000 * 0.0021, rel=0.01)
    assert display_view(Photo(np.zeros((600, 2000, 3), np.float32), 0.01), config) == (
        config.display_scale, None)


def test_a_views_search_renders_only_the_yarn_its_view_needs_across_the_whole_view():
    """The search over a microscope's 3 x 2.3 mm view generates a yarn of the view's diagonal
    plus the margin, not the yarn frame's 26 mm, and at a tilt its core still crosses the
    view from edge to edge: the outer tenths of the columns are as dark as the middle."""
    from ipm.frame import YARN_LENGTH_MM, YARN_MARGIN_MM, view_yarn_length
    from ipm.photo import Photo
    from ipm.refine.measure import search_view
    from ipm.refine.objective import RenderObjective
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options

    assert view_yarn_length(3.0, 4.0) == pytest.approx(5.0 + YARN_MARGIN_MM)
    assert view_yarn_length(40.0, 6.0) == YARN_LENGTH_MM
    photo = Photo(np.full((1080, 1440, 3), 0.5, np.float32), 0.0021)
    scale, view = search_view(photo, 0.2)
    renderer = Renderer(options=setup_options("backlit"))  # a dark yarn on a light panel
    yarn = preset("golden").replace(R_ply=0.15, r_x=0.12, r_y=0.1)
    for tilt in (0.0, 20.0):
        objective = RenderObjective(renderer, photo.at_pitch(scale), scale, 4, frame=view,
                                    tilt_deg=tilt)
        assert objective.length < YARN_LENGTH_MM / 2
        darkness = 1 - objective.render(yarn, 0).mean(axis=2)
        tenth = view.width // 10
        middle = darkness[:, 4 * tenth:6 * tenth].sum(axis=0).mean()
        for edge in (darkness[:, :tenth], darkness[:, -tenth:]):
            assert edge.sum(axis=0).mean() > 0.7 * middle


class _BandObjective:
    """A stand-in for the render of a search: a dark band as wide as a yarn's core,
    ``2 (R_ply + r_y)`` at ``pitch`` mm per pixel, drawn here, with a thin dark line across
    it (a flyaway)."""

    def __init__(self, pitch: float) -> None:
        self.pitch = pitch

    def render(self, params, seed):
        return band_image(self.width(params))

    def width(self, params) -> float:
        return 2 * (params.R_ply + params.r_y) / self.pitch


def band_image(width_px: float, h: int = 240, w: int = 320) -> np.ndarray:
    rows = np.arange(h)[:, None] - (h - 1) / 2
    img = np.where(np.abs(rows) < width_px / 2, 0.2, 0.8) * np.ones((h, w))
    cols = np.arange(w)[None, :]
    img = np.where(np.abs(rows - 0.3 * (cols - w / 2)) < 1, 0.2, img)
    return np.repeat(img[..., None], 3, axis=2)


def test_match_size_scales_the_thickness_to_the_photo_core_keeping_proportions():
    """The start of a sized search: R_ply, r_x and r_y scaled by one factor until the drawn
    core is as wide as the photo's (60 px), from a yarn twice too thick and from one too
    thin; the other parameters are left alone."""
    from ipm.refine.measure import match_size

    truth = preset("golden")
    objective = _BandObjective(2 * (truth.R_ply + truth.r_y) / 60)
    photo = band_image(60)
    for factor in (2.0, 0.6):
        start = truth.replace(R_ply=truth.R_ply * factor, r_x=truth.r_x * factor,
                              r_y=truth.r_y * factor)
        sized = match_size(objective, start, photo)
        assert objective.width(sized) == pytest.approx(60, abs=1.5)
        ratios = [getattr(sized, k) / getattr(start, k) for k in ("R_ply", "r_x", "r_y")]
        assert max(ratios) == pytest.approx(min(ratios))
        assert sized.replace(R_ply=start.R_ply, r_x=start.r_x, r_y=start.r_y) == start


class _CountObjective:
    """Its ``silhouette`` group is lowest at 3 plies with the photo's stripe period
    (``alpha_ply / n`` = 2 mm), by ``depth`` per squared ply, with seed noise 0.01 (seeds
    0, 1, 2: std 0.0058); every other group is flat."""

    photo_stats = {"core": None, "silhouette": None}

    def __init__(self, setup: str, depth: float = 1.0):
        self.setup, self.depth = setup, depth
        self.calls = []

    def __call__(self, p, seed, weights=None):
        self.calls.append((p, weights))
        assert p.alpha_ply / p.n == pytest.approx(2.0)  # every count at the start's period
        sil = self.depth * (p.n - 3) ** 2 + 0.01 * (seed % 2)
        return (weights or {}).get("silhouette", 1.0) * sil + (weights or {}).get("core", 1.0)


def test_a_backlit_fit_chooses_the_ply_count_by_the_silhouette_and_the_nets_prior():
    """From the nets' 2 plies at a 2 mm stripe period, a silhouette lowest at 3 by far more
    than its seed noise takes the count to 3 at the same period; one lower at 3 by 1.7
    units of its noise does not outweigh the nets' 0.9 against 0.05 (-ln: 0.1 against 3.0);
    frontlit, no group chooses and the nets' count stands."""
    from ipm.refine.measure import choose_ply_count

    start = preset("golden").replace(n=2, alpha_ply=4.0)
    prior = {2: 0.6, 3: 0.2, 4: 0.1, 5: 0.05, 6: 0.05}
    objective = _CountObjective("backlit")
    chosen, scores = choose_ply_count(objective, start, prior, (0, 1, 2), ("silhouette",))
    assert chosen.n == 3 and chosen.alpha_ply == pytest.approx(6.0)
    assert chosen.replace(n=2, alpha_ply=4.0) == start
    assert set(scores) == {2, 3, 4, 5, 6} and min(scores, key=scores.get) == 3
    assert {k for _, w in objective.calls for k, v in w.items() if v} == {"silhouette"}
    shallow = _CountObjective("backlit", depth=0.01)
    kept, _ = choose_ply_count(shallow, start, {2: 0.9, 3: 0.05, 4: 0.05}, (0, 1, 2),
                               ("silhouette",))
    assert kept is start
    frontlit = _CountObjective("frontlit")
    assert choose_ply_count(frontlit, start, prior, (0, 1, 2), ()) == (start, {})
    assert not frontlit.calls


def test_the_objective_renders_a_pair_of_params_and_seed_once_whatever_the_weights(photo):
    """A fit scores its start under several weightings: the second scoring of the same
    yarn and fiber seed reuses the render (the counter of renders stays), and gives the
    loss a fresh objective gives; another seed or yarn renders anew."""
    from ipm.photo import Photo
    from ipm.refine.objective import RenderObjective
    from ipm.render.renderer import Renderer

    small = Photo.read(photo, 0.04).at_pitch(0.2)
    renderer = Renderer()
    objective = RenderObjective(renderer, small, 0.2, 4, seeds_per_eval=2)
    golden = preset("golden")
    whole = objective(golden, 1)
    assert objective.evaluations == 2  # two fiber seeds per evaluation
    silhouette = objective(golden.replace(), 1,
                           {k: float(k == "silhouette") for k in objective.photo_stats})
    assert objective.evaluations == 2
    assert silhouette == pytest.approx(objective.group_distances(golden, 1)["silhouette"])
    assert whole == pytest.approx(RenderObjective(renderer, small, 0.2, 4, seeds_per_eval=2)(
        golden, 1))
    objective(golden, 2)
    objective(golden.replace(R_ply=1.1 * golden.R_ply), 1)
    assert objective.evaluations == 6


def test_a_fit_that_keeps_an_unsure_nets_ply_count_keeps_their_pitch(photo):
    """Frontlit, where a fit keeps the nets' ply count: with that count below even odds
    the fit says so and does not move alpha_ply (nothing else asked: no search at all; with
    a thickness stage asked too, only that stage runs); with the count likely, the pitch is
    searched (the plan's gates alone: test_refine_plan)."""
    from ipm.photo import Photo
    from ipm.refine.fit import fit
    from ipm.refine.plan import FitConfig
    from ipm.render.renderer import Renderer

    truth = preset("golden")
    neural = truth.replace(alpha_ply=truth.alpha_ply * 1.3)
    shot = Photo.read(photo, 0.04)
    quick = FitConfig(budget=6, rescore_seeds=(1,), rescore_top=1, seeds_per_eval=1)
    unsure = {truth.n: 0.3, truth.n + 1: 0.7}

    renderer = Renderer()
    held = fit(shot, neural, renderer, quick, count_prior=unsure)
    assert held.refined == held.neural and held.search is None
    assert any("probability of only 0.30" in w for w in held.warnings)
    searched = fit(shot, neural, renderer, quick, count_prior={truth.n: 0.9})
    assert searched.search is not None and searched.search.evaluations >= 6
    staged = replace(quick, params="R_ply;alpha_ply")
    thickness = fit(shot, neural, renderer, staged, count_prior=unsure)
    assert [s.params for s in thickness.plan.stages] == [("R_ply",)]
    assert thickness.refined.alpha_ply == neural.alpha_ply


def test_the_width_ratio_of_a_render_to_the_photo_core():
    """A drawn band twice and half as wide as the photo's 60 px core."""
    from ipm.refine.measure import width_ratio

    truth = preset("golden")
    objective = _BandObjective(2 * (truth.R_ply + truth.r_y) / 60)
    photo = band_image(60)
    assert width_ratio(objective, truth, photo) == pytest.approx(1.0, abs=0.05)
    for factor in (2.0, 0.5):
        thick = truth.replace(R_ply=truth.R_ply * factor, r_y=truth.r_y * factor)
        assert width_ratio(objective, thick, photo) == pytest.approx(factor, rel=0.05)


def test_a_yarn_far_thinner_than_the_nets_read_is_searched_thickness_first():
    """Backlit nets that read golden 2.5 times too thick put it outside their range: the fit
    says so, searches the thickness, flyaways and ply twist in turn without their prior, and
    its render's core comes nearer the photo's width (the half-contrast width of the
    benchmarks' net-free yardstick, not the fit's own width measure, on the photo and on the
    two rendered at its pitch); a reading within the gate keeps the default search, and so
    does a frontlit fit, whose core width follows the light."""
    from ipm.photo import Photo
    from ipm.refine.fit import fit
    from ipm.refine.plan import FitConfig
    from ipm.refine.search import parse_stages
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options
    from ipm.textile.image import measure_image

    renderer = Renderer(options=setup_options("backlit"))
    truth = preset("golden")
    shot = Photo(linear_to_srgb(renderer.render(truth, 5, 0.25, 8)), 0.04, "backlit")
    thick = truth.replace(**{k: 2.5 * getattr(truth, k) for k in ("R_ply", "r_x", "r_y")})
    options = FitConfig(scale=0.1, spp=2, budget=8, display_spp=2)
    sigma = {"R_ply": 0.01, "r_x": 0.01, "r_y": 0.01, "alpha_ply": 0.1}
    result = fit(shot, thick, renderer, options, sigma=sigma)
    assert any("outside the nets' range" in w for w in result.warnings), result.warnings
    outside = parse_stages("R_ply,r_x,r_y;g,l_hair,l_loop,d_mean;alpha_ply")
    assert tuple(s.params for s in result.plan.stages) == outside
    assert result.sigma is None and not result.plan.prior and result.plan.seeds_per_eval == 1
    thickness = result.plan.stages[0].search
    assert thickness.polish > 0 and thickness.keep_cover

    def core(linear):
        return measure_image(linear_to_srgb(linear).mean(axis=2), True)["core_diameter_px"]

    photo_core = core(renderer.render(truth, 5, 0.25, 8))
    before, after = (core(renderer.render(p, 5, 0.25, 8)) / photo_core
                     for p in (result.neural, result.refined))
    assert before > 2 and abs(np.log(after)) < 0.75 * abs(np.log(before)), (before, after)
    quick = replace(options, budget=4)
    kept = fit(shot, truth, renderer, quick, sigma=sigma)
    assert [s.params for s in kept.plan.stages] == [("alpha_ply",)] and kept.sigma == sigma
    assert not any("outside the nets' range" in w for w in kept.warnings)
    frontlit = Photo(linear_to_srgb(Renderer().render(truth, 5, 0.25, 8)), 0.04)
    lit = fit(frontlit, thick, Renderer(), quick, sigma=sigma)
    assert [s.params for s in lit.plan.stages] == [("alpha_ply",)] and lit.sigma == sigma


@pytest.mark.parametrize("setup", ["frontlit", "backlit"])
def test_the_displayed_capture_is_the_photos_exposure_and_defocus(setup):
    """A render turned into a 'photo' by our own means (a gain in linear light, a Gaussian
    blur of each channel, the sRGB curve written out): the capture matched to it is that
    blur in mm, and that gain as the exposure backlit (the panel is the light) and as the
    card's albedo frontlit (the yarn's brightness is the fibers' colour's to match)."""
    from scipy.ndimage import gaussian_filter

    from ipm.refine.capture import card_warning, matched_capture, search_card
    from ipm.render.renderer import Renderer
    from ipm.render.scene import setup_options

    renderer = Renderer(options=setup_options(setup))
    linear = renderer.render(preset("golden"), 5, 0.25, 8)

    def srgb(x):  # the sRGB curve, written out
        x = np.clip(x, 0, 1)
        return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)

    def photo_of(gain, sigma_px):
        return srgb(np.stack([gaussian_filter(linear[..., c] * gain, sigma_px, mode="nearest")
                              for c in range(3)], axis=-1))

    for gain, sigma_px in ((1.0, 0.0), (0.5, 1.5), (1.5, 4.0)):
        capture = matched_capture(photo_of(gain, sigma_px), linear, 0.04, setup=setup)
        stops = np.log2(gain) if setup == "backlit" else 0.0
        card = 1.0 if setup == "backlit" else gain
        assert capture.exposure_stops == pytest.approx(stops, abs=0.1), (gain, sigma_px)
        assert capture.backdrop_gain == pytest.approx(card, rel=0.07), (gain, sigma_px)
        assert capture.blur_mm / 0.04 == pytest.approx(sigma_px, abs=0.1 + 0.05 * sigma_px), (
            gain, sigma_px)
    if setup == "frontlit":  # a light card (the scene's albedo times 30) is matched in full
        from ipm.render.photometric import Photometric

        light = srgb(renderer.render(preset("golden"), 5, 0.25, 8,
                                     photometric=Photometric(backdrop_gain=30.0)))
        on_light = matched_capture(light, linear, 0.04, setup=setup)
        assert on_light.backdrop_gain == pytest.approx(30.0, rel=0.07)
        # a white card is inside what the nets saw; a card darker than any they saw is said
        assert card_warning(on_light, setup) is None
        darker = replace(on_light, backdrop_gain=0.1)
        assert "0.1 times as light" in card_warning(darker, setup)
        assert card_warning(matched_capture(photo_of(1.0, 0.0), linear, 0.04, setup=setup),
                            setup) is None
        # the search renders on the photo's card: the light one's, the scene's as it is
        assert search_card(light, setup) == pytest.approx(30.0, rel=0.1)
        assert search_card(photo_of(1.0, 0.0), setup) == 1.0
    else:
        assert search_card(photo_of(1.5, 0.0), setup) == 1.0  # the panel is the light
