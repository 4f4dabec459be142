"""Every kind of bad input we know of, run as a user would, and what ipm answers: the table
in docs/robustness.md (command, exit status, the first line of its message, peak memory).
Made anew by this script, so the table stays true to the code.

    python -m ipm.benchmarks.bad_inputs --out docs/robustness.md
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ipm.benchmarks.machine import markdown_header, publish

COMMAND = "python -m ipm.benchmarks.bad_inputs --out docs/robustness.md"
ROOT = Path(__file__).resolve().parent.parent
#: Runs a command and prints its children's peak resident memory (KiB) last on stderr.
MEASURED = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:]); "
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); "
            "sys.exit(r.returncode)")


def inputs(d: Path) -> dict[str, Path]:
    """Bad (and good) files to feed the commands, made in ``d``."""
    from PIL import Image

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
    return {k: Path(v) for k, v in files.items()}


def cases(d: Path) -> list[tuple[str, list[str]]]:
    """(what is wrong, the ipm arguments), in the order of the table."""
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
        for what, argv in cases(d):
            t0 = time.perf_counter()
            r = subprocess.run([sys.executable, "-c", MEASURED, sys.executable, "-m", "ipm",
                                *argv], capture_output=True, text=True, timeout=600)
            lines = [ln for ln in r.stderr.strip().splitlines() if ln.strip()]
            peak_mb = int(lines.pop()) / 1024 if lines and lines[-1].isdigit() else float("nan")
            message = next((ln for ln in lines if ln.startswith(("error", "warning", "note"))),
                           lines[0] if lines else "")
            rows.append(f"| {what} | `ipm {' '.join(a.replace(tmp, '…') for a in argv)}` | "
                        f"{r.returncode} | {message.replace(tmp, '…').replace('|', '/')} | "
                        f"{peak_mb:.0f} MB, {time.perf_counter() - t0:.1f} s |")
    text = (markdown_header("Bad input: what ipm answers", COMMAND) + "\nEach row is a fresh "
            "process; peak memory is the command's resident set.  Exit 2 is a refused input, "
            "0 a run that went on with a warning or note.\n\n" + "\n".join(rows) + "\n")
    publish(text, args.out)


if __name__ == "__main__":
    main()
