#!/usr/bin/env python3
"""Gathers training runs' nets into one ensemble folder (written beside, then swapped in); a
net of a later run replaces the same net of an earlier one.  A run given as RUN=SUFFIX has
its nets renamed NAME+SUFFIX (the detail nets, beside the nets of the same parameters).
OUT may be one of the RUNs (a fine-tune replacing some of its nets).  The nets are stored in
float16, which reads as float32 does (benchmarks/results/half_weights.md).  The last step
of scripts/make_nets.sh:

    python3 scripts/gather_nets.py OUT RUN [RUN=SUFFIX ...]
"""
import json
import shutil
import sys
from pathlib import Path

from ipm.nets.store import halve

out = Path(sys.argv[1])
runs = [(Path(r.partition("=")[0]), r.partition("=")[2]) for r in sys.argv[2:]]
order = ["n", "thickness", "m", "alpha", "r_x", "r_y", "alpha_ply", "R_ply", "flyaways"]
for with_suffix in (False, True):  # the multi-task raw net after these, the detail nets last
    for run, suffix in runs:
        for net in json.loads((run / "ensemble.json").read_text())["nets"]:
            if bool(suffix) == with_suffix and f"{net}{suffix}" not in order:
                order.append(f"{net}{suffix}")
tmp = out.with_name(out.name + ".new")
shutil.rmtree(tmp, ignore_errors=True)
tmp.mkdir(parents=True)
for run, suffix in runs:
    for net in json.loads((run / "ensemble.json").read_text())["nets"]:
        shutil.rmtree(tmp / f"{net}{suffix}", ignore_errors=True)
        (tmp / f"{net}{suffix}").mkdir()
        for f in (run / net).glob("model.*"):  # the net, not its training checkpoint
            shutil.copy(f, tmp / f"{net}{suffix}" / f.name)
setup = json.loads((runs[0][0] / "ensemble.json").read_text()).get("setup", "frontlit")
manifest = {"format": "ipm.nets/1", "preset": "ensemble", "setup": setup, "nets": order}
assert sorted(p.name for p in tmp.iterdir()) == sorted(order), "a net is missing"
(tmp / "ensemble.json").write_text(json.dumps(manifest, indent=2))
halve(tmp)
if (out / "README.md").exists():
    shutil.copy(out / "README.md", tmp / "README.md")
shutil.rmtree(out, ignore_errors=True)
tmp.rename(out)
print(f"ensemble of {len(order)} nets -> {out}")
