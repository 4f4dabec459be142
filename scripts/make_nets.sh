#!/usr/bin/env bash
# Re-makes the shipped nets (nets/models) from scratch: the datasets, then the training of the
# nine nets of the `ensemble` preset, then the ensemble folder.  This is the
# whole recipe of the shipped models; nets/models/README.md (the model card) gives its times
# and accuracy.
#
#   bash scripts/make_nets.sh [DATA=data] [RUNS=runs] [OUT=nets/models]
#   SETUP=backlit bash scripts/make_nets.sh data-backlit runs-backlit nets/models-backlit
#
# SETUP=backlit makes the backlit nets: renders in the backlit setup with a varied look
# (`ipm generate --vary-look`: lamps, backdrop, defocus, vignetting, tone, JPEG), and every
# training crop in another look (`ipm train --look`), since real backlit captures differ in
# all of these.
#
# Every step resumes: a finished dataset or training run is left as it is, so a stopped
# script is simply run again.  Training runs as two one-thread processes side by side (the
# two cores of the reference machine), every net from scratch at lr 1e-3 with a cosine
# decay; the harder nets (alpha, m, the ply count) for more epochs.  Blur augmentation
# (--blur 1.5 input pixels) throughout, so the nets hold on defocused photos.  The data
# follow the guided prior with flyaways in the real yarns' ranges (ipm/prior.py).
set -euo pipefail
DATA="${1:-data}"; RUNS="${2:-runs}"; OUT="${3:-nets/models}"; SETUP="${SETUP:-frontlit}"
mkdir -p "$DATA" "$RUNS"
if [ "$SETUP" = frontlit ]; then
  look=(); augment=()
else
  look=(--setup "$SETUP" --vary-look); augment=(--setup "$SETUP" --look)
fi
ipm generate --out "$DATA/train" --count 2000 --seed 0 --spp 4-24 "${look[@]}"
ipm generate --out "$DATA/val" --count 200 --seed 1 --split val --spp 4-24 "${look[@]}"
ipm generate --out "$DATA/test" --count 200 --seed 20261122 --split test "${look[@]}"
common=(--preset ensemble --data "$DATA/train" --val "$DATA/val" --blur 1.5 --seed 0 --lr 1e-3
        "${augment[@]}")
train() { OMP_NUM_THREADS=1 ipm train "${common[@]}" "$@"; }
(train --nets alpha,m --epochs 18 --out "$RUNS/make-a" &&
 train --nets n,thickness --epochs 12 --out "$RUNS/make-b") & first=$!
(train --nets alpha_ply,R_ply,r_x,r_y --epochs 12 --out "$RUNS/make-c" &&
 train --nets flyaways --epochs 8 --out "$RUNS/make-d") & second=$!
wait "$first"; wait "$second"  # a failed training fails the script
# the ensemble: each net from the last run that trained it
python3 - "$OUT" "$RUNS/make-a" "$RUNS/make-b" "$RUNS/make-c" "$RUNS/make-d" <<'PY'
"""Gather the runs' nets into one ensemble folder (written beside, then swapped in); a net
of a later run replaces the same net of an earlier one."""
import json, shutil, sys
from pathlib import Path

out, runs = Path(sys.argv[1]), [Path(r) for r in sys.argv[2:]]
order = ["n", "thickness", "m", "alpha", "r_x", "r_y", "alpha_ply", "R_ply", "flyaways"]
tmp = out.with_name(out.name + ".new")
shutil.rmtree(tmp, ignore_errors=True)
tmp.mkdir(parents=True)
for run in runs:
    for net in json.loads((run / "ensemble.json").read_text())["nets"]:
        shutil.rmtree(tmp / net, ignore_errors=True)
        (tmp / net).mkdir()
        for f in (run / net).glob("model.*"):  # the net, not its training checkpoint
            shutil.copy(f, tmp / net / f.name)
setup = json.loads((runs[0] / "ensemble.json").read_text()).get("setup", "frontlit")
manifest = {"format": "ipm.nets/1", "preset": "ensemble", "setup": setup, "nets": order}
assert sorted(p.name for p in tmp.iterdir()) == sorted(order), "a net is missing"
(tmp / "ensemble.json").write_text(json.dumps(manifest, indent=2))
if (out / "README.md").exists():
    shutil.copy(out / "README.md", tmp / "README.md")
shutil.rmtree(out, ignore_errors=True)
tmp.rename(out)
print(f"ensemble of {len(order)} nets -> {out}")
PY
