"""Training and inference end to end on tiny sketch datasets: every preset for two steps,
predict and saliency on the result, resuming, and the CLI's one-line errors."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import torch
from PIL import Image

from ipm.errors import UserError
from ipm.nets.config import PRESETS, TrainConfig
from ipm.nets.sketchdata import write_sketch_dataset
from ipm.params import YarnParams

SCALE = 0.1  # frames of 200 x 60 px, net input 120 x 58 px
# Tiny nets: one thread is faster, and immune to OpenMP spinning on a busy machine.
torch.set_num_threads(1)
ENV = {**os.environ, "OMP_NUM_THREADS": "1"}
TINY = dict(width=0.125, input_scale=SCALE, epochs=1, steps_per_epoch=2, batch_size=4)


def ipm(*args, **kw):
    return subprocess.run([sys.executable, "-m", "ipm", *map(str, args)], capture_output=True,
                          text=True, env=ENV, **kw)


@pytest.fixture(scope="session")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("nets-data")
    write_sketch_dataset(root / "train", 8, seed=0, scale=SCALE)
    write_sketch_dataset(root / "val", 4, seed=1, scale=SCALE, split="val")
    real = root / "real"
    real.mkdir()
    rng = np.random.default_rng(0)
    for i in range(3):  # grayscale backlit-style photos of another size than the frame
        Image.fromarray(rng.integers(0, 256, (300, 400), dtype=np.uint8)).save(
            real / f"r{i}.png")
    return root


@pytest.fixture(scope="session")
def trained(data, tmp_path_factory):
    """One run per preset, trained in this process."""
    from ipm.nets.train import train

    runs = {}
    for preset in PRESETS:
        out = tmp_path_factory.mktemp(f"run-{preset}")
        cfg = TrainConfig(data=data / "train", val=data / "val", out=out, preset=preset,
                          real=data / "real" if preset != "reg" else None,
                          real_pixel_size=0.04, real_invert=True, **TINY)
        runs[preset] = train(cfg, log=lambda line: None)
    return runs


@pytest.fixture
def photo(data):
    return data / "train" / "images" / "000000.png"


@pytest.mark.parametrize("preset", list(PRESETS))
def test_every_preset_trains_and_predicts(trained, preset, photo):
    from ipm.nets.ensemble import Ensemble

    run = trained[preset]
    manifest = json.loads((run / "ensemble.json").read_text())
    assert manifest["nets"] == list(PRESETS[preset].tasks)
    for name in manifest["nets"]:
        info = json.loads((run / name / "model.json").read_text())
        assert info["epoch"] == 1 and "baseline" in info and info["val"]["loss"] >= 0
        assert (run / name / "checkpoint.safetensors").is_file()
    from ipm.photo import Photo

    params = Ensemble.load(run).predict(Photo.read(photo, 0.01 / SCALE))
    assert isinstance(params, YarnParams)


def test_predict_cli(trained, photo, tmp_path):
    r = ipm("predict", photo, "--pixel-size", 0.01 / SCALE, "--models", trained["ensemble"],
            "-o", tmp_path / "p.json")
    assert r.returncode == 0, r.stderr
    written = YarnParams.load(tmp_path / "p.json")
    assert YarnParams.from_json(r.stdout) == written
    assert (written.t_x, written.t_y) in [(0.01, 0.007), (0.018, 0.01)]
    # the written file is what `ipm curves` reads
    r = ipm("curves", tmp_path / "p.json", "-o", tmp_path / "y.npz")
    assert r.returncode == 0, r.stderr


def test_predict_several_photos_in_one_process(trained, photo, tmp_path):
    import shutil

    folder = tmp_path / "photos"
    folder.mkdir()
    for name in ("a.png", "b.png"):
        shutil.copy(photo, folder / name)
    args = ("--pixel-size", 0.01 / SCALE, "--models", trained["ensemble"])
    r = ipm("predict", folder, *args, "-o", tmp_path / "out")
    assert r.returncode == 0, r.stderr
    one = ipm("predict", photo, *args)
    for name in ("a", "b"):
        written = YarnParams.load(tmp_path / "out" / f"{name}.json")
        assert written == YarnParams.from_json(one.stdout)
    r = ipm("predict", folder / "a.png", folder / "b.png", *args)
    assert r.returncode == 2 and "--out FOLDER" in r.stderr


def test_predict_warns_when_the_photo_is_coarser_than_the_nets(trained, photo):
    """The tiny nets work at 0.1 mm per pixel: a photo of 0.1 mm passes, one of 0.2 mm is
    upsampled for every net, and that is said (the prediction still comes)."""
    from ipm.nets.ensemble import Ensemble

    ens = Ensemble.load(trained["ensemble"])
    assert ens.upsampling_warning(0.01 / SCALE) is None
    assert ens.upsampling_warning(0.01 / SCALE * 1.2) is None
    w = ens.upsampling_warning(0.02 / SCALE)
    assert w is not None and "alpha_ply" in w and "0.1 mm" in w
    r = ipm("predict", photo, "--pixel-size", 0.02 / SCALE, "--models", trained["ensemble"])
    assert r.returncode == 0, r.stderr
    assert "warning: the photo's pixels (0.2 mm) are coarser" in r.stderr
    assert "warning" not in ipm("predict", photo, "--pixel-size", 0.01 / SCALE, "--models",
                                trained["ensemble"]).stderr


@pytest.mark.parametrize("param", ["alpha_ply", "n", "l_hair", "flyaways"])
def test_saliency_cli(trained, photo, tmp_path, param):
    r = ipm("saliency", photo, "--param", param, "--pixel-size", 0.01 / SCALE,
            "--models", trained["ensemble"], "-o", tmp_path / "s.png")
    assert r.returncode == 0, r.stderr
    s = np.asarray(Image.open(tmp_path / "s.png"))
    assert s.shape == (60, 200) and s.max() == 255


def test_resume_continues_and_refuses_other_options(data, tmp_path):
    from ipm.nets.train import train

    cfg = TrainConfig(data=data / "train", val=data / "val", out=tmp_path, preset="reg",
                      nets=("raw",), **TINY)
    train(cfg, log=lambda line: None)
    lines = []
    train(cfg.replace(epochs=2), log=lines.append)
    assert any("resuming after epoch 1" in line for line in lines)
    assert any("epoch 2/2" in line for line in lines)
    state = json.loads((tmp_path / "raw" / "model.json").read_text())
    assert state["epoch"] in (1, 2)
    with pytest.raises(UserError, match="other options .*lr"):
        train(cfg.replace(lr=0.5), log=lambda line: None)
    with pytest.raises(UserError, match="other options .*blur_px"):
        train(cfg.replace(epochs=3, blur_px=1.0), log=lambda line: None)
    # a run made before an option existed resumes with that option at its default
    saved = json.loads((tmp_path / "train.json").read_text())
    del saved["blur_px"]
    (tmp_path / "train.json").write_text(json.dumps(saved))
    train(cfg.replace(epochs=2), log=lambda line: None)


def test_init_starts_from_trained_weights(trained, data, tmp_path):
    """--init: training starts from the given run's net (with a rate too small to move
    them, its weights come out unchanged), and a net of another configuration is refused
    in one line."""
    from ipm.nets.model import NetConfig, YarnNet
    from ipm.nets.store import load_net
    from ipm.nets.train import train, warm_start

    source = trained["reg"] / "raw"
    net, _ = load_net(source)
    cfg = TrainConfig(data=data / "train", val=data / "val", out=tmp_path / "ft",
                      preset="reg", nets=("raw",), init=trained["reg"], **TINY)
    lines = []
    train(cfg.replace(lr=1e-12), log=lines.append)  # a rate too small to move the weights
    assert any(f"starting from the weights of {source}" in line for line in lines)
    tuned, _ = load_net(tmp_path / "ft" / "raw")
    # the weights (not BatchNorm's running statistics, which a training step updates)
    for (k, a), b in zip(net.named_parameters(), tuned.parameters(), strict=True):
        assert torch.allclose(a, b, atol=1e-6), k
    wider = YarnNet(NetConfig("raw", "resnet18", 0.25, SCALE))
    with pytest.raises(UserError, match="another net .*width 0.125.*width 0.25"):
        warm_start(wider, source)


@pytest.mark.slow
def test_resume_after_kill(data, tmp_path):
    """SIGKILL mid-run leaves a consistent checkpoint that the next run resumes from."""
    args = [sys.executable, "-m", "ipm", "train", "--data", data / "train", "--val",
            data / "val", "--out", tmp_path, "--preset", "reg", "--nets", "raw", "--width",
            0.125, "--input-scale", SCALE, "--batch-size", 4, "--epochs", 1000]
    proc = subprocess.Popen(list(map(str, args)), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, env=ENV)
    ckpt = tmp_path / "raw" / "checkpoint.safetensors"
    deadline = time.time() + 120
    while time.time() < deadline and not ckpt.is_file():
        time.sleep(0.2)
    time.sleep(0.5)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert ckpt.is_file()
    r = ipm("train", "--data", data / "train", "--val", data / "val", "--out", tmp_path,
            "--preset", "reg", "--nets", "raw", "--width", 0.125, "--input-scale", SCALE,
            "--batch-size", 4, "--epochs", 3)
    assert r.returncode == 0, r.stderr
    assert "resuming after epoch" in r.stderr or "done (" in r.stderr


def test_ddp_two_cpu_processes(data, tmp_path):
    """torchrun with two gloo processes trains one net; rank 0 writes the results."""
    r = subprocess.run([sys.executable, "-m", "torch.distributed.run", "--nproc-per-node", "2",
                        "--master-port", "29517", "-m", "ipm", "train",
                        "--data", str(data / "train"), "--val", str(data / "val"),
                        "--out", str(tmp_path), "--preset", "reg", "--nets", "raw",
                        "--width", "0.125", "--input-scale", str(SCALE), "--batch-size", "4",
                        "--epochs", "2"], capture_output=True, text=True, env=ENV, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stderr.count("epoch 2/2") == 1  # only rank 0 reports
    info = json.loads((tmp_path / "raw" / "model.json").read_text())
    assert info["epoch"] in (1, 2)


# -- one-line errors ---------------------------------------------------------------------------
def _one_line_error(r):
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert r.stderr.startswith("error: ") and r.stderr.count("\n") == 1, r.stderr
    assert "Traceback" not in r.stderr


def _bad_photo(tmp_path, kind):
    path = tmp_path / "bad.png"
    if kind == "text":
        path.write_text("hello")
    elif kind == "truncated":
        Image.fromarray(np.full((60, 200, 3), 99, np.uint8)).save(path)
        path.write_bytes(path.read_bytes()[:200])
    elif kind == "tiny":  # a bright band across a dark 30 x 20 px frame: a yarn, too small
        img = np.zeros((20, 30, 3), np.uint8)
        img[8:12] = 200
        Image.fromarray(img).save(path)
    elif kind == "huge":
        Image.new("1", (12_000, 11_000)).save(path)
    elif kind == "missing":
        pass
    return path


@pytest.mark.parametrize("kind, message", [
    ("text", "is not an image"), ("truncated", "cannot decode"), ("tiny", "too small"),
    ("huge", "too large"), ("missing", "no such file")])
def test_predict_bad_photo(trained, tmp_path, kind, message):
    from ipm.nets.commands import predict

    with pytest.raises(UserError, match=message):
        predict([_bad_photo(tmp_path, kind)], pixel_size=0.01 / SCALE,
                models=trained["ensemble"])


def test_predict_bad_photo_cli(trained, tmp_path):
    r = ipm("predict", _bad_photo(tmp_path, "truncated"), "--pixel-size", 0.01 / SCALE,
            "--models", trained["ensemble"])
    _one_line_error(r)
    assert "pixel size" not in r.stderr, r.stderr  # the photo's fault, said


@pytest.mark.parametrize("mode", ["L", "I;16", "RGBA", "P"])
def test_predict_accepts_other_modes(trained, photo, tmp_path, mode, capsys):
    from ipm.nets.commands import predict

    img = Image.open(photo)
    img = (Image.fromarray(np.asarray(img.convert("L")).astype(np.uint16) * 257)
           if mode == "I;16" else img.convert(mode))
    img.save(tmp_path / "m.png")
    predict([tmp_path / "m.png"], pixel_size=0.01 / SCALE, models=trained["ensemble"])
    assert YarnParams.from_json(capsys.readouterr().out)


@pytest.fixture
def damaged_run(trained, tmp_path):
    import shutil

    return shutil.copytree(trained["ensemble"], tmp_path / "run")


@pytest.mark.parametrize("damage, message", [
    (lambda run: (run / "alpha" / "model.safetensors").unlink(), "not found"),
    (lambda run: (run / "alpha" / "model.safetensors").write_bytes(b"garbage"), "corrupt"),
    (lambda run: (run / "alpha" / "model.json").write_text("{"), "not readable JSON"),
    (lambda run: (run / "ensemble.json").unlink(), "holds no trained models"),
])
def test_predict_bad_models(damaged_run, damage, message):
    from ipm.nets.ensemble import Ensemble

    damage(damaged_run)
    with pytest.raises(UserError, match=message):
        Ensemble.load(damaged_run)


def test_predict_nan_weights_in_an_integer_net_cli(damaged_run, photo):
    from safetensors.torch import load_file, save_file

    path = damaged_run / "m" / "model.safetensors"
    tensors = load_file(path)
    tensors = {k: v.fill_(float("nan")) if v.is_floating_point() else v
               for k, v in tensors.items()}
    save_file(tensors, path)
    r = ipm("predict", photo, "--pixel-size", 0.01 / SCALE, "--models", damaged_run)
    _one_line_error(r)
    assert "non-finite weights" in r.stderr


def test_predict_bad_models_cli(damaged_run, photo):
    (damaged_run / "m" / "model.safetensors").write_bytes(b"\x80\x04pickle")
    r = ipm("predict", photo, "--pixel-size", 0.01 / SCALE, "--models", damaged_run)
    _one_line_error(r)
    assert "corrupt" in r.stderr


def test_no_shipped_models_names_how_to_train(monkeypatch, tmp_path):
    from ipm.nets import ensemble

    monkeypatch.setattr(ensemble, "SHIPPED_FOR", {"frontlit": tmp_path, "backlit": tmp_path})
    with pytest.raises(UserError, match="no backlit models .*ipm train --setup backlit"):
        ensemble.Ensemble.load(setup="backlit")


def test_nets_know_their_capture_setup(trained, data, photo, tmp_path):
    """A run records the setup of its renders; nets of one setup refuse photos and requests
    of the other, and training refuses renders of another setup than --setup."""
    from ipm.nets.ensemble import Ensemble
    from ipm.photo import Photo

    run = trained["ensemble"]
    assert json.loads((run / "ensemble.json").read_text())["setup"] == "frontlit"
    with pytest.raises(UserError, match="trained on frontlit renders, not backlit"):
        Ensemble.load(run, setup="backlit")
    with pytest.raises(UserError, match="is a backlit photo; the nets .* read frontlit"):
        Ensemble.load(run).predict(Photo.read(photo, 0.01 / SCALE, "backlit"))
    r = ipm("predict", photo, "--pixel-size", 0.01 / SCALE, "--models", run,
            "--setup", "backlit")
    _one_line_error(r)
    assert "trained on frontlit renders" in r.stderr
    r = ipm("train", "--data", data / "train", "--val", data / "val", "--out", tmp_path / "o",
            "--setup", "backlit", "--width", 0.125, "--input-scale", SCALE, "--epochs", 1)
    _one_line_error(r)
    assert "holds frontlit renders; these nets are for backlit photos" in r.stderr


def test_train_bad_options(data, tmp_path):
    r = ipm("train", "--data", data / "train", "--val", data / "val", "--out", tmp_path / "o",
            "--preset", "reg-latent")
    _one_line_error(r)
    assert "--real" in r.stderr
    ok = dict(data=data / "train", val=data / "val", out=tmp_path / "o")
    for bad, message in [(dict(data=tmp_path), "manifest.jsonl not found"),
                         (dict(nets=("beta",)), "has no net beta"),
                         (dict(input_scale=1.5), "input scale"),
                         (dict(encoder="vgg"), "unknown encoder")]:
        with pytest.raises(UserError, match=message):
            from ipm.nets.train import train

            train(TrainConfig(**{**ok, **bad}), log=lambda line: None)


def test_gather_nets_builds_one_ensemble_from_runs(trained, photo, tmp_path):
    """scripts/gather_nets.py (make_nets.sh's last step): a later run's net replaces the same
    net of an earlier run, a RUN=SUFFIX run's nets are renamed, the multi-task net comes
    after the per-parameter ones, and the folder loads and predicts."""
    import shutil
    from pathlib import Path

    from ipm.nets.ensemble import Ensemble

    ens, reg = trained["ensemble"], tmp_path / "reg"
    shutil.copytree(trained["reg"], reg)
    info = json.loads((reg / "flyaways" / "model.json").read_text())
    (reg / "flyaways" / "model.json").write_text(json.dumps({**info, "mark": "later run"}))
    script = Path(__file__).parents[1] / "scripts" / "gather_nets.py"
    out = tmp_path / "models"
    r = subprocess.run([sys.executable, str(script), out, ens, reg, f"{ens}=-detail"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    per_net = json.loads((ens / "ensemble.json").read_text())["nets"]
    nets = json.loads((out / "ensemble.json").read_text())["nets"]
    assert nets[:len(per_net)] == per_net and nets[len(per_net)] == "raw"
    assert nets[len(per_net) + 1:] == [f"{n}-detail" for n in per_net]
    assert json.loads((out / "flyaways" / "model.json").read_text())["mark"] == "later run"
    from safetensors.torch import load_file

    weights = "model.safetensors"  # the run's net, stored in float16
    gathered, trained_net = (load_file(str(f / weights)) for f in (out / "m-detail", ens / "m"))
    assert gathered.keys() == trained_net.keys()
    for k, v in trained_net.items():
        assert gathered[k].dtype == (torch.float16 if v.is_floating_point() else v.dtype)
        assert torch.equal(gathered[k], v.half() if v.is_floating_point() else v)
    assert not list(out.glob("*/checkpoint*")) and not out.with_name("models.new").exists()
    from ipm.photo import Photo

    assert Ensemble.load(out).predict(Photo.read(photo, 0.01 / SCALE)).n in range(2, 7)
