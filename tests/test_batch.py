"""``ipm fit FOLDER`` (ipm.refine.batch) and its workers (ipm.workers): a folder's photos each
fitted into its own folder, resumed after a stop without fitting a photo twice, bad files
named and the rest fitted, the report made from the folders alone; the same params.json
with one worker or two.  The driver's tests stand a recording fitter in for the nets (what
is tested is the driver); the slow ones fit for real."""

from __future__ import annotations

import hashlib
import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from ipm.errors import UserError
from ipm.refine import batch
from ipm.refine.fitter import FitJob

GOLDEN = Path(__file__).resolve().parent.parent / "examples" / "golden.png"


def photo(path: Path, seed: int) -> Path:
    rng = np.random.default_rng(seed)
    Image.fromarray(rng.integers(0, 255, (12, 20, 3), dtype=np.uint8)).save(path)
    return path


class Recorder:
    """A fitter that fits nothing: it returns a params.json naming the photo's bytes'
    hash (as a fit's does) and counts its calls; ``interrupt_at``: the call that is stopped
    as Ctrl-C stops one."""

    calls: list[str] = []
    interrupt_at: int | None = None

    def __init__(self, models=None, variant=None, threads=None) -> None:
        pass

    def fit_file(self, name: str, data: bytes, pixel_size: float, job: FitJob) -> dict:
        Recorder.calls.append(name)
        if len(Recorder.calls) == Recorder.interrupt_at:
            raise KeyboardInterrupt
        try:
            Image.open(io.BytesIO(data))
        except OSError:
            return {"error": f"{name} is not an image Pillow can read", "worker": {}}
        value = data[-20] / 255  # a parameter that follows the photo
        params = {"refined": {"n": 2, "m": 50, "alpha": -2.0, "r_x": 0.1, "r_y": 0.1,
                              "alpha_ply": 3 + value, "R_ply": 0.2, "g": 10, "l_hair": 1,
                              "l_loop": 1, "d_mean": 0.5},
                  "intervals": {"alpha_ply": [2.5 + value, 3.5 + value, "search"]},
                  "loss": {"neural": 0.3, "refined": 0.2}, "improved": True, "warnings": [],
                  "photo": {"file": name, "sha256": hashlib.sha256(data).hexdigest()},
                  "textile": {"photo": {"diameter_mm": 0.4 + value, "hairiness_h": 2.0,
                                        "twist_direction": "S"}}}
        return {"files": {"params.json": json.dumps(params).encode(),
                          "compare.png": b"png"}, "lines": [], "seconds": 0.1, "worker": {}}


def folder_of(tmp_path: Path, count: int) -> Path:
    """A folder of ``count`` small photos f0.png, f1.png, ..."""
    photos = tmp_path / "photos"
    photos.mkdir()
    for i in range(count):
        photo(photos / f"f{i}.png", i)
    return photos


@pytest.fixture
def recorder(monkeypatch):
    monkeypatch.setattr("ipm.refine.fitter.Fitter", Recorder)
    Recorder.calls, Recorder.interrupt_at = [], None
    return Recorder


def run(folder: Path, out: Path, **kw) -> int:
    return batch.fit_folder(folder, out, FitJob(), 0.01, None, None, None,
                            kw.get("workers"), None)


def test_a_folder_is_fitted_into_a_folder_per_photo_with_a_report(tmp_path, recorder, capsys):
    photos = folder_of(tmp_path, 3)
    (photos / "broken.png").write_bytes(b"not an image")
    (photos / "notes.txt").write_text("not a photo")
    out = tmp_path / "out"
    assert run(photos, out) == 1  # a photo failed
    err = capsys.readouterr().err
    assert "error: not fitted: broken.png is not an image Pillow can read" in err
    assert "3 of 4 photos fitted" in err
    for i in range(3):
        params = json.loads((out / f"f{i}" / "params.json").read_text())
        assert params["photo"]["file"] == f"f{i}.png"
        assert json.loads((out / f"f{i}" / "run.json").read_text())["fit_seconds"] == 0.1
    rows = (out / batch.CSV).read_text().splitlines()
    assert rows[0].startswith("photo,folder,status,error")
    assert [r.split(",")[:3] for r in rows[1:]] == [
        ["broken.png", "broken", "failed"], *[[f"f{i}.png", f"f{i}", "fitted"]
                                              for i in range(3)]]
    assert (out / batch.FIGURE).read_bytes().startswith(b"\x89PNG")
    assert "3 of 4 photos fitted" in (out / batch.PAGE).read_text()


def test_a_rerun_fits_only_what_is_missing_or_changed(tmp_path, recorder):
    photos = folder_of(tmp_path, 3)
    out = tmp_path / "out"
    assert run(photos, out) == 0
    report = (out / batch.CSV).read_bytes()
    recorder.calls.clear()
    assert run(photos, out) == 0
    assert recorder.calls == []  # nothing fitted twice
    assert (out / batch.CSV).read_bytes() == report
    photo(photos / "f1.png", 7)  # the same name, another photo
    assert run(photos, out) == 0
    assert recorder.calls == ["f1.png"]


def test_an_interrupted_run_resumes_to_the_same_report(tmp_path, recorder, capsys):
    photos = folder_of(tmp_path, 4)
    whole = tmp_path / "whole"
    assert run(photos, whole) == 0
    recorder.calls.clear()
    recorder.interrupt_at = 3
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        run(photos, out)
    assert "2 of 4 photos not fitted yet; the same command resumes" in capsys.readouterr().err
    assert sorted(p.parent.name for p in out.glob("*/params.json")) == ["f0", "f1"]
    recorder.calls.clear()
    recorder.interrupt_at = None
    assert run(photos, out) == 0
    assert recorder.calls == ["f2.png", "f3.png"]
    for name in (batch.CSV, batch.PAGE, batch.FIGURE):
        assert (out / name).read_bytes() == (whole / name).read_bytes()


def test_a_folder_fit_refuses_what_it_cannot_do(tmp_path, recorder):
    photos = folder_of(tmp_path, 1)
    with pytest.raises(UserError, match="is the folder of photos"):
        run(photos, photos)
    other = tmp_path / "other"
    other.mkdir()
    (other / "mine.txt").write_text("a user's file")
    with pytest.raises(UserError, match="not empty and holds no settings.json"):
        run(photos, other)
    out = tmp_path / "out"
    assert run(photos, out) == 0
    with pytest.raises(UserError, match="other settings"):
        batch.fit_folder(photos, out, FitJob(refine=True), 0.01, None, None, None, None, None)
    with pytest.raises(UserError, match="use --workers 2"):
        batch.check_memory(1000, gb=free_gb() / 2.5)
    assert recorder.calls == ["f0.png"]


def free_gb() -> float:
    with open("/proc/meminfo") as f:
        info = dict(line.split(":", 1) for line in f)
    return int(info["MemAvailable"].split()[0]) / 2**20


def test_two_photos_of_one_stem_get_two_folders(tmp_path, recorder):
    photos = tmp_path / "photos"
    photos.mkdir()
    photo(photos / "a.png", 0)
    photo(photos / "a.tif", 1)
    run(photos, tmp_path / "out")
    assert sorted(p.name for p in (tmp_path / "out").iterdir() if p.is_dir()) == [
        "a_png", "a_tif"]


def golden_folder(tmp_path: Path) -> Path:
    """Two small frontlit photos: the bundled example's left and right halves."""
    photos = tmp_path / "photos"
    photos.mkdir()
    img = np.asarray(Image.open(GOLDEN).convert("RGB"))
    half = img.shape[1] // 2
    Image.fromarray(img[:, :half]).save(photos / "left.png")
    Image.fromarray(img[:, half:]).save(photos / "right.png")
    return photos


def ipm(*args) -> list[str]:
    return [sys.executable, "-m", "ipm", *map(str, args)]


@pytest.mark.slow
def test_one_worker_or_two_give_the_same_params_json(tmp_path):
    photos = golden_folder(tmp_path)
    common = ["--pixel-size", "0.02", "--setup", "frontlit"]
    for name, extra in (("one", []), ("two", ["--workers", "2"])):
        r = subprocess.run(ipm("fit", photos, "-o", tmp_path / name, *common, *extra),
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
    pids = set()
    for stem in ("left", "right"):
        assert ((tmp_path / "one" / stem / "params.json").read_bytes()
                == (tmp_path / "two" / stem / "params.json").read_bytes())
        pids.add(json.loads((tmp_path / "two" / stem / "run.json").read_text())["worker"]["pid"])
    assert len(pids) == 2  # fitted side by side
    single = tmp_path / "single"
    r = subprocess.run(ipm("fit", photos / "left.png", "-o", single, *common),
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert (single / "params.json").read_bytes() == (
        tmp_path / "one" / "left" / "params.json").read_bytes()


@pytest.mark.slow
def test_a_killed_run_leaves_no_worker_and_resumes(tmp_path):
    photos = golden_folder(tmp_path)
    out = tmp_path / "out"
    cmd = ipm("fit", photos, "-o", out, "--pixel-size", "0.02", "--setup", "frontlit",
              "--workers", "2")
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    deadline = time.monotonic() + 300
    while not list(out.glob("*/params.json")) and time.monotonic() < deadline:
        time.sleep(0.1)
    children = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True,
                              text=True).stdout.split()
    os.kill(proc.pid, signal.SIGKILL)  # the driver alone
    proc.wait()
    first = {p.parent.name: p.stat().st_mtime_ns for p in out.glob("*/params.json")}
    assert first
    time.sleep(3)
    alive = [c for c in children if Path(f"/proc/{c}").exists()
             and "zombie" not in Path(f"/proc/{c}/status").read_text().lower()]
    assert alive == []  # the workers died with their driver
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    for name, mtime in first.items():
        assert (out / name / "params.json").stat().st_mtime_ns == mtime  # not fitted again
    assert sorted(p.parent.name for p in out.glob("*/params.json")) == ["left", "right"]


def test_nets_sent_as_bytes_unpack_to_the_same_files(tmp_path):
    from ipm.nets.ensemble import SHIPPED_FOR, Ensemble
    from ipm.nets.store import pack_ensemble, unpack_ensemble

    folder = SHIPPED_FOR["backlit"]
    copy = unpack_ensemble(pack_ensemble(folder))
    files = sorted(p.relative_to(copy) for p in copy.rglob("*") if p.is_file())
    assert Path("ensemble.json") in files and len(files) > 10
    for f in files:
        assert (copy / f).read_bytes() == (folder / f).read_bytes()
    assert Ensemble.load(copy, setup="backlit").setup == "backlit"
