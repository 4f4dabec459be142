"""The second probe of the CLI (issue 49), one test per defect: nothing a user owns is
overwritten, no traceback or hang, no silently wrong answer, folder runs that finish."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
GOLDEN_PNG = ROOT / "examples" / "golden.png"


def ipm(*args, timeout=120, env=None, **kw):
    return subprocess.run([sys.executable, "-m", "ipm", *map(str, args)], capture_output=True,
                          text=True, timeout=timeout, env=env, **kw)


def one_line_error(r, *words):
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and all(w in lines[0] for w in words), r.stderr
    assert "Traceback" not in r.stderr


@pytest.fixture
def golden(tmp_path):
    p = tmp_path / "p.json"
    p.write_text(json.dumps(json.loads((ROOT / "examples" / "golden.json").read_text())
                            ["params"]))
    return p


# 1. Nothing a command read, or did not make, is written over (unless --force).

def test_edit_does_not_write_over_the_sidecar_it_read(tmp_path):
    sidecar = tmp_path / "g.json"
    shutil.copy(ROOT / "examples" / "golden.json", sidecar)
    before = sidecar.read_bytes()
    one_line_error(ipm("edit", sidecar, "--set", "g=*2", "-o", sidecar), str(sidecar), "--force")
    assert sidecar.read_bytes() == before
    r = ipm("edit", sidecar, "--set", "g=*2", "-o", sidecar, "--force")
    assert r.returncode == 0, r.stderr
    assert json.loads(sidecar.read_text())["g"] == 2 * json.loads(before)["params"]["g"]


def test_predict_into_the_photos_folder_keeps_the_users_json(tmp_path):
    photos = tmp_path / "photos"
    photos.mkdir()
    shutil.copy(GOLDEN_PNG, photos / "a.png")
    shutil.copy(GOLDEN_PNG, photos / "b.png")
    (photos / "a.json").write_text('{"note": "mine"}')
    one_line_error(ipm("predict", photos, "--pixel-size", "0.04", "-o", photos),
                   str(photos / "a.json"), "--force")
    assert (photos / "a.json").read_text() == '{"note": "mine"}'
    assert not (photos / "b.json").exists()


def test_fit_does_not_write_over_the_photos_sidecar(tmp_path):
    x = tmp_path / "x"
    x.mkdir()
    shutil.copy(GOLDEN_PNG, x / "params.png")
    shutil.copy(ROOT / "examples" / "golden.json", x / "params.json")
    before = (x / "params.json").read_bytes()
    one_line_error(ipm("fit", x / "params.png", "--out", x), str(x / "params.json"), "--force")
    assert (x / "params.json").read_bytes() == before


# 2. A resumed comparison is tied to each photo's content.

def test_compare_resume_fits_a_replaced_or_fixed_photo_again(tmp_path):
    from PIL import Image

    from ipm.dataset import Record
    from ipm.errors import UserError
    from ipm.refine.compare import fit_all

    a, b, c = (tmp_path / f"{k}.png" for k in "abc")
    for p in (a, b):
        Image.fromarray(np.full((64, 200, 3), 30 + 10 * (p == b), np.uint8)).save(p)
    c.write_text("not an image")
    records = [Record(p, 0.02) for p in (a, b, c)]
    runs = iter(range(100))

    def neural_of(i, photo):  # every attempt fails with its own number: no renders needed
        raise UserError(f"attempt {next(runs)}")

    fits = tmp_path / "fits.jsonl"
    first = fit_all(fits, records, neural_of, None, None)
    assert [r["error"] for r in first[:2]] == ["attempt 0", "attempt 1"]
    assert "not an image" in first[2]["error"]
    Image.fromarray(np.full((64, 200, 3), 90, np.uint8)).save(b)  # replaced
    shutil.copy(a, c)  # fixed
    again = fit_all(fits, records, neural_of, None, None)
    assert again[0]["error"] == "attempt 0"  # unchanged: resumed
    assert again[1]["error"] == "attempt 2" and again[2]["error"] == "attempt 3"


# 3. One-line errors, and the output's suffix decides the curve format.

@pytest.mark.parametrize("fmt, name, words", [
    ("usd", "y.txt", "--format usd"), ("ply", "p.usda", "--format ply"),
    (None, "y", "cannot tell the format")])
def test_curves_format_and_suffix_must_agree(golden, tmp_path, fmt, name, words):
    args = ["--format", fmt] if fmt else []
    one_line_error(ipm("curves", golden, "-o", tmp_path / name, *args), words)
    assert not (tmp_path / name).exists()


def test_curves_format_follows_the_suffix(golden, tmp_path):
    for name in ("y.usda", "y.ply", "y.txt"):
        assert ipm("curves", golden, "-o", tmp_path / name).returncode == 0
    assert (tmp_path / "y.usda").read_text().startswith("#usda")
    assert (tmp_path / "y.ply").read_bytes().startswith(b"ply")
    assert (tmp_path / "y.txt").read_text()[0] in "-0123456789"


# 4. Memory linear in the yarn, a patch too large refused before any work.

def _find_segments_before(cum, lengths, rng):
    """The code before: a copy of the cumulative lengths per flyaway (``c = cum[f]``)."""
    from ipm.generator import FLYAWAY_TRIES

    f_count, v = cum.shape
    g = len(lengths)
    fib, start, end = (np.zeros(g, dtype=np.int64) for _ in range(3))
    todo = np.arange(g)
    for _ in range(FLYAWAY_TRIES):
        if not len(todo):
            break
        f = rng.integers(f_count, size=len(todo))
        s = rng.integers(v, size=len(todo))
        forward = rng.random(len(todo)) < 0.5
        c = cum[f]
        target = np.where(forward, c[np.arange(len(todo)), s] + lengths[todo],
                          c[np.arange(len(todo)), s] - lengths[todo])
        idx = np.array([np.searchsorted(row, t) for row, t in zip(c, target, strict=True)])
        e = np.where(forward, idx, idx - 1)
        ok = (target <= c[:, -1]) & (target >= 0) & (np.abs(e - s) >= 2)
        fib[todo[ok]], start[todo[ok]], end[todo[ok]] = f[ok], s[ok], e[ok]
        todo = todo[~ok]
    if len(todo):
        f = rng.integers(f_count, size=len(todo))
        fib[todo], start[todo], end[todo] = f, 0, v - 1
    return fib, start, end


def test_flyaway_segments_need_no_copy_per_flyaway():
    """Same segments as before from the same draws, in memory linear in the yarn (the copy
    per flyaway was 2000 x 4000 x 8 bytes = 64 MB here, quadratic in the yarn's length)."""
    import tracemalloc

    from ipm.generator import _find_segments

    step = np.random.default_rng(1).uniform(0.01, 0.05, (60, 4000))
    cum = np.concatenate([np.zeros((60, 1)), np.cumsum(step, axis=1)], axis=1)
    lengths = np.random.default_rng(2).uniform(0.5, 200.0, 2000)  # some too long: clipped
    old = _find_segments_before(cum, lengths, np.random.default_rng(3))
    tracemalloc.start()
    new = _find_segments(cum, lengths, np.random.default_rng(3))
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    for a, b in zip(old, new, strict=True):
        np.testing.assert_array_equal(a, b)
    assert peak < 8_000_000


def test_a_patch_too_large_for_memory_is_refused_before_any_work(tmp_path):
    """pink_6ply with 200 fibers a ply and doubled radii (all in range), 40 x 40 stitches.
    The call runs under a 3 GB address-space limit, so that the code before fails there
    rather than taking the machine's memory."""
    from ipm.presets import preset

    d = preset("pink_6ply").to_dict()
    d.update(m=200, R_ply=2 * d["R_ply"], r_x=2 * d["r_x"], r_y=2 * d["r_y"])
    (tmp_path / "thick.json").write_text(json.dumps(d))
    limit = ("import resource, sys, runpy; resource.setrlimit(resource.RLIMIT_AS, "
             "(3 << 30, 3 << 30)); sys.argv = ['ipm', *sys.argv[1:]]; "
             "runpy.run_module('ipm', run_name='__main__')")
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-c", limit, "curves", tmp_path / "thick.json",
                        "--knit", "knit", "--stitches", "40x40", "-o", tmp_path / "y.npz"],
                       capture_output=True, text=True, timeout=300)
    one_line_error(r, "GB", "--stitches")
    assert time.perf_counter() - t0 < 60 and not (tmp_path / "y.npz").exists()


# 5. A render of 2^32 samples or more is refused (Dr.Jit crashed on it).

def test_a_render_of_too_many_samples_is_one_line(golden, tmp_path):
    r = ipm("render", golden, "--scale", "0.1", "--spp", "400000", "-o", tmp_path / "r.png",
            timeout=300)
    one_line_error(r, "2^32", "--spp")
    assert not (tmp_path / "r.png").exists()


# 6. A FIFO is not read (it would block forever).

def test_a_fifo_is_not_a_photo(tmp_path):
    fifo = tmp_path / "fifo.png"
    os.mkfifo(fifo)
    one_line_error(ipm("calibrate", fifo, timeout=60), str(fifo), "not a regular file")
    one_line_error(ipm("predict", fifo, timeout=60), str(fifo), "not a regular file")


# 7. The capture setup, chosen from the photo and said; carried by a fit's params.json.

def test_the_setup_is_told_from_the_photo():
    from ipm.photo import Photo, detect_setup

    shot = Photo.read(GOLDEN_PNG)
    assert detect_setup(shot.image)[0] == "frontlit"
    negative = shot.inverted().image  # a dark yarn on a light background: backlit if grey
    assert detect_setup(np.repeat(negative.mean(axis=2, keepdims=True), 3, axis=2))[0] == (
        "backlit")


@pytest.mark.slow
def test_predict_says_it_reads_a_backlit_photo_as_one(tmp_path):
    from PIL import Image

    img = np.asarray(Image.open(GOLDEN_PNG).convert("L"))
    Image.fromarray(255 - img).save(tmp_path / "backlit.png")
    r = ipm("predict", tmp_path / "backlit.png", "--pixel-size", "0.04", timeout=300)
    assert r.returncode == 0, r.stderr
    assert "backlit" in r.stderr and "--setup" in r.stderr


@pytest.mark.slow
def test_render_of_a_backlit_fit_renders_backlit(golden, tmp_path):
    fit = {"neural": json.loads(golden.read_text()), "settings": {"setup": "backlit"}}
    (tmp_path / "params.json").write_text(json.dumps(fit))
    r = ipm("render", tmp_path / "params.json", "--scale", "0.05", "--spp", "1",
            "-o", tmp_path / "r.png", timeout=300)
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "r.json").read_text())["setup"] == "backlit"


# 8. Integer parameters take integers only.

@pytest.mark.parametrize("spec", ["n=2.5", "n=*1.5", "m=40.2", "g=*0.33"])
def test_integer_edits_are_not_rounded(spec):
    from ipm.edit import apply_edits
    from ipm.errors import ParamError
    from ipm.presets import preset

    with pytest.raises(ParamError, match="integer"):
        apply_edits(preset("golden"), [spec])
    assert apply_edits(preset("golden"), ["n=*2"]).n == 6


def test_edit_sets_the_colour():
    from ipm.edit import apply_edits
    from ipm.errors import ParamError
    from ipm.presets import preset

    assert apply_edits(preset("golden"), ["color=0.5,0.25,0.1"]).color == (0.5, 0.25, 0.1)
    with pytest.raises(ParamError, match="color"):
        apply_edits(preset("golden"), ["color=*2"])


# 9. Folder runs finish every good photo, list each bad one, exit non-zero.

@pytest.mark.slow
def test_predict_folder_goes_past_bad_files(tmp_path):
    photos, out = tmp_path / "photos", tmp_path / "out"
    photos.mkdir()
    shutil.copy(GOLDEN_PNG, photos / "a.png")
    (photos / "b.png").write_text("not an image")
    os.mkfifo(photos / "c.png")
    (photos / "d.png").symlink_to(photos / "d.png")  # a loop
    shutil.copy(GOLDEN_PNG, photos / "e.png")
    r = ipm("predict", photos, "--pixel-size", "0.04", "-o", out, timeout=300)
    assert r.returncode == 1, r.stderr
    assert "Traceback" not in r.stderr
    assert (out / "a.json").is_file() and (out / "e.json").is_file()
    failed = [ln for ln in r.stderr.splitlines() if ln.startswith("error: ")]
    assert [ln.split()[1].rstrip(":") for ln in failed[:3]] == [
        str(photos / k) for k in ("b.png", "c.png", "d.png")], r.stderr
    assert "3 of 5 photos failed" in r.stderr


@pytest.mark.slow
def test_compare_lists_bad_photos_and_fails(tmp_path):
    """A photo that cannot be read and one that is gone (a dangling link): both listed, the
    report written, exit 1 (it was 0, and the dangling link aborted the run)."""
    photos = tmp_path / "photos"
    photos.mkdir()
    (photos / "a.png").write_text("not an image")
    (photos / "b.png").symlink_to(tmp_path / "gone.png")
    r = ipm("compare", photos, "--out", tmp_path / "cmp", "--pixel-size", "0.02",
            timeout=300)
    assert r.returncode == 1, r.stderr
    assert "a.png" in r.stderr and "b.png" in r.stderr and "Traceback" not in r.stderr
    report = (tmp_path / "cmp" / "index.md").read_text()
    assert "a.png" in report and "b.png" in report


# 10. SIGTERM is an interruption; a run without a terminal says what it does.

@pytest.mark.slow
def test_sigterm_is_a_clean_interruption(tmp_path):
    out = tmp_path / "fit"
    proc = subprocess.Popen([sys.executable, "-m", "ipm", "fit", str(GOLDEN_PNG), "--out",
                             str(out)], stderr=subprocess.PIPE, text=True)
    # the setup's note is the fit's first line: the nets, the search and the writing follow
    first = proc.stderr.readline()
    assert proc.poll() is None, first
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    err = first + err
    assert proc.returncode == 143, err
    assert "interrupted" in err and "Traceback" not in err
    assert not out.exists()


def test_progress_without_a_terminal_prints_lines(capsys):
    from ipm.progress import progress_bar

    with progress_bar("best {task.fields[best]}") as bar:
        task = bar.add_task("fits", total=3, best="-")
        for i in range(3):
            bar.update(task, completed=i + 1, best=f"{i}")
    err = capsys.readouterr().err.splitlines()
    assert err[-1].startswith("fits 3/3") and "best 2" in err[-1]


# Smaller ones.

def test_version():
    r = ipm("--version")
    assert r.returncode == 0 and r.stdout.startswith("ipm ")


@pytest.mark.parametrize("change, words", [
    ({"pixel_size_mm": True}, "pixel_size_mm"), ({"pixel_size_mm": "0.01"}, "pixel_size_mm"),
    ({"tick_mm": None}, "tick_mm")])
def test_calibration_errors_name_the_field(tmp_path, change, words):
    from ipm.calibrate import Calibration
    from ipm.errors import UserError

    cal = {"format": "ipm.calibration/1", "pixel_size_mm": 0.01, "tick_period_px": 100.0,
           "angle_deg": 0.0, "tick_mm": 1.0, "source": "ruler.png"}
    (tmp_path / "c.json").write_text(json.dumps({**cal, **change}))
    with pytest.raises(UserError, match=words):
        Calibration.load(tmp_path / "c.json")


@pytest.mark.parametrize("value", [True, 1000.0])
def test_a_bad_sidecar_pixel_size_names_the_sidecar(tmp_path, value):
    from ipm.errors import UserError
    from ipm.photo import pixel_size_of

    shutil.copy(GOLDEN_PNG, tmp_path / "y.png")
    (tmp_path / "y.json").write_text(json.dumps({"pixel_size_mm": value}))
    with pytest.raises(UserError, match="y.json"):
        pixel_size_of(tmp_path / "y.png")


def test_fit_help_fits_80_columns():
    r = ipm("fit", "--help", env={**os.environ, "COLUMNS": "80"})
    assert r.returncode == 0
    lines = r.stdout.splitlines()
    assert "…" not in r.stdout and max(map(len, lines)) <= 80
    assert "--refine" in r.stdout and "--sure-count" in r.stdout


def test_messages_name_the_files(tmp_path):
    photos = tmp_path / "photos"
    (photos / "x").mkdir(parents=True)
    shutil.copy(GOLDEN_PNG, photos / "a.png")
    shutil.copy(GOLDEN_PNG, photos / "x" / "a.png")
    one_line_error(ipm("predict", photos / "a.png", photos / "x" / "a.png", "--pixel-size",
                       "0.04", "-o", tmp_path / "out"), str(photos / "a.png"),
                   str(photos / "x" / "a.png"))
    from PIL import Image

    Image.new("RGB", (8, 8)).save(tmp_path / "tiny.png")
    one_line_error(ipm("calibrate", tmp_path / "tiny.png"), str(tmp_path / "tiny.png"))
