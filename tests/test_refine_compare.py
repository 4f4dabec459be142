"""`ipm compare`: neural-only vs refined over a labelled dataset and a plain photo folder."""

import csv
import json
import shutil
import subprocess
import sys

import pytest

from ipm.errors import UserError
from ipm.params import RAW_CONTINUOUS
from ipm.refine.compare import FITS, PhotoPrep, compare, photos_in
from ipm.refine.plan import FitConfig

OPTIONS = FitConfig(budget=12)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    from ipm.render.dataset import GenerateOptions, generate_dataset

    folder = tmp_path_factory.mktemp("compare") / "data"
    generate_dataset(folder, GenerateOptions(count=2, seed=77, split="test"), workers=1)
    return folder


@pytest.fixture(scope="module")
def ensemble():
    from ipm.nets.ensemble import Ensemble

    return Ensemble.load(None)


def test_labelled_dataset_report(dataset, ensemble, tmp_path):
    s = compare(photos_in(dataset, 0.01), tmp_path, ensemble, OPTIONS, figure_count=1)
    assert s["count"] == 2 and set(s["params"]) == set(RAW_CONTINUOUS)
    header = (tmp_path / "results.csv").read_text().splitlines()[0].split(",")
    assert len(set(header)) == len(header), header  # each parameter's columns once
    rows = list(csv.DictReader((tmp_path / "results.csv").open()))
    assert len(rows) == 2 and all(r["true_alpha_ply"] for r in rows)
    for r in rows:
        assert float(r["loss_refined"]) <= float(r["loss_neural"])
    index = (tmp_path / "index.md").read_text()
    assert all(f"| {k} |" in index for k in RAW_CONTINUOUS) and "compare.png" in index
    assert (tmp_path / "compare.png").stat().st_size > 0

    # a rerun resumes: the fits file is kept as it is, nothing is fitted again
    before = (tmp_path / FITS).read_text()
    again = compare(photos_in(dataset, 0.01), tmp_path, ensemble, OPTIONS, figure_count=0)
    assert (tmp_path / FITS).read_text() == before and again == s


def test_plain_folder_has_no_labels(dataset, ensemble, tmp_path):
    photos = tmp_path / "photos"
    photos.mkdir()
    first = sorted((dataset / "images").iterdir())[0]
    shutil.copy(first, photos / "yarn.png")
    (photos / "notes.txt").write_text("not a photo")
    listed = photos_in(photos, 0.04)
    assert [p.image.name for p in listed] == ["yarn.png"] and listed[0].params is None
    s = compare(listed, tmp_path / "out", ensemble, OPTIONS, figure_count=0)
    assert s["count"] == 1 and s["params"] == {}
    head = (tmp_path / "out" / "results.csv").read_text().splitlines()[0]
    assert "true_" not in head and "refined_alpha" in head


def test_photos_of_one_setup_at_a_time(dataset, tmp_path):
    """A folder's photos take --setup; a dataset's carry their own, and a mix, or a --setup
    that contradicts them, is one line."""
    photos = tmp_path / "photos"
    photos.mkdir()
    shutil.copy(sorted((dataset / "images").iterdir())[0], photos / "yarn.png")
    assert photos_in(photos, 0.04, setup="backlit")[0].setup == "backlit"
    assert {p.setup for p in photos_in(dataset, 0.01)} == {"frontlit"}
    with pytest.raises(UserError, match="frontlit setups .--setup backlit.; compare one"):
        photos_in(dataset, 0.01, setup="backlit")
    mixed = tmp_path / "mixed"
    shutil.copytree(dataset, mixed)
    lines = (mixed / "manifest.jsonl").read_text().splitlines()
    lines[0] = json.dumps({**json.loads(lines[0]), "setup": "backlit"})
    (mixed / "manifest.jsonl").write_text("\n".join(lines) + "\n")
    with pytest.raises(UserError, match="backlit and frontlit setups; compare one"):
        photos_in(mixed, 0.01)


def test_folder_without_photos(tmp_path):
    with pytest.raises(UserError, match="holds no photos"):
        photos_in(tmp_path, 0.01)
    with pytest.raises(UserError, match="not a folder"):
        photos_in(tmp_path / "missing", 0.01)


def test_cli_refuses_other_settings_in_one_line(dataset, tmp_path):
    out = tmp_path / "report"
    out.mkdir()
    (out / "settings.json").write_text(json.dumps({"photos": "elsewhere"}))
    r = subprocess.run([sys.executable, "-m", "ipm", "compare", str(dataset), "--out",
                        str(out), "--budget", "12"], capture_output=True, text=True)
    assert r.returncode == 2 and "other settings" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert json.loads((out / "settings.json").read_text()) == {"photos": "elsewhere"}


def test_photo_prep_blurs_in_mm_and_inverts(dataset):
    """--blur-mm blurs by sigma in mm at the yarn (so in pixels by each photo's pixel size),
    keeping the mean light; --invert flips the values."""
    import numpy as np

    from ipm.benchmarks.render_speed import highpass
    from ipm.photo import srgb_to_linear

    photo = photos_in(dataset, 0.01)[0]
    sharp, blurred = (PhotoPrep().load(photo).image,
                      PhotoPrep(blur_mm=2 * photo.pixel_size_mm).load(photo).image)
    assert np.std(highpass(blurred)) < 0.5 * np.std(highpass(sharp))
    light = [srgb_to_linear(x).mean() for x in (sharp, blurred)]
    assert light[1] == pytest.approx(light[0], rel=0.01)  # blurred in linear light
    assert np.allclose(PhotoPrep(invert=True).load(photo).image, 1 - sharp)
    with pytest.raises(UserError, match="blur must be in"):
        PhotoPrep(blur_mm=2.0)


def test_summary_counts_how_often_the_intervals_hold_the_truth():
    from ipm.presets import preset
    from ipm.refine.compare import summary

    truth = [preset("golden"), preset("rose")]
    rows = [{"neural": t.to_dict(), "refined": t.to_dict(), "improved": False, "seconds": 1.0,
             "intervals": {"alpha_ply": [t.alpha_ply + d, t.alpha_ply + d + 1.0, "search"]}}
            for t, d in zip(truth, (-0.5, 0.5), strict=True)]
    s = summary(rows, truth)["params"]
    assert s["alpha_ply"]["interval_holds"] == 0.5 and s["alpha_ply"]["interval_width"] == 1.0
    assert "interval_holds" not in s["alpha"]


def test_the_report_shows_the_flyaway_parameters_a_search_moved():
    from ipm.params import RAW_CONTINUOUS
    from ipm.presets import preset
    from ipm.refine.compare import reported, summary

    staged = FitConfig(params="R_ply;g,l_hair")
    assert reported(staged, "frontlit") == (*RAW_CONTINUOUS, "g", "l_hair")
    assert reported(FitConfig(), "backlit") == RAW_CONTINUOUS
    t = preset("golden")
    rows = [{"neural": t.replace(g=t.g + 40).to_dict(), "refined": t.replace(g=t.g + 10).to_dict(),
             "improved": True, "seconds": 1.0}]
    s = summary(rows, [t], reported(staged, "frontlit"))["params"]
    assert s["g"]["neural"] == 40 and s["g"]["refined"] == 10 and s["g"]["change_pct"] == -75


def test_the_summary_counts_the_right_ply_counts_of_both_reconstructions():
    """Three photos by hand: the nets wrong, the fit right; both wrong alike; the nets
    right, the fit wrong."""
    from ipm.presets import preset
    from ipm.refine.compare import markdown, summary

    truth = [preset("golden"), preset("rose"), preset("red")]
    wrong = [t.replace(n=t.n + 1) for t in truth]
    pairs = [(wrong[0], truth[0]), (wrong[1], wrong[1]), (truth[2], wrong[2])]
    rows = [{"image": f"{i}.png", "neural": a.to_dict(), "refined": b.to_dict(),
             "improved": True, "seconds": 1.0, "loss_neural": 1.0, "loss_refined": 0.5}
            for i, (a, b) in enumerate(pairs)]
    s = summary(rows, truth)
    assert s["n_right"] == pytest.approx({"neural": 1 / 3, "refined": 1 / 3})
    assert s["n_changed"] == {"to_right": 1, "to_wrong": 1, "wrong_to_wrong": 0}
    assert ("Ply count n right: neural 33%, refined 33%; the fit changed the nets' count on "
            "2: wrong to right on 1, right to wrong on 1, wrong to another wrong on 0."
            ) in markdown(s, rows, "c", None)


def test_the_searched_parameter_is_split_by_whether_the_nets_ply_count_is_right():
    """Three photos by hand: the nets' ply count right on two (alpha_ply off by 1 and 3,
    refined to 0 and 1 off), wrong on one (off by 2, refined 4 off); the parameters the
    search left alone are not split."""
    from ipm.presets import preset
    from ipm.refine.compare import markdown, summary

    truth = [preset("golden"), preset("rose"), preset("red")]
    offs = [(1.0, 0.0), (3.0, 1.0), (2.0, 4.0)]
    rows = []
    for i, (t, (a, b)) in enumerate(zip(truth, offs, strict=True)):
        n = t.n if i < 2 else t.n + 1
        rows.append({"image": f"{i}.png", "improved": True, "seconds": 1.0,
                     "loss_neural": 1.0, "loss_refined": 0.5,
                     "neural": t.replace(n=n, alpha_ply=t.alpha_ply + a).to_dict(),
                     "refined": t.replace(n=n, alpha_ply=t.alpha_ply - b).to_dict()})
    s = summary(rows, truth)
    split = s["params"]["alpha_ply"]["by_ply_count"]
    assert split["right"] == pytest.approx({"photos": 2, "neural": 2.0, "refined": 0.5})
    assert split["wrong"] == pytest.approx({"photos": 1, "neural": 2.0, "refined": 4.0})
    assert "by_ply_count" not in s["params"]["R_ply"]
    assert ("`alpha_ply` (MAE, neural -> refined) on the photos whose ply count the nets read "
            "right (2 photos): 2 -> 0.5; wrong (1 photo): 2 -> 4.") in markdown(s, rows, "c",
                                                                                None)
