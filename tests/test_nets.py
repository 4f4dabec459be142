"""ipm.nets building blocks: smoke / cardinality / exception / gradcheck (kornia style),
tasks, safetensors round trips and the exposure augmentation."""

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from ipm.errors import UserError
from ipm.nets.decoder import Decoder
from ipm.nets.encoders import Encoder
from ipm.nets.heads import RegressionHead
from ipm.nets.losses import (
    LatentLoss,
    LatentSMA,
    ReconLoss,
    RegressLoss,
    latent_loss,
    recon_loss,
    regress_loss,
)
from ipm.nets.model import NetConfig, YarnNet, crop_size
from ipm.nets.objective import Objective
from ipm.nets.store import load_checkpoint, load_net, load_tensors, save_checkpoint, save_net
from ipm.nets.tasks import ENSEMBLE_TASKS, REG_TASKS, TASKS
from ipm.params import PARAM_ORDER, THICKNESS_CLASSES

torch.manual_seed(0)
torch.set_num_threads(1)  # tiny nets; see test_nets_train.py


# -- cardinality -------------------------------------------------------------------------------
@pytest.mark.parametrize("name, width, channels", [
    ("resnet18", 0.25, 128), ("resnet34", 0.25, 128), ("convnext", 0.25, 128),
    ("resnet18", 1.0, 512)])
def test_encoder_shapes(name, width, channels):
    z = Encoder(name, width)(torch.zeros(2, 3, 64, 160))
    assert z.shape == (2, channels, 2, 5)


def test_full_width_resnets_match_torchvision():
    import torchvision

    for name in ("resnet18", "resnet34"):
        ref = getattr(torchvision.models, name)(weights=None)
        ours = {k: v.shape for k, v in Encoder(name).body.state_dict().items()}
        theirs = [v.shape for k, v in ref.state_dict().items() if not k.startswith("fc.")]
        assert list(ours.values()) == theirs


def test_head_decoder_shapes():
    z = torch.zeros(3, 64, 4, 9)
    assert RegressionHead(5, channels=64)(z).shape == (3, 5)
    assert RegressionHead(5, channels=64, mlp=False)(z).shape == (3, 5)
    out = Decoder(channels=64)(z)
    assert out.shape == (3, 3, 64, 144) and out.abs().max() <= 1


def test_crop_size_is_papers_at_scale_one():
    assert crop_size(1.0) == (584, 1200) and crop_size(0.25) == (146, 300)


@pytest.mark.parametrize("task", [t.name for t in (*ENSEMBLE_TASKS, *REG_TASKS)])
def test_net_outputs(task):
    net = YarnNet(NetConfig(task, width=0.125, input_scale=0.1))
    z, y = net(torch.zeros(2, 3, *net.config.crop))
    assert y.shape == (2, TASKS[task].outputs)
    p = net.predict(torch.zeros(1, 3, *net.config.crop))
    if TASKS[task].is_classification:
        assert p.sum().item() == pytest.approx(1, abs=1e-5)


# -- exceptions --------------------------------------------------------------------------------
def test_shape_checks():
    with pytest.raises(ValueError, match=r"\(B, 3, H, W\)"):
        Encoder("resnet18", 0.25)(torch.zeros(3, 70, 150))
    with pytest.raises(ValueError, match="latent codes"):
        RegressionHead(2, channels=64)(torch.zeros(2, 32, 3, 3))
    with pytest.raises(ValueError, match="shapes differ"):
        regress_loss(torch.zeros(2, 3), torch.zeros(2, 4))
    with pytest.raises(ValueError, match="shapes differ"):
        latent_loss(torch.zeros(2, 8, 2, 2), torch.zeros(8, 3, 3))
    with pytest.raises(ValueError, match="unknown encoder"):
        Encoder("vgg")
    with pytest.raises(ValueError, match="input scale"):
        NetConfig("alpha", input_scale=2)
    with pytest.raises(RuntimeError, match="no real-image batch"):
        _ = LatentSMA().mean


# -- losses ------------------------------------------------------------------------------------
def test_loss_values_and_twins():
    a, b = torch.rand(4, 3), torch.rand(4, 3)
    assert RegressLoss()(a, b) == regress_loss(a, b) == (a - b).abs().mean()
    x, r = torch.rand(2, 3, 8, 8), torch.rand(2, 3, 4, 4)
    target = x.reshape(2, 3, 4, 2, 4, 2).mean((3, 5))
    assert torch.allclose(ReconLoss()(r, x), ((r - target) ** 2).mean())
    z, mu = torch.rand(2, 4, 2, 2), torch.rand(4, 2, 2)
    assert torch.allclose(LatentLoss()(z, mu), ((z - mu) ** 2).mean())


def test_gradcheck():
    a = torch.rand(3, 2, dtype=torch.float64, requires_grad=True)
    b = torch.rand(3, 2, dtype=torch.float64) + 2  # keep |a - b| away from the kink
    assert torch.autograd.gradcheck(regress_loss, (a, b))
    r = torch.rand(1, 3, 2, 2, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(recon_loss, (r, torch.rand(1, 3, 4, 4, dtype=torch.float64)))
    z = torch.rand(2, 3, 1, 1, dtype=torch.float64, requires_grad=True)
    mu = torch.rand(3, 1, 1, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda z: latent_loss(z, mu), (z,))
    latent_loss(z, mu).backward()
    assert mu.grad is None  # stop-gradient


def test_latent_sma_keeps_last_batches():
    sma = LatentSMA(batches=5)
    for v in range(8):
        sma.update(torch.full((2, 3, 1, 1), float(v)))
    assert sma.mean.flatten().tolist() == [5.0] * 3  # mean of batches 3..7


def test_objective_terms():
    net = YarnNet(NetConfig("raw", width=0.125, input_scale=0.1, decoder=True))
    obj = Objective(net, recon=True, latent=True)
    x = torch.rand(2, 3, *net.config.crop) * 2 - 1
    terms = obj(x, torch.rand(2, 9), x_real=x.flip(0))
    assert set(terms) == {"task", "recon", "latent", "loss"}
    terms["loss"].backward()
    assert all(p.grad is not None for p in net.parameters())
    with pytest.raises(ValueError, match="needs real images"):
        obj(x, torch.rand(2, 9))


# -- tasks -------------------------------------------------------------------------------------
def test_ensemble_decides_every_parameter(sampled_params):
    for tasks in (ENSEMBLE_TASKS, REG_TASKS):
        decided = [k for t in tasks for k in t.decides]
        assert sorted(decided) == sorted(PARAM_ORDER)
    p = sampled_params[0]
    values = {}
    for t in ENSEMBLE_TASKS:
        y = t.target(p)
        out = np.eye(t.outputs)[int(y)] if t.is_classification else y
        values.update(t.decode(out))
    assert values["n"] == p.n and values["m"] == p.m
    assert (values["t_x"], values["t_y"]) == THICKNESS_CLASSES[p.thickness]
    assert values["alpha_ply"] == pytest.approx(p.alpha_ply)


def test_decode_extremes_stay_in_range():
    from ipm.params import PAPER_INTERVALS

    for t in REG_TASKS:
        for x in (-1.0, 0.0, 1.0, 2.0):
            for k, v in t.decode(np.full(t.outputs, x)).items():
                assert PAPER_INTERVALS[k].lo <= v <= PAPER_INTERVALS[k].hi


# -- storage -----------------------------------------------------------------------------------
def test_net_round_trip(tmp_path):
    net = YarnNet(NetConfig("flyaways", width=0.125, input_scale=0.1, decoder=True)).eval()
    save_net(tmp_path / "f", net, {"epoch": 3})
    back, info = load_net(tmp_path / "f")
    assert info["epoch"] == 3 and back.d is None
    x = torch.rand(1, 3, *net.config.crop)
    assert torch.equal(back.predict(x), net.predict(x))
    tensors, _ = load_tensors(tmp_path / "f" / "model.safetensors")
    assert not any(k.startswith("d.") for k in tensors)


def test_a_detail_net_keeps_its_crop(tmp_path):
    """A detail net's input size (``crop_px``) survives saving; a net without one saves the
    config it always had (so runs made before detail nets resume)."""
    net = YarnNet(NetConfig("alpha", width=0.125, input_scale=1.0, crop_px=(48, 64))).eval()
    save_net(tmp_path / "a", net, {})
    back, _ = load_net(tmp_path / "a")
    assert back.config == net.config and back.config.crop == (48, 64)
    assert back.config.to_dict() == json.loads(json.dumps(back.config.to_dict()))
    assert "crop_px" not in NetConfig("alpha", input_scale=0.25).to_dict()
    with pytest.raises(ValueError, match="at least 32"):
        NetConfig("alpha", crop_px=(16, 64))


def test_checkpoint_round_trip(tmp_path):
    net = YarnNet(NetConfig("alpha", width=0.125, input_scale=0.1))
    opt = torch.optim.Adam(net.parameters(), 1e-3)
    net(torch.rand(2, 3, *net.config.crop))[1].sum().backward()
    opt.step()
    save_checkpoint(tmp_path / "c.safetensors", net, opt, {"epoch": 2, "history": [1.5]})
    net2 = YarnNet(NetConfig("alpha", width=0.125, input_scale=0.1))
    opt2 = torch.optim.Adam(net2.parameters(), 1e-3)
    state = load_checkpoint(tmp_path / "c.safetensors", net2, opt2)
    assert state == {"epoch": 2, "history": [1.5]}
    for a, b in zip(net.state_dict().values(), net2.state_dict().values(), strict=True):
        assert torch.equal(a, b)
    s1, s2 = opt.state_dict(), opt2.state_dict()
    assert torch.equal(s1["state"][0]["exp_avg_sq"], s2["state"][0]["exp_avg_sq"])
    assert s1["param_groups"][0]["lr"] == s2["param_groups"][0]["lr"]


@pytest.mark.parametrize("damage, message", [
    (lambda p: p.unlink(), "not found"),
    (lambda p: p.write_bytes(b"\x00" * 10), "corrupt or not safetensors"),
    (lambda p: p.write_bytes(p.read_bytes()[: len(p.read_bytes()) // 2]), "corrupt"),
    (lambda p: p.write_bytes(b"\x80\x04\x95pickle"), "corrupt or not safetensors"),
])
def test_bad_weights(tmp_path, damage, message):
    net = YarnNet(NetConfig("alpha", width=0.125, input_scale=0.1))
    save_net(tmp_path, net, {})
    damage(tmp_path / "model.safetensors")
    with pytest.raises(UserError, match=message):
        load_net(tmp_path)


def test_weights_of_another_net(tmp_path):
    save_net(tmp_path, YarnNet(NetConfig("alpha", width=0.125, input_scale=0.1)), {})
    other = tmp_path / "o"
    save_net(other, YarnNet(NetConfig("flyaways", width=0.125, input_scale=0.1)), {})
    (tmp_path / "model.safetensors").write_bytes((other / "model.safetensors").read_bytes())
    with pytest.raises(UserError, match="does not match"):
        load_net(tmp_path)


# -- data --------------------------------------------------------------------------------------
def test_exposure_lut():
    from ipm.nets.data import exposure_lut

    np.testing.assert_allclose(exposure_lut(0.0)[[0, 255]], [-1.0, 1.0], atol=1e-6)
    assert np.all(np.diff(exposure_lut(0.3)) >= 0)
    assert exposure_lut(0.5)[128] > exposure_lut(0.0)[128] > exposure_lut(-0.5)[128]


class _Frames:
    """Stand-in for nets.data.Frames: one 8-bit frame of fine stripes over a ramp along x, so
    a crop's mean tells where it was cut and its fine detail how blurred it is."""

    labels = None

    def __init__(self) -> None:
        x = np.arange(200)
        ramp = 40 + x, 60 * ((x // 2) % 2)
        row = np.clip(ramp[0] + ramp[1], 0, 255)
        self.img = np.repeat(np.tile(row, (80, 1))[..., None], 3, axis=2).astype(np.uint8)

    def __len__(self) -> int:
        return 4

    def __getitem__(self, i: int) -> np.ndarray:
        return self.img


def test_blur_augmentation_blurs_the_same_crop_and_exposure():
    from ipm.nets.data import Crops
    from ipm.photo import srgb_to_linear

    frames = _Frames()
    sharp = Crops(frames, (32, 64), seed=3)
    blurred = Crops(frames, (32, 64), seed=3, blur_px=3.0)
    for i in range(len(frames)):
        a, b = sharp[i][0].numpy(), blurred[i][0].numpy()
        detail = [np.abs(np.diff(x, axis=2)).mean() for x in (a, b)]
        assert detail[1] < 0.6 * detail[0]
        # blurring keeps the light: the same crop position (ramp) and exposure as unblurred
        light = [srgb_to_linear((x + 1) / 2).mean() for x in (a, b)]
        assert light[1] == pytest.approx(light[0], rel=0.03)
    # evaluation crops are never blurred
    evaluation = Crops(frames, (32, 64), train=False, blur_px=3.0)
    assert torch.equal(evaluation[0][0], Crops(frames, (32, 64), train=False)[0][0])


def test_look_jitter_changes_the_look_and_keeps_the_pattern():
    """--look: the same crops (position, stripes) in other colours, levels and noise; seeded
    per (seed, epoch, image); evaluation crops as rendered."""
    from ipm.nets.data import Crops

    frames = _Frames()
    plain, looked = Crops(frames, (32, 64), seed=3), Crops(frames, (32, 64), seed=3, look=True)
    means = []
    for i in range(len(frames)):
        a, b = plain[i][0].numpy(), looked[i][0].numpy()
        assert not np.allclose(a, b)
        np.testing.assert_array_equal(b, Crops(frames, (32, 64), seed=3, look=True)[i][0])
        # the stripes (the image's column pattern) are where they were
        cols = [x.mean(axis=(0, 1)) for x in (a, b)]
        assert np.corrcoef(np.diff(cols[0]), np.diff(cols[1]))[0, 1] > 0.8
        means.append(b.mean(axis=(1, 2)))
    # grey frames come out in other colours: the channels differ
    assert np.ptp(np.array(means), axis=1).max() > 0.05
    evaluation = Crops(frames, (32, 64), train=False, look=True)
    assert torch.equal(evaluation[0][0], Crops(frames, (32, 64), train=False)[0][0])


def test_learning_rate_schedule(tmp_path):
    from ipm.nets.config import TrainConfig
    from ipm.nets.train import learning_rate

    cfg = TrainConfig(data=tmp_path, val=tmp_path, out=tmp_path, epochs=5, lr=1e-3)
    rates = [learning_rate(cfg, e) for e in range(1, 6)]
    assert rates[0] == pytest.approx(1e-3) and rates[-1] == pytest.approx(1e-5)
    assert all(np.diff(rates) < 0)
    assert learning_rate(cfg.replace(schedule="constant"), 4) == 1e-3
    assert TrainConfig.paper(data=tmp_path, val=tmp_path, out=tmp_path).schedule == "constant"


def test_shipped_sigma_is_the_validation_mae_as_a_gaussian_std():
    """The refinement's prior: every refined parameter has a sigma, the validation MAE of
    the net that decides it times sqrt(pi / 2)."""
    from ipm.nets.ensemble import Ensemble

    ens = Ensemble.load(None)
    sigma = ens.sigma()
    assert {"alpha", "alpha_ply", "R_ply", "r_x", "r_y"} <= set(sigma)
    mae = ens.info[ens.deciders()["R_ply"]]["val"]["mae"]["R_ply"]
    assert sigma["R_ply"] == pytest.approx(mae * np.sqrt(np.pi / 2)) and sigma["R_ply"] > 0


@pytest.mark.slow  # renders
def test_shipped_nets_hold_on_a_blurred_photo():
    """A photo's defocus: the shipped nets, trained with blur augmentation, keep R_ply and m
    on renders blurred by a pixel; the nets shipped before that (commit a046881) miss both
    bounds, R_ply's by more than twice."""
    from ipm.nets.ensemble import Ensemble
    from ipm.params import PAPER_INTERVALS
    from ipm.photo import Photo, defocus, linear_to_srgb
    from ipm.prior import GuidedPrior
    from ipm.render.renderer import Renderer

    ens, renderer = Ensemble.load(None), Renderer()
    errors = {"R_ply": [], "m": []}
    for i, p in enumerate(GuidedPrior().sample_many(8, seed=20261201)):  # no training seed
        photo = linear_to_srgb(defocus(renderer.render(p, i, 0.25, 8), 1.0))
        q = ens.predict(Photo(photo, 0.04), 3)
        for k, e in errors.items():
            e.append(abs(getattr(q, k) - getattr(p, k)) / PAPER_INTERVALS[k].width)
    assert np.mean(errors["R_ply"]) < 0.07 and np.mean(errors["m"]) < 0.2


@pytest.fixture(scope="module")
def two_scale_models(tmp_path_factory):
    """The shipped models plus ``m`` and ``alpha`` at input scale 0.5 (0.02 mm per pixel), as
    a user's ensemble with nets at two scales (their weights: the 0.25 nets', which a
    ResNet takes at any input size; their validation error halved, to tell them apart)."""
    import shutil

    from ipm.nets.ensemble import SHIPPED

    folder = tmp_path_factory.mktemp("two-scale") / "models"
    shutil.copytree(SHIPPED, folder)
    manifest = json.loads((folder / "ensemble.json").read_text())
    for name in ("m", "alpha"):
        shutil.copytree(folder / name, folder / f"{name}-0.5")
        info = json.loads((folder / name / "model.json").read_text())
        info["config"]["input_scale"] = 0.5
        info["val"]["mae"][name] /= 2
        (folder / f"{name}-0.5" / "model.json").write_text(json.dumps(info))
        manifest["nets"].append(f"{name}-0.5")
    (folder / "ensemble.json").write_text(json.dumps(manifest))
    return folder


@pytest.mark.parametrize("pixel_size, m_net", [(0.01, "m-detail"), (0.02, "m-0.5"),
                                               (0.04, "m"), (0.1, "m")])
def test_ensemble_picks_the_finest_net_the_photo_supplies(two_scale_models, pixel_size, m_net):
    """Nets of one parameter at three input scales: a photo of 0.01 mm per pixel gets the
    shipped detail nets, one of 0.02 mm the 0.02 mm nets, a coarser one the 0.04 mm nets
    (upsampling would blur it), one net of each group of nets reading the same parameters;
    of those that read ``m``, the one with the lowest validation MAE decides it and gives
    its sigma."""
    from ipm.nets.ensemble import Ensemble

    ens = Ensemble.load(two_scale_models)
    chosen = ens.chosen(pixel_size)
    assert m_net in chosen and m_net.replace("m", "alpha") in chosen
    groups = [net.config.spec.decides for net in chosen.values()]
    assert len(groups) == len(set(groups))
    readers = {name: ens.info[name]["val"]["mae"]["m"] for name, net in chosen.items()
               if "m" in net.config.spec.decides}
    assert m_net in readers and ens.deciders(pixel_size)["m"] == min(readers, key=readers.get)
    sigma = ens.sigma(pixel_size)["m"] / np.sqrt(np.pi / 2)
    assert sigma == pytest.approx(min(readers.values()))
    assert ens.upsampling_warning(pixel_size) is None or pixel_size > 0.05


def test_ply_counts_are_the_n_nets_most_likely_classes_first():
    from ipm.nets.ensemble import Ensemble
    from ipm.photo import Photo, pixel_size_of
    from ipm.refine.search import likeliest_counts

    ens = Ensemble.load(None)
    path = Path(__file__).parents[1] / "examples" / "golden.png"
    photo = Photo.read(path, pixel_size_of(path, None, None))
    prior = ens.ply_count_probabilities(photo)
    assert sorted(prior) == [2, 3, 4, 5, 6] and abs(sum(prior.values()) - 1) < 1e-5
    counts = likeliest_counts(prior, most=5, mass=1.0)
    assert sorted(counts) == [2, 3, 4, 5, 6] and counts[0] == ens.predict(photo).n
    assert [prior[n] for n in counts] == sorted(prior.values(), reverse=True)
    assert likeliest_counts(prior, most=2) == counts[:len(likeliest_counts(prior, most=2))]
    assert len(likeliest_counts(prior, most=2)) in (1, 2)
    assert likeliest_counts(prior, most=5, mass=0.0) == counts[:1]


def test_a_real_photo_narrower_than_the_crop_is_tiled_along_the_yarn(tmp_path):
    """Unlabelled real photos (the domain-adaptation set) of a field smaller than the nets'
    crop are repeated along the yarn to the crop's width, periodically (a mirror would flip
    the twist's handedness); their rows are padded as any photo's."""
    from PIL import Image

    from ipm.nets.data import Frames

    rng = np.random.default_rng(0)
    Image.fromarray(rng.integers(0, 256, (320, 500, 3), dtype=np.uint8)).save(tmp_path / "a.png")
    frames = Frames.real(tmp_path, 0.25, (48, 200), pixel_size_mm=0.01, invert=False,
                         frame_height=600)
    img = frames[0]  # 5 x 3.2 mm: 125 x 80 px at 0.04 mm
    assert img.shape == (80, 200, 3)
    assert np.array_equal(img[:, 125:], img[:, :75])


def test_each_parameter_comes_from_the_net_with_the_lowest_validation_error(tmp_path):
    """A multi-task ``raw`` net beside the per-parameter nets (the backlit ensemble): each
    parameter is taken from the net whose stored validation MAE on it is lower, the classes
    (``n``, the thickness) from the classifiers; the prior's sigma follows the same net."""
    import shutil

    from ipm.nets.ensemble import SHIPPED_FOR, Ensemble
    from ipm.photo import Photo

    folder = tmp_path / "models"
    shutil.copytree(SHIPPED_FOR["backlit"], folder)
    info = json.loads((folder / "raw" / "model.json").read_text())
    per_net = json.loads((folder / "r_x" / "model.json").read_text())["val"]["mae"]["r_x"]
    info["val"]["mae"]["r_x"] = 2 * per_net           # raw worse on r_x ...
    info["val"]["mae"]["r_y"] = 1e-6                  # ... better on r_y
    (folder / "raw" / "model.json").write_text(json.dumps(info))
    ens = Ensemble.load(folder, setup="backlit")
    who = ens.deciders()
    assert (who["r_x"], who["r_y"], who["n"], who["t_x"]) == ("r_x", "raw", "n", "thickness")
    assert ens.sigma()["r_x"] == pytest.approx(per_net * np.sqrt(np.pi / 2))
    rng = np.random.default_rng(0)
    photo = Photo(rng.uniform(0.3, 1.0, (146 * 4, 300 * 4, 3)), 0.01, "backlit")
    out = ens.outputs(photo)
    p = ens.predict(photo)
    decode = {name: ens.nets[name].config.spec.decode(out[name]) for name in out}
    assert p.r_x == decode["r_x"]["r_x"] and p.r_y == decode["raw"]["r_y"]
    assert p.n == decode["n"]["n"]
