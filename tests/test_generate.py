"""``ipm generate``: the dataset contract, determinism per sample, kill-and-resume, bad input."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from PIL import Image

from ipm.dataset import MANIFEST, read_manifest
from ipm.errors import UserError
from ipm.params import YarnParams
from ipm.render.dataset import (
    GenerateOptions,
    generate_dataset,
    sample_plan,
    sample_seeds,
    spp_range,
)
from ipm.render.photometric import Photometric

TINY = ("--scale", "0.1", "--spp", "2")


def ipm_args(*args):
    return [sys.executable, "-m", "ipm", *map(str, args)]


def ipm(*args):
    return subprocess.run(ipm_args(*args), capture_output=True, text=True)


def check_dataset(folder, count):
    """Exactly ``count`` samples, one per index, each a whole PNG of the right size."""
    lines = (folder / MANIFEST).read_text().splitlines()
    records = [json.loads(line) for line in lines]
    assert sorted(r["index"] for r in records) == list(range(count))
    for r in records:
        with Image.open(folder / r["image"]) as img:
            img.load()
            assert img.mode == "RGB" and img.size == (r["width"], r["height"])
    return records


def test_sample_seeds_depend_on_seed_split_index_only():
    a, b = sample_seeds(0, "train", 5), sample_seeds(0, "train", 5)
    assert a.fiber_seed == b.fiber_seed and a.render_seed == b.render_seed
    assert a.params_rng.random() == b.params_rng.random()
    others = [sample_seeds(1, "train", 5), sample_seeds(0, "val", 5), sample_seeds(0, "train", 6)]
    assert all(o.fiber_seed != a.fiber_seed for o in others)
    opts = GenerateOptions(count=10, seed=0)
    assert sample_plan(opts, 3) == sample_plan(opts, 3)


def test_an_spp_range_draws_each_samples_count_within_it_and_leaves_the_rest():
    fixed, ranged = GenerateOptions(count=200), GenerateOptions(count=200, spp=4, spp_max=24)
    plans = [sample_plan(ranged, i) for i in range(200)]
    counts = [p.spp for p in plans]
    assert min(counts) == 4 and max(counts) == 24
    # log-uniform: as many samples below the geometric mean (~9.8) as above it
    assert 70 < sum(c < 9.8 for c in counts) < 130
    assert [p.spp for p in map(sample_plan, [ranged] * 5, range(5))] == counts[:5]
    for i, p in enumerate(plans[:20]):  # the sample count changes nothing else of a sample
        q = sample_plan(fixed, i)
        assert (p.params, p.fiber_seed, p.render_seed, p.photometric) == \
            (q.params, q.fiber_seed, q.render_seed, q.photometric)
        assert q.spp == 6
    assert "spp_max" not in fixed.settings() and ranged.settings()["spp_max"] == 24


def test_spp_text_is_a_count_or_a_range():
    assert spp_range("6") == (6, None) and spp_range("4-24") == (4, 24)
    with pytest.raises(UserError, match="range like 4-24"):
        spp_range("many")
    with pytest.raises(UserError, match="empty"):
        GenerateOptions(count=1, spp=8, spp_max=4)


def test_manifest_contract(tmp_path):
    records = generate_dataset(tmp_path / "ds", GenerateOptions(count=3, seed=1, scale=0.1,
                                                                spp=2), workers=2)
    assert records == read_manifest(tmp_path / "ds")
    assert [r.to_dict(tmp_path / "ds") for r in records] == check_dataset(tmp_path / "ds", 3)
    for r in map(json.loads, (tmp_path / "ds" / MANIFEST).read_text().splitlines()):
        assert {"image", "params", "seed", "split", "index", "scale", "spp", "pixel_size_mm",
                "setup", "photometric"} <= set(r)
        assert r["setup"] == "frontlit"
        assert r["image"] == f"images/{r['index']:06d}.png" and r["split"] == "train"
        assert r["pixel_size_mm"] == pytest.approx(0.1)
        YarnParams.from_dict(r["params"])
        Photometric.from_dict(r["photometric"])
    assert len({r.seed for r in records}) == 3


def test_a_view_is_a_window_of_the_same_yarns_at_the_scales_pitch(tmp_path):
    """``--view W H``: the same samples (yarns, seeds) as the full frame, rendered as a W x H
    px window at the scale's pitch centred on the frame: each window matches the full
    frame's central W x H px better than any crop shifted by up to 2 px (render noise
    aside); the settings record the view only when there is one, so datasets made before
    views resume."""
    full = GenerateOptions(count=2, seed=1, scale=0.1, spp=8)
    detail = GenerateOptions(count=2, seed=1, scale=0.1, spp=8, view=(48, 32))
    assert "view" not in full.settings() and detail.settings()["view"] == [48, 32]
    frames = generate_dataset(tmp_path / "f", full, workers=1)
    records = generate_dataset(tmp_path / "d", detail, workers=1)
    for r, f, line in zip(records, frames, check_dataset(tmp_path / "d", 2), strict=True):
        assert (line["width"], line["height"]) == (48, 32)
        assert r.pixel_size_mm == pytest.approx(0.1)
        assert r.params == sample_plan(full, r.index).params == f.params
        window = np.asarray(Image.open(r.image), dtype=float)
        frame = np.asarray(Image.open(f.image), dtype=float)  # 200 x 60 px
        top, left = (60 - 32) // 2, (200 - 48) // 2
        error = {(dy, dx): np.abs(frame[top + dy:top + dy + 32, left + dx:left + dx + 48]
                                  - window).mean()
                 for dy in range(-2, 3) for dx in range(-2, 3)}
        assert min(error, key=error.get) == (0, 0)
    with pytest.raises(UserError, match="32 to 4000 px"):
        GenerateOptions(count=1, view=(8, 32))


def test_kill_and_rerun_gives_exactly_n_samples_with_the_same_bytes(tmp_path):
    count, out = 8, tmp_path / "ds"
    args = ipm_args("generate", "--count", count, "--out", out, "--seed", 3, "--workers", 2,
                    *TINY)
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        manifest = out / MANIFEST
        if manifest.is_file() and len(manifest.read_text().splitlines()) >= 2:
            break
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)  # the whole run, workers included, mid-write
    proc.wait()
    assert len((out / MANIFEST).read_text().splitlines()) < count, "killed too late"
    # a torn last line, as a kill during the append leaves it
    with open(out / MANIFEST, "a") as f:
        f.write('{"index": 7, "image": "images/0000')
    r = subprocess.run(args, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    resumed = check_dataset(out, count)
    fresh = ipm("generate", "--count", count, "--out", tmp_path / "fresh", "--seed", 3,
                "--workers", 1, *TINY)
    assert fresh.returncode == 0, fresh.stderr
    assert resumed == check_dataset(tmp_path / "fresh", count)


def test_samples_are_the_same_bytes_across_processes(tmp_path):
    """Workers of one run and of another agree byte for byte.  While Mitsuba ordered the
    scene's shapes differently from process to process, about one process in eight rendered
    every image with other sample values (benchmarks/determinism.py; the cause is tested in
    tests/test_render.py)."""
    opts = ("--count", 4, "--seed", 3, "--scale", "0.1", "--spp", "5-7")
    assert ipm("generate", "--out", tmp_path / "a", "--workers", 2, *opts).returncode == 0
    assert ipm("generate", "--out", tmp_path / "b", "--workers", 1, *opts).returncode == 0
    for rec in check_dataset(tmp_path / "a", 4):
        assert rec["spp"] in (6, 8)  # the counts multijitter takes: 5 -> 6, 7 -> 8
        assert (tmp_path / "a" / rec["image"]).read_bytes() == \
            (tmp_path / "b" / rec["image"]).read_bytes()


def test_rerun_completes_and_grows(tmp_path):
    out = tmp_path / "ds"
    generate_dataset(out, GenerateOptions(count=2, scale=0.1, spp=2), workers=1)
    (out / "images" / "000001.png").unlink()  # an image lost: its line is dropped, re-rendered
    records = generate_dataset(out, GenerateOptions(count=4, scale=0.1, spp=2), workers=2)
    assert [r.index for r in records] == [0, 1, 2, 3] == [r["index"] for r in
                                                          check_dataset(out, 4)]


def test_bad_input_one_line_exit_2_nothing_lost(tmp_path):
    out = tmp_path / "ds"
    assert ipm("generate", "--count", 2, "--out", out, "--seed", 0, *TINY).returncode == 0
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    foreign = tmp_path / "photos"
    foreign.mkdir()
    (foreign / "mine.jpg").write_bytes(b"jpeg")
    a_file = tmp_path / "file"
    a_file.write_text("x")
    cases = [(("--count", 3, "--out", out, "--seed", 1, *TINY), "other settings (seed)"),
             (("--count", 3, "--out", foreign, *TINY), "not empty"),
             (("--count", 3, "--out", a_file / "ds", *TINY), "missing or not writable"),
             (("--count", 3, "--out", out, "--variant", "llvm_rgb", *TINY),
              "unknown Mitsuba variant"),
             (("--count", 3, "--out", out, "--split", "a/b", *TINY), "split"),
             (("--count", 3, "--out", out, *TINY, "--spp", "8-4"), "range 8-4 is empty")]
    for args, message in cases:
        r = ipm("generate", *args)
        assert r.returncode == 2, (args, r.stderr)
        assert r.stderr.count("\n") == 1 and message in r.stderr, r.stderr
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    assert (foreign / "mine.jpg").read_bytes() == b"jpeg"


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes to read-only folders")
def test_read_only_folder_is_refused(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    with pytest.raises(UserError, match="not writable"):
        generate_dataset(ro / "ds", GenerateOptions(count=1, scale=0.1, spp=1))


def test_read_manifest_missing_is_user_error(tmp_path):
    with pytest.raises(UserError, match="not a dataset"):
        read_manifest(tmp_path)


def test_photometric_off_is_nominal(tmp_path):
    r = ipm("generate", "--count", 1, "--out", tmp_path / "ds", "--no-photometric", *TINY)
    assert r.returncode == 0, r.stderr
    rec = read_manifest(tmp_path / "ds")[0]
    ph = Photometric.from_dict(rec.info["photometric"])
    assert ph.exposure_stops == 0 and ph.shift_mm == (0, 0) and ph.noise == (0, 0)
    assert np.allclose(ph.white_balance, 1)


def test_ray_gives_the_same_samples_as_the_local_pool(tmp_path):
    """Scale-out: the same generation on a local Ray instance started here."""
    ray = pytest.importorskip("ray")
    opts = GenerateOptions(count=4, seed=3, scale=0.1, spp=2)
    local = generate_dataset(tmp_path / "local", opts, workers=1)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        remote = generate_dataset(tmp_path / "ray", opts, ray="auto")
    finally:
        ray.shutdown()
    # the same samples (parameters, seeds, capture variation); for the bytes of the images
    # see test_samples_are_the_same_bytes_across_processes
    assert ([{**r.info, "variant": None} for r in local]
            == [{**r.info, "variant": None} for r in remote])
    assert [r.params for r in local] == [r.params for r in remote]
    check_dataset(tmp_path / "ray", 4)


def test_ray_without_a_cluster_is_a_clear_error(tmp_path, monkeypatch):
    pytest.importorskip("ray")
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    r = ipm("generate", "--out", tmp_path / "ds", "--count", 2, *TINY, "--ray", "auto")
    assert r.returncode == 2 and "error: cannot reach a Ray cluster at 'auto'" in r.stderr
    assert "Traceback" not in r.stderr


def test_a_smaller_count_keeps_what_was_made(tmp_path):
    out = tmp_path / "ds"
    assert ipm("generate", "--count", 3, "--out", out, "--workers", 1, *TINY).returncode == 0
    r = ipm("generate", "--count", 2, "--out", out, "--workers", 1, *TINY)
    assert r.returncode == 0, r.stderr
    assert "1 beyond --count 2" in r.stderr
    assert [rec.index for rec in read_manifest(out)] == [0, 1, 2]


def test_workers_of_a_killed_generate_end_with_it(tmp_path):
    """SIGKILL to the command alone (not its process group): its render workers must not
    render on as orphans."""
    proc = subprocess.Popen(ipm_args("generate", "--count", 200, "--out", tmp_path / "ds",
                                     "--workers", 2, *TINY),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        manifest = tmp_path / "ds" / MANIFEST
        if manifest.is_file() and manifest.read_text().strip():
            break
        time.sleep(0.05)
    children = subprocess.run(["ps", "--ppid", str(proc.pid), "-o", "pid="],
                              capture_output=True, text=True).stdout.split()
    assert len(children) >= 2, "no workers seen"
    proc.kill()
    proc.wait()
    time.sleep(10)
    alive = [pid for pid in children if os.path.exists(f"/proc/{pid}")
             and "zombie" not in open(f"/proc/{pid}/status").read().lower()]
    assert not alive, f"workers still running: {alive}"


def test_ctrl_c_is_one_line_and_exit_130(tmp_path):
    """SIGINT to the whole process group, as a terminal's Ctrl-C sends it."""
    proc = subprocess.Popen(ipm_args("generate", "--count", 200, "--out", tmp_path / "ds",
                                     "--workers", 2, *TINY),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    deadline = time.monotonic() + 60
    manifest = tmp_path / "ds" / MANIFEST
    while time.monotonic() < deadline and not (manifest.is_file() and manifest.read_text()):
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130
    assert "interrupted" in err and "Traceback" not in err
    for rec in read_manifest(tmp_path / "ds"):  # what was made is listed and whole
        with Image.open(rec.image) as img:
            img.load()


def test_a_dataset_folder_is_made_with_its_missing_parents(tmp_path):
    """`ipm generate --out new/dir/ds` makes the folders, as `mkdir -p`; a parent that is a
    file is still refused in one line."""
    from ipm.render.dataset import GenerateOptions, _prepare

    assert _prepare(tmp_path / "new" / "dir" / "ds", GenerateOptions(count=1)) == {}
    assert (tmp_path / "new" / "dir" / "ds").is_dir()
    (tmp_path / "file").write_text("x")
    with pytest.raises(UserError, match="missing or not writable"):
        _prepare(tmp_path / "file" / "ds", GenerateOptions(count=1))
