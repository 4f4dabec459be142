"""Every kind of bad input we know of, run as a user would, and what ipm answers: the table
in docs/robustness.md (command, exit status, the first line of its message, peak memory).
Made anew by this script, so the table stays true to the code.

    python -m ipm.benchmarks.bad_inputs --out docs/robustness.md
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish

COMMAND = "python -m ipm.benchmarks.bad_inputs --out docs/robustness.md"
ROOT = Path(__file__).resolve().parent.parent
#: Runs a command (``sys.argv[2:]``), sends it SIGTERM after ``sys.argv[1]`` seconds unless
#: that is 0, and prints its peak resident memory (KiB) last on stderr.
MEASURED = ("import resource, signal, subprocess, sys, time; t = float(sys.argv[1]); "
            "p = subprocess.Popen(sys.argv[2:]); time.sleep(t) if t else None; "
            "p.send_signal(signal.SIGTERM) if t and p.poll() is None else None; rc = p.wait(); "
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); "
            "sys.exit(rc)")
#: Seconds after which the SIGTERM case is sent its signal (the nets are loading then).
TERM_AFTER = 6.0


def inputs(d: Path) -> dict[str, Path]:
    """Bad (and good) files to feed the commands, made in ``d``."""
    from PIL import Image

    from ipm.presets import preset

    golden = json.loads((ROOT / "examples" / "golden.json").read_text())["params"]
    files = {"golden": d / "golden.json", "photo": d / "photo.png"}
    files["golden"].write_text(json.dumps(golden))
    shutil.copy(ROOT / "examples" / "golden.png", files["photo"])
    shutil.copy(ROOT / "examples" / "golden.json", d / "photo.json")  # its pixel size
    (d / "text.png").write_text("not an image")
    (d / "empty.png").write_bytes(b"")
    (d / "truncated.png").write_bytes((ROOT / "examples" / "golden.png").read_bytes()[:5000])
    Image.new("RGB", (1000, 300), (128, 128, 128)).save(d / "grey.png")
    Image.new("RGBA", (1000, 300), (0, 0, 0, 0)).save(d / "clear.png")
    Image.open(ROOT / "examples" / "golden.png").rotate(90, expand=True).save(d / "vertical.png")
    (d / "range.json").write_text(json.dumps({**golden, "alpha_ply": 99.0}))
    (d / "typo.json").write_text(json.dumps({**golden, "twsit": 3}))
    (d / "broken.json").write_text("{not json")
    (d / "folder").mkdir()
    (d / "models").mkdir()
    (d / "models" / "ensemble.json").write_text("{not json")
    # issue 49: files a command must not write over, odd files in folders, wrong setups
    shutil.copy(ROOT / "examples" / "golden.json", d / "sidecar.json")
    (d / "photos").mkdir()
    shutil.copy(ROOT / "examples" / "golden.png", d / "photos" / "a.png")
    (d / "photos" / "a.json").write_text('{"note": "the user\'s own"}')
    (d / "x").mkdir()
    shutil.copy(ROOT / "examples" / "golden.png", d / "x" / "params.png")
    shutil.copy(ROOT / "examples" / "golden.json", d / "x" / "params.json")
    (d / "mixed").mkdir()
    shutil.copy(ROOT / "examples" / "golden.png", d / "mixed" / "a.png")
    (d / "mixed" / "b.png").write_text("not an image")
    os.mkfifo(d / "mixed" / "c.png")
    (d / "mixed" / "d.png").symlink_to(d / "mixed" / "d.png")
    shutil.copy(ROOT / "examples" / "golden.png", d / "mixed" / "e.png")
    (d / "bad").mkdir()
    (d / "bad" / "a.png").write_text("not an image")
    (d / "bad" / "b.png").symlink_to(d / "gone.png")
    os.mkfifo(d / "fifo.png")
    (d / "twins" / "x").mkdir(parents=True)
    shutil.copy(ROOT / "examples" / "golden.png", d / "twins" / "a.png")
    shutil.copy(ROOT / "examples" / "golden.png", d / "twins" / "x" / "a.png")
    Image.new("RGB", (8, 8)).save(d / "tiny.png")
    gray = np.asarray(Image.open(ROOT / "examples" / "golden.png").convert("L"))
    Image.fromarray(255 - gray).save(d / "backlit.png")  # a dark yarn on a light panel
    thick = preset("pink_6ply").to_dict()  # 200 fibers a ply and its radii doubled
    thick.update(m=200, R_ply=2 * thick["R_ply"], r_x=2 * thick["r_x"], r_y=2 * thick["r_y"])
    (d / "thick.json").write_text(json.dumps(thick))
    (d / "fit").mkdir()
    (d / "fit" / "params.json").write_text(json.dumps({"refined": golden,
                                                       "settings": {"setup": "backlit"}}))
    cal = {"format": "ipm.calibration/1", "pixel_size_mm": True, "tick_period_px": 80.0,
           "angle_deg": 0.0, "tick_mm": 1.0, "source": "ruler.png"}
    (d / "true_cal.json").write_text(json.dumps(cal))
    for name, size in (("true_side", True), ("absurd_side", 1000.0)):
        shutil.copy(ROOT / "examples" / "golden.png", d / f"{name}.png")
        (d / f"{name}.json").write_text(json.dumps({"pixel_size_mm": size}))
    return {k: Path(v) for k, v in files.items()}


def cases(d: Path) -> list[tuple]:
    """(what is wrong, the ipm arguments[, seconds after which it is sent SIGTERM]), in the
    order of the table."""
    photo, golden = str(d / "photo.png"), str(d / "golden.json")
    return [
        ("photo is not an image", ["predict", str(d / "text.png"), "--pixel-size", "0.02"]),
        ("photo is empty", ["predict", str(d / "empty.png"), "--pixel-size", "0.02"]),
        ("photo is truncated", ["predict", str(d / "truncated.png"), "--pixel-size", "0.02"]),
        ("photo is missing", ["predict", str(d / "missing.png"), "--pixel-size", "0.02"]),
        ("photo is uniform grey", ["predict", str(d / "grey.png"), "--pixel-size", "0.02"]),
        ("photo is fully transparent", ["predict", str(d / "clear.png"), "--pixel-size", "0.02"]),
        ("yarn runs vertically (turned, said)", ["predict", str(d / "vertical.png"),
                                                 "--pixel-size", "0.02"]),
        ("pixel size in micrometres (8.5)", ["predict", photo, "--pixel-size", "8.5"]),
        ("pixel size 1000", ["fit", photo, "--pixel-size", "1000", "--out", str(d / "f1")]),
        ("pixel size NaN", ["predict", photo, "--pixel-size", "nan"]),
        ("no pixel size and no sidecar", ["fit", str(d / "vertical.png"), "--out",
                                          str(d / "f2")]),
        ("calibration file is not one", ["fit", photo, "--calibration", str(d / "broken.json"),
                                         "--out", str(d / "f3")]),
        ("calibrate an image without a scale", ["calibrate", photo]),
        ("corrupt models", ["fit", photo, "--models", str(d / "models"), "--out",
                            str(d / "f4")]),
        ("fit --time 0", ["fit", photo, "--time", "0", "--out", str(d / "f5")]),
        ("fit --time nan", ["fit", photo, "--time", "nan", "--out", str(d / "f6")]),
        ("parameter out of range", ["curves", str(d / "range.json"), "-o", str(d / "y.npz")]),
        ("parameter file is not JSON", ["curves", str(d / "broken.json"), "-o",
                                        str(d / "y.npz")]),
        ("unknown parameter key (warned)", ["curves", str(d / "typo.json"), "-o",
                                            str(d / "y2.npz")]),
        ("output is the input (render)", ["render", golden, "-o", str(d / "golden.png")]),
        ("output is the input (curves)", ["curves", golden, "-o", golden]),
        ("output is a folder", ["curves", golden, "-o", str(d / "folder")]),
        ("render to .jpg", ["render", golden, "-o", str(d / "x.jpg")]),
        ("edit: unknown parameter", ["edit", golden, "--set", "twist=2"]),
        ("edit: factor leaves the interval", ["edit", golden, "--set", "alpha_ply=*100"]),
        ("knit: unknown pattern", ["knit", golden, "--pattern", "moss", "-o",
                                   str(d / "k.png")]),
        ("knit: bad stitches", ["knit", golden, "--stitches", "8by6", "-o", str(d / "k.png")]),
        ("generate: bad spp range", ["generate", "--out", str(d / "ds"), "--spp", "9-3"]),
        # issue 49
        ("edit over the sidecar it reads", ["edit", str(d / "sidecar.json"), "--set", "g=*2",
                                            "-o", str(d / "sidecar.json")]),
        ("predict into the photos' folder over the user's a.json",
         ["predict", str(d / "photos"), "--pixel-size", "0.04", "-o", str(d / "photos")]),
        ("fit over the photo's sidecar", ["fit", str(d / "x" / "params.png"), "--out",
                                          str(d / "x")]),
        ("curves: --format usd into .txt", ["curves", golden, "--format", "usd", "-o",
                                            str(d / "y.txt")]),
        ("curves: --format ply into .usda", ["curves", golden, "--format", "ply", "-o",
                                             str(d / "p.usda")]),
        ("curves: no suffix, no --format", ["curves", golden, "-o", str(d / "y")]),
        ("curves: .usda without --format (writes USD text)", ["curves", golden, "-o",
                                                              str(d / "y2.usda")]),
        ("knit patch too large for memory", ["curves", str(d / "thick.json"), "--knit",
                                             "knit", "--stitches", "40x40", "-o",
                                             str(d / "t.npz")]),
        ("render of 2^32 samples or more", ["render", golden, "--scale", "0.1", "--spp",
                                            "400000", "-o", str(d / "r.png")]),
        ("knit render of 2^32 samples or more", ["knit", golden, "--size", "1000x1000",
                                                 "--spp", "5000", "-o", str(d / "k2.png")]),
        ("render --spp 1e8", ["render", golden, "--spp", "100000000", "-o",
                              str(d / "r2.png")]),
        ("calibrate a FIFO", ["calibrate", str(d / "fifo.png")]),
        ("predict a FIFO without --pixel-size", ["predict", str(d / "fifo.png")]),
        ("folder with a bad file, a FIFO and a link loop (predict)",
         ["predict", str(d / "mixed"), "--pixel-size", "0.04", "-o", str(d / "pred")]),
        ("folder with a bad file and a dangling link (compare)",
         ["compare", str(d / "bad"), "--pixel-size", "0.04", "--out", str(d / "cmp")]),
        ("backlit photo without --setup (auto, said)", ["predict", str(d / "backlit.png"),
                                                        "--pixel-size", "0.04"]),
        ("render a backlit fit's params.json", ["render", str(d / "fit" / "params.json"),
                                                "--scale", "0.05", "--spp", "1", "-o",
                                                str(d / "fit.png")]),
        ("edit: n=2.5", ["edit", golden, "--set", "n=2.5"]),
        ("edit: n=*1.5", ["edit", golden, "--set", "n=*1.5"]),
        ("edit: color", ["edit", golden, "--set", "color=0.5,0.4,0.3", "-o",
                         str(d / "c.json")]),
        ("SIGTERM while fitting", ["fit", photo, "--out", str(d / "f7")], TERM_AFTER),
        ("--version", ["--version"]),
        ("calibration pixel_size_mm true", ["fit", photo, "--calibration",
                                            str(d / "true_cal.json"), "--out", str(d / "f8")]),
        ("sidecar pixel_size_mm true", ["predict", str(d / "true_side.png")]),
        ("sidecar pixel_size_mm 1000", ["predict", str(d / "absurd_side.png")]),
        ("two photos share a name", ["predict", str(d / "twins" / "a.png"),
                                     str(d / "twins" / "x" / "a.png"), "--pixel-size", "0.04",
                                     "-o", str(d / "twins_out")]),
        ("calibrate an 8x8 image", ["calibrate", str(d / "tiny.png")]),
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    rows = ["| bad input | command | exit | message (first line) | peak memory |",
            "|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        inputs(d)
        for what, argv, *term in cases(d):
            t0 = time.perf_counter()
            r = subprocess.run([sys.executable, "-c", MEASURED, str(term[0] if term else 0),
                                sys.executable, "-m", "ipm", *argv], capture_output=True,
                               text=True, timeout=600)
            lines = [ln for ln in r.stderr.strip().splitlines() if ln.strip()]
            peak_mb = int(lines.pop()) / 1024 if lines and lines[-1].isdigit() else float("nan")
            said = [next((ln for ln in lines if ln.startswith(kind)), None)
                    for kind in ("error", "warning", "note")]  # the most serious first
            message = next((ln for ln in said if ln), lines[0] if lines else "")
            if term:
                left = (d / "f7").exists()
                message += f" (output folder {'left behind' if left else 'not left behind'})"
            rows.append(f"| {what} | `ipm {' '.join(a.replace(tmp, '…') for a in argv)}` | "
                        f"{r.returncode} | {message.replace(tmp, '…').replace('|', '/')} | "
                        f"{peak_mb:.0f} MB, {time.perf_counter() - t0:.1f} s |")
    text = (markdown_header("Bad input: what ipm answers", COMMAND) + "\nEach row is a fresh "
            "process; peak memory is the command's resident set.  Exit 2 is a refused input, "
            "0 a run that went on with a warning or note, 1 a folder run that did every good "
            "photo and listed the bad ones (each its own error line; the first is shown), "
            "143 a run stopped by SIGTERM.\n\n" + "\n".join(rows) + "\n")
    publish(text, args.out)


if __name__ == "__main__":
    main()
