"""`ipm sample` / `ipm curves` as a user runs them, bad input included."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from ipm.fibers import FiberSet
from ipm.frame import YARN_LENGTH_MM
from ipm.presets import preset


def ipm(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "ipm", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd)


def test_sample_preset_and_curves(tmp_path):
    r = ipm("sample", "--preset", "golden", "-o", tmp_path / "p.json")
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "p.json").read_text())["n"] == 3
    r = ipm("curves", tmp_path / "p.json", "-o", tmp_path / "y.npz", "--seed", 1)
    assert r.returncode == 0, r.stderr
    g = preset("golden")  # g per 10 mm of ply, less the authors' dropped strips (0.88)
    flyaways = round(0.88 * g.g * YARN_LENGTH_MM * math.hypot(1, 2 * math.pi * g.R_ply
                                                              / g.alpha_ply) / 10)
    assert FiberSet.load_npz(tmp_path / "y.npz").num_fibers == 3 * 43 + flyaways
    r = ipm("curves", tmp_path / "p.json", "-o", tmp_path / "y.txt", "--format", "mitsuba")
    blocks = (tmp_path / "y.txt").read_text().count("\n\n") + 1  # blank lines between fibers
    assert r.returncode == 0 and blocks == 3 * 43 + flyaways


def test_sample_seeded(tmp_path):
    outs = [ipm("sample", "--seed", s).stdout for s in (3, 3, 4)]
    assert outs[0] == outs[1] != outs[2]
    assert json.loads(outs[0])["n"] in range(2, 7)


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.pop("alpha"), "missing parameter(s): alpha"),
    (lambda d: d.update(m="many"), "m: expected an integer, got 'many'"),
    (lambda d: d.update(R_ply=9.0), "R_ply = 9.0 is outside its allowed range [0.053, 1.486]"),
])
def test_bad_parameters_one_line_no_output(tmp_path, edit, message):
    d = preset("rose").to_dict()
    edit(d)
    (tmp_path / "p.json").write_text(json.dumps(d))
    r = ipm("curves", tmp_path / "p.json", "-o", tmp_path / "y.npz")
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and message in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "y.npz").exists()


@pytest.mark.parametrize("content", [b"\x89PNG\r\n\x1a\n\x00\x00", b"{not json", b""])
def test_unreadable_parameter_file(tmp_path, content):
    (tmp_path / "p.json").write_bytes(content)
    r = ipm("curves", tmp_path / "p.json", "-o", tmp_path / "y.npz")
    assert r.returncode == 2 and r.stderr.startswith("error: ") and r.stderr.count("\n") == 1
    assert not (tmp_path / "y.npz").exists()


def test_missing_file_and_folder(tmp_path):
    r = ipm("curves", tmp_path / "nope.json", "-o", tmp_path / "y.npz")
    assert r.returncode == 2 and "nope.json" in r.stderr
    r = ipm("sample", "-o", tmp_path / "no" / "p.json")
    assert r.returncode == 2 and "does not exist" in r.stderr
    r = ipm("sample", "--preset", "purple")
    assert r.returncode == 2 and "unknown preset 'purple'" in r.stderr


def test_existing_output_survives_a_failed_run(tmp_path):
    out = tmp_path / "y.npz"
    (tmp_path / "p.json").write_text(preset("golden").to_json())
    assert ipm("curves", tmp_path / "p.json", "-o", out).returncode == 0
    before = out.read_bytes()
    (tmp_path / "p.json").write_text("{}")
    assert ipm("curves", tmp_path / "p.json", "-o", out).returncode == 2
    assert out.read_bytes() == before
    assert np.load(out)["points"].dtype == np.float32
    assert not [p for p in tmp_path.iterdir() if ".tmp" in p.name]


def test_atomic_writes_leave_files_readable_like_open_does(tmp_path):
    """The temporary file of an atomic write is made 0600; the result gets the mode a plain
    open() would give (0666 less the umask)."""
    import os
    import stat

    from ipm.io import write_text

    mask = os.umask(0o022)
    try:
        write_text(tmp_path / "a.json", "{}")
        assert stat.S_IMODE((tmp_path / "a.json").stat().st_mode) == 0o644
    finally:
        os.umask(mask)


@pytest.mark.parametrize("value", ["0", "-1", "nan"])
def test_fit_rejects_a_bad_time_limit(tmp_path, value):
    r = ipm("fit", tmp_path / "p.png", "--refine", "--time", value, "--out", tmp_path / "f")
    assert r.returncode == 2 and r.stderr.startswith("error: time must be"), r.stderr
    assert r.stderr.count("\n") == 1 and not (tmp_path / "f").exists()


def test_an_output_that_is_an_input_is_refused(tmp_path):
    from PIL import Image

    params, photo = tmp_path / "p.json", tmp_path / "neural.png"
    params.write_text(preset("golden").to_json())
    Image.new("RGB", (64, 32)).save(photo)
    before = params.read_bytes(), photo.read_bytes()
    for args in (("curves", params, "-o", params),
                 ("render", params, "-o", tmp_path / "p.png"),  # its sidecar is p.json
                 ("predict", photo, "-o", photo),
                 ("fit", photo, "--out", tmp_path)):
        r = ipm(*args, cwd=tmp_path)
        assert r.returncode == 2 and "is an input of this command" in r.stderr, (args, r.stderr)
        assert r.stderr.count("\n") == 1
    assert (params.read_bytes(), photo.read_bytes()) == before


def test_an_output_file_that_is_a_folder_is_refused(tmp_path):
    from PIL import Image

    params, photo, folder = tmp_path / "p.json", tmp_path / "y.png", tmp_path / "d"
    params.write_text(preset("golden").to_json())
    Image.new("RGB", (64, 32)).save(photo)
    folder.mkdir()
    for args in (("sample", "-o", folder), ("curves", params, "-o", folder),
                 ("render", params, "-o", folder), ("predict", photo, "-o", folder)):
        r = ipm(*args)
        assert r.returncode == 2 and "is a folder" in r.stderr, (args, r.stderr)
        assert r.stderr.count("\n") == 1


def test_the_cli_and_its_refusals_stay_light(tmp_path):
    """Importing the CLI, and refusing a photo without a pixel size, load none of torch,
    scipy or mitsuba: help and one-line errors come at once."""
    from PIL import Image

    Image.new("RGB", (300, 100)).save(tmp_path / "p.png")
    code = ("import sys; from ipm.cli import main; sys.argv = ['ipm', *sys.argv[1:]]\n"
            "try:\n    main()\nexcept SystemExit:\n    pass\n"
            "print(sorted(m for m in ('torch', 'scipy', 'mitsuba') if m in sys.modules))")
    for args in ((), ("predict", str(tmp_path / "p.png")), ("measure", str(tmp_path / "p.png")),
                 ("compare", str(tmp_path), "--out", str(tmp_path / "c"))):
        r = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True)
        assert r.stdout.strip().splitlines()[-1] == "[]", (args, r.stdout, r.stderr)
