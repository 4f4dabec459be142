"""`ipm bench`'s report machinery on a tiny held-out set with the shipped models."""

import json
import shutil
import subprocess
import sys
from dataclasses import replace

import pytest

from ipm.benchmarks.report import FLYAWAY, RAW, BenchOptions, perturb, run
from ipm.errors import UserError

TINY = BenchOptions(count=3, refine_count=1, robust_count=2, repeats=1, throughput_count=2,
                    train_steps=1, budget=12)


@pytest.fixture(scope="module")
def heldout(tmp_path_factory):
    from ipm.render.dataset import GenerateOptions, generate_dataset

    folder = tmp_path_factory.mktemp("bench") / "heldout"
    generate_dataset(folder, GenerateOptions(count=TINY.count, seed=TINY.seed, split="test"),
                     workers=1)
    return folder


@pytest.fixture(scope="module")
def first(heldout, tmp_path_factory):
    out = tmp_path_factory.mktemp("bench") / "report"
    return out, run(out, TINY, data=heldout)


def test_report_files_and_a_row_per_parameter(first):
    out, results = first
    for name in ("index.md", "results.json", "pred_vs_true.png", "error_vs_value.png",
                 "robustness.png", "loss_traces.png", "best_worst.png"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    index = (out / "index.md").read_text()
    for k in RAW + FLYAWAY:
        assert f"| {k} |" in index or f"| **{k}** |" in index, k
    for k in RAW:
        assert sum(line.startswith(f"| {k} |") for line in index.splitlines()) == 1, k
    saved = json.loads((out / "results.json").read_text())
    assert set(saved["accuracy"]["ensemble"]["params"]) == set(RAW + FLYAWAY)
    assert saved["refine"]["count"] == 1 and len(saved["robustness"]) > 5
    assert saved["speed"]["render_s_scale_1_16spp"] > 0 and saved["speed"]["fit_s"] > 0
    for stat in ("hair_count", "loop_count", "hair_length_mean", "loop_reach_mean"):
        assert stat in saved["flyaway_distribution"]


def test_same_seeds_same_numbers(first, heldout, tmp_path):
    """A second run from scratch gives the same accuracy numbers.  The timings and the
    refinement rows are carried over: a refinement's renders are not always the same bytes
    in another Renderer (the renderer's open cross-process determinism problem), so its
    numbers are not part of this promise."""
    out, results = first
    (tmp_path / "cache").mkdir()
    for name in ("speed.json", "refine.jsonl"):
        shutil.copy(out / "cache" / name, tmp_path / "cache" / name)
    again = run(tmp_path, TINY, data=heldout)
    for key in ("accuracy", "baseline", "flyaway_distribution", "robustness", "refine"):
        assert again[key] == results[key], key


def test_resume_refuses_other_settings(first, heldout):
    out, _ = first
    with pytest.raises(UserError, match="other settings"):
        run(out, replace(TINY, budget=13), data=heldout)


def test_perturbations_change_the_image_and_keep_its_shape():
    import numpy as np

    from ipm.photo import Photo

    img = np.random.default_rng(0).random((20, 40, 3)).astype(np.float32)
    photo = Photo(img, 0.04)
    for kind, level in (("exposure", 1.0), ("noise", 0.03), ("blur", 1.5), ("rotation", 5.0)):
        out = perturb(photo, kind, level).image
        assert out.shape == img.shape and 0 <= out.min() and out.max() <= 1
        assert np.abs(out - img).mean() > 1e-3, kind
    assert perturb(photo, "exposure", 1.0).image.mean() > img.mean()


def test_cli_bad_output_folder_one_line(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    r = subprocess.run([sys.executable, "-m", "ipm", "bench", "--quick", "--out",
                        blocker / "report"], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.strip().startswith("error:"), r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and blocker.read_text() == "x"


def test_refinement_resumes_past_a_torn_line(first, heldout, tmp_path):
    """A kill while a refinement row was being written leaves a torn line: the rerun keeps
    the whole rows before it (no refit) and rewrites the cache without the torn one."""
    from ipm.benchmarks.report import load_records, refine_all

    out, _ = first
    row = (out / "cache" / "refine.jsonl").read_text().splitlines()[0]
    (tmp_path / "cache").mkdir()
    (tmp_path / "cache" / "refine.jsonl").write_text(row + "\n" + row[: len(row) // 2])
    records = load_records(heldout, 1)
    rows = refine_all(tmp_path, records, [None], {}, TINY.budget)  # [None]: a refit fails
    assert rows == [json.loads(row)]
    assert (tmp_path / "cache" / "refine.jsonl").read_text() == row + "\n"


def test_no_refinement_is_a_valid_report(heldout, tmp_path):
    from ipm.benchmarks.report import refine_summary

    assert refine_summary([], [])["params"] == {}
    with pytest.raises(UserError, match="holds none of"):
        run(tmp_path / "r", TINY, data=heldout, variants=tmp_path)
    assert not (tmp_path / "r" / "cache" / "settings.json").exists()


def test_records_are_sorted_and_carry_their_fiber_seed(heldout):
    from ipm.benchmarks.report import load_records

    records = load_records(heldout, TINY.count)
    assert [r.image.name for r in records] == sorted(r.image.name for r in records)
    assert all(isinstance(r.seed, int) for r in records)


def test_cycles_verdict_interpolates_between_the_grid_points_around_the_target():
    from ipm.benchmarks.blender_compare import interpolated_time

    # noise falling as 1/time: the target halfway (in log) between two points
    assert interpolated_time([1, 2, 4], [0.04, 0.02, 0.01], 0.01 * 2 ** 0.5, rising=False) \
        == pytest.approx(2 * 2 ** 0.5)
    assert interpolated_time([1, 4], [1.0, 4.0], 2.0, rising=True) == pytest.approx(2.0)
    assert interpolated_time([1, 2], [0.04, 0.02], 0.05, rising=False) is None  # off the grid


def test_cycles_verdict_matches_each_yarn_to_its_own_cycles_noise():
    from ipm.benchmarks.blender_compare import CYCLES, IPM, IPM_SPP, NOISE, Rows, report, verdict

    # ipm: noise c / sqrt(spp) in a * spp seconds; Cycles: a clean fast yarn, a noisy slow one
    rows = Rows()
    rows["cycles"] = [([20.0, 20.0], 1.0, 0.01), ([40.0, 40.0], 1.0, 0.02)]
    for spp in IPM_SPP:
        rows[f"{IPM} {spp}"] = [([0.05 * spp] * 2, 1.0, 0.04 / spp ** 0.5),
                                ([0.1 * spp] * 2, 1.0, 0.1 / spp ** 0.5)]
    spp, t, t_i = verdict(rows, "cycles", NOISE, yarn=0)
    assert (spp, t, t_i) == (16, pytest.approx(0.8), pytest.approx(0.8))  # 25x
    spp, t, t_i = verdict(rows, "cycles", NOISE, yarn=1)
    assert (spp, t, t_i) == (25, pytest.approx(2.5), pytest.approx(2.5))  # 16x
    # pooled: mean noise 0.07 / sqrt(spp) against Cycles' mean 0.015 -> between 20 and 25 spp
    spp, t, t_i = verdict(rows, "cycles", NOISE)
    assert spp == 25 and rows.seconds("cycles") == 30.0
    assert rows.seconds(f"{IPM} 20") < t_i < rows.seconds(f"{IPM} 25")
    # the report states both yarns' speed-ups and their median
    for label in CYCLES:
        rows[label] = rows["cycles"]
    del rows["cycles"]
    text = report(rows, fibers=[100, 500], threads=2)
    assert "median **20.5x** over 2 of 2 yarns (16.0-25.0x)" in text
    assert "0 (100 fibers): 25.0x, 1 (500 fibers): 16.0x" in text
    # every SNR is 1: ipm matches it at the grid's 4 spp already, a lower bound on the speed-up
    assert "equal detail SNR: median at least **100.0x** over 2 of 2 yarns" in text
    assert "0 (100 fibers): ≥100.0x, 1 (500 fibers): ≥100.0x" in text


def test_make_nets_time_recipe_is_the_scripts():
    """The training-time benchmark projects scripts/make_nets.sh's image counts and epochs:
    its numbers must be the script's."""
    import re
    from pathlib import Path

    from ipm.benchmarks.make_nets_time import RECIPE, RECIPE_DATA, TRAIN_IMAGES

    script = (Path(__file__).parents[1] / "scripts" / "make_nets.sh").read_text()
    counts = [int(c) for c in re.findall(r"ipm generate .*?--count (\d+)", script)]
    frontlit = sum(d.images.get("frontlit", 0) for d in RECIPE_DATA.values())
    backlit = sum(d.images.get("backlit", 0) for d in RECIPE_DATA.values())
    fine = counts[-3:]  # the fine yarns' windows, backlit only, last in the script
    assert frontlit == sum(counts[:-3]) and backlit == sum(counts[:3]) + sum(fine)
    assert TRAIN_IMAGES == {"frame": counts[0], "detail window": counts[3],
                            "frontlit frame, varied look": counts[6],
                            "detail window, varied look": counts[9],
                            "backlit frame, varied look": counts[0],
                            "fine window, varied look": fine[0]}
    fine_block = script[script.index('if [ "$FINE" = 1 ]'):]
    fine_options = re.search(r"fine=\(([^)]*)\)", fine_block).group(1).split()
    assert set(fine_options) - {'"${look[@]}"'} <= set(RECIPE_DATA["fine window, varied "
                                                                  "look"].options)
    varied = re.search(r'varied=\(--setup "\$SETUP" ([^)]*)\)', script).group(1).split()
    for kind in ("backlit frame, varied look", "backlit test frame, varied look",
                 "frontlit frame, varied look", "frontlit test frame, varied look",
                 "detail window, varied look"):
        assert set(varied) <= set(RECIPE_DATA[kind].options), kind
    def trained_in(text):
        return {(tuple(n.split(",")), int(e)) for n, e in
                re.findall(r"--nets (\S+) --epochs (\d+)", text)}

    assert {(t.nets, t.epochs) for t in RECIPE["frontlit"]} == trained_in(
        script[:script.index('if [ "$FINE" = 1 ]')])
    assert {(t.nets, t.epochs) for t in RECIPE["backlit"] if t.phase == 2} == trained_in(
        fine_block)
    assert {(t.nets, t.epochs) for t in RECIPE["backlit"] if t.phase == 1} == {
        (t.nets, t.epochs) for t in RECIPE["frontlit"] if t.data == "frame"} - {
        (("alpha_ply",), 24)}
    assert [t.preset for t in RECIPE["backlit"] if t.nets == ("raw",)] == ["reg", "reg"]
    assert [t.preset for t in RECIPE["frontlit"] if t.nets == ("raw",)] == ["reg", "reg"]
    assert "--preset reg --nets raw --epochs 12" in script
    assert "--preset reg --nets raw --epochs 6" in script


def test_interval_coverage_counts_the_truths_inside(tmp_path):
    """Intervals re-derived from a report's rows: a fit whose every value is the truth holds
    it, one far off does not; two reports counted together weigh their photos."""
    import json

    from ipm.benchmarks.interval_coverage import coverage, pooled
    from ipm.dataset import read_manifest
    from ipm.nets.sketchdata import write_sketch_dataset
    from ipm.params import RAW_CONTINUOUS

    data = write_sketch_dataset(tmp_path / "data", 4, seed=3, scale=0.05)
    records = read_manifest(data)
    sigma = {k: 1e-3 for k in RAW_CONTINUOUS}
    rows = []
    for i, r in enumerate(records):
        far = {k: getattr(r.params, k) * 0.5 for k in RAW_CONTINUOUS}  # m halved: a whole m
        fit = r.params.to_dict() if i < 3 else r.params.replace(
            **{**far, "m": r.params.m // 2}).to_dict()
        rows.append({"image": str(r.image), "neural": fit, "refined": fit, "improved": False,
                     "intervals": {}})
    report = tmp_path / "report"
    report.mkdir()
    (report / "fits.jsonl").write_text("\n".join(json.dumps(row) for row in rows) + "\n")
    covered = coverage(report, data, sigma)
    assert {k: c["holds"] for k, c in covered.items()} == {k: 0.75 for k in RAW_CONTINUOUS}
    assert all(c["photos"] == 4 for c in covered.values())
    other = {k: {**c, "holds": 0.25, "photos": 12} for k, c in covered.items()}
    assert pooled([covered, other]) == {k: (16, 0.375) for k in RAW_CONTINUOUS}


def test_pitch_profile_map_pitch_weighs_loss_by_its_seed_noise_against_the_prior():
    """A swept row built by hand: the period group lowest at 6 mm, the contour at 3 mm, the
    nets at 3 mm with sigma 0.5 and a seed noise of 0.1 at their guess.  Loss alone: each
    group's own minimum; with the prior, 10 (v - 6)^2 + 2 (v - 3)^2 is lowest at 5.5."""
    import numpy as np

    from ipm.benchmarks.pitch_profile import map_pitch

    values = np.linspace(2, 8, 25)
    row = {"values": values.tolist(), "neural": 3.0, "sigma": 0.5, "prior_weight": 1.0,
           "curves": {"period": ((values - 6) ** 2).tolist(),
                      "contour": ((values - 3) ** 2).tolist()},
           "start": {"period": [1.0, 1.1, 0.9], "contour": [0.0, 0.0, 0.0]}}
    assert map_pitch(row, {"period": 1.0}, prior=False) == 6.0
    assert map_pitch(row, {"contour": 1.0}, prior=False) == 3.0
    assert map_pitch(row, {"period": 1.0}) == 5.5
    assert map_pitch(row, {"period": 1.0, "contour": 0.0}) == 5.5
