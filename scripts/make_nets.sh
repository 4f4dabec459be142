#!/usr/bin/env bash
# Re-makes the shipped nets (nets/models) from scratch: the datasets, then the training of the
# nine nets of the `ensemble` preset and the multi-task `raw` net, then the ensemble folder
# (scripts/gather_nets.py).  This is the whole recipe of the shipped models;
# nets/models/README.md (the model card) gives its times and accuracy.
#
#   bash scripts/make_nets.sh [DATA=data] [RUNS=runs] [OUT=nets/models]
#   SETUP=backlit bash scripts/make_nets.sh data-backlit runs-backlit nets/models-backlit
#
# SETUP=backlit makes the backlit nets: renders in the backlit setup with a varied look
# (`ipm generate --vary-look`: lamps, backdrop, defocus, vignetting, tone, JPEG) and fiber
# material (`--vary-material`: how much light a fiber stops, the room's fill), and every
# training crop in another look (`ipm train --look`), since real backlit captures differ in
# all of these.  The frontlit nets are trained on the scene's own look first, then
# fine-tuned on a varied one (TUNE=1, below); without `--look`: with it, the ply-count net
# and the raw net were worse on the validation set in the recipe's epochs (measured in
# benchmarks/README.md, "Photos ipm did not make").
#
# TUNE=1 (the default for frontlit) fine-tunes every 0.04 mm net of the ensemble, from the
# nets the steps before made, for 6 epochs at lr 3e-4 on 2000 + 200 frames of the same
# yarns rendered with a varied look and material ($DATA-look: `--vary-look` moves the soft
# boxes about the yarn, greys the card from near-black to mid-grey, and the rest as
# backlit).  Trained on the varied frames from scratch in the recipe's epochs, the nets
# were worse on the varied validation set than the nets of the scene's own look (the
# ply-count net at chance); fine-tuned, better (benchmarks/README.md).  With DETAIL=1 the
# two detail nets are fine-tuned the same way on 2000 + 200 windows in the varied look.
#
# DETAIL=1 (the default for frontlit) adds detail nets for the fiber twist `alpha` and the
# fibers per ply `m`: trained on 3.2 x 3.2 mm windows rendered at 0.01 mm per pixel (`ipm
# generate --scale 1 --view 320 320`, a 256 x 256 px input) of 4000 yarns (the first 2000
# the yarns of the training set; windows cost a sixth of a whole frame), where the
# fibers' slant shows; the ensemble uses them for photos of 0.0125 mm per pixel or finer
# and the 0.04 mm nets otherwise.  With them, the ply twist `alpha_ply` is trained again for
# 24 epochs (make-g, replacing make-c's 12-epoch net; the model card has both nets'
# validation error).  The shipped backlit nets were made with DETAIL=0.
#
# FINE=1 (the default for backlit) adds nets for fine spun yarns (0.15-0.6 mm) at a
# microscope's pitch, read from photos of 0.0125 mm per pixel or finer (the real backlit
# photos): the whole ensemble again on windows of the fine sampler at 0.01 mm per pixel,
# suffix -fine (below).  MAIN=0 leaves out the datasets and nets at 0.04 mm and adds to the
# nets already in OUT: the recipe in stages, one a session (MAIN=1 FINE=0, then MAIN=0).
#
# RAW=1 (the default) adds one multi-task net of every raw-yarn parameter (the paper's
# `reg`, make-r); the ensemble takes each parameter from whichever net has the lower
# validation error on it (`Ensemble.deciders`).
#
# Every step resumes: a finished dataset or training run is left as it is, so a stopped
# script is simply run again.  Training runs as two one-thread processes side by side (the
# two cores of the reference machine), every net from scratch at lr 1e-3 with a cosine
# decay; the harder nets (alpha, m, the ply count) for more epochs.  Blur augmentation
# (--blur 1.5 input pixels) throughout, so the nets hold on defocused photos.  The data
# follow the guided prior with flyaways in the real yarns' ranges (ipm/prior.py).
set -euo pipefail
DATA="${1:-data}"; RUNS="${2:-runs}"; OUT="${3:-nets/models}"; SETUP="${SETUP:-frontlit}"
if [ "$SETUP" = frontlit ]; then DETAIL="${DETAIL:-1}"; else DETAIL="${DETAIL:-0}"; fi
if [ "$SETUP" = frontlit ]; then TUNE="${TUNE:-1}"; else TUNE="${TUNE:-0}"; fi
RAW="${RAW:-1}"; MAIN="${MAIN:-1}"
if [ "$SETUP" = backlit ]; then FINE="${FINE:-1}"; else FINE="${FINE:-0}"; fi
mkdir -p "$DATA" "$RUNS"
varied=(--setup "$SETUP" --vary-look --vary-material)
if [ "$SETUP" = frontlit ]; then
  look=(); augment=()
else
  look=("${varied[@]}"); augment=(--setup "$SETUP" --look)
fi
if [ "$MAIN" = 1 ]; then
  ipm generate --out "$DATA/train" --count 2000 --seed 0 --spp 4-24 "${look[@]}"
  ipm generate --out "$DATA/val" --count 200 --seed 1 --split val --spp 4-24 "${look[@]}"
  ipm generate --out "$DATA/test" --count 200 --seed 20261122 --split test "${look[@]}"
  detail_runs=()
  if [ "$DETAIL" = 1 ]; then
    # windows at 0.01 mm of the training yarns and more, and of the validation yarns; the test
    # yarns as whole frames at 0.01 mm (the paper's pitch), where the ensemble uses the detail
    # nets
    view=(--scale 1 --view 320 320 --spp 4-24 "${look[@]}")
    ipm generate --out "$DATA-detail/train" --count 4000 --seed 0 "${view[@]}"
    ipm generate --out "$DATA-detail/val" --count 200 --seed 1 --split val "${view[@]}"
    ipm generate --out "$DATA/test-full" --count 200 --seed 20261122 --split test --scale 1 \
      "${look[@]}"
    detail_runs=("$RUNS/make-e=-detail" "$RUNS/make-f=-detail" "$RUNS/make-g")
  fi
  recipe=(--data "$DATA/train" --val "$DATA/val" --blur 1.5 --seed 0 --lr 1e-3 "${augment[@]}")
  common=(--preset ensemble "${recipe[@]}")
  train() { OMP_NUM_THREADS=1 ipm train "${common[@]}" "$@"; }
  (train --nets alpha,m --epochs 18 --out "$RUNS/make-a" &&
   train --nets n,thickness --epochs 12 --out "$RUNS/make-b") & first=$!
  (train --nets alpha_ply,R_ply,r_x,r_y --epochs 12 --out "$RUNS/make-c" &&
   train --nets flyaways --epochs 8 --out "$RUNS/make-d" &&
   if [ "$RAW" = 1 ]; then
     OMP_NUM_THREADS=1 ipm train --preset reg --nets raw --epochs 12 "${recipe[@]}" \
       --out "$RUNS/make-r"
   fi) & second=$!
  wait "$first"; wait "$second"  # a failed training fails the script
  if [ "$DETAIL" = 1 ]; then
    detail=(--preset ensemble --data "$DATA-detail/train" --val "$DATA-detail/val" --blur 1.5
            --seed 0 --lr 1e-3 --input-scale 1 --crop 256 256 "${augment[@]}")
    (OMP_NUM_THREADS=1 ipm train "${detail[@]}" --nets alpha --epochs 16 --out "$RUNS/make-e" &&
     train --nets alpha_ply --epochs 24 --out "$RUNS/make-g") & first=$!
    (OMP_NUM_THREADS=1 ipm train "${detail[@]}" --nets m --epochs 28 --out "$RUNS/make-f") &
    second=$!
    wait "$first"; wait "$second"
  fi
  # the ensemble: each net from the last run that trained it
  raw_runs=()
  if [ "$RAW" = 1 ]; then raw_runs=("$RUNS/make-r"); fi
  python3 "$(dirname "$0")/gather_nets.py" "$OUT" "$RUNS/make-a" "$RUNS/make-b" "$RUNS/make-c" \
    "$RUNS/make-d" "${raw_runs[@]}" "${detail_runs[@]}"
fi
if [ "$TUNE" = 1 ]; then
  ipm generate --out "$DATA-look/train" --count 2000 --seed 0 --spp 4-24 "${varied[@]}"
  ipm generate --out "$DATA-look/val" --count 200 --seed 1 --split val --spp 4-24 "${varied[@]}"
  ipm generate --out "$DATA-look/test" --count 200 --seed 20261122 --split test "${varied[@]}"
  tune=(--data "$DATA-look/train" --val "$DATA-look/val" --blur 1.5 --seed 0 --lr 3e-4
        --init "$OUT" "${augment[@]}")
  retrain() { OMP_NUM_THREADS=1 ipm train --preset ensemble "${tune[@]}" "$@"; }
  (retrain --nets n,alpha_ply,R_ply --epochs 6 --out "$RUNS/tune-a" &&
   retrain --nets alpha,m,thickness,flyaways --epochs 6 --out "$RUNS/tune-c") & first=$!
  (if [ "$RAW" = 1 ]; then
     OMP_NUM_THREADS=1 ipm train --preset reg --nets raw --epochs 6 "${tune[@]}" \
       --out "$RUNS/tune-r"
   fi &&
   retrain --nets r_x,r_y --epochs 6 --out "$RUNS/tune-b") & second=$!
  wait "$first"; wait "$second"
  tune_runs=("$RUNS/tune-a" "$RUNS/tune-b" "$RUNS/tune-c")
  if [ "$RAW" = 1 ]; then tune_runs+=("$RUNS/tune-r"); fi
  if [ "$DETAIL" = 1 ]; then
    # the detail nets from make-e and make-f, on windows of the first 2000 training yarns
    # and of the validation yarns in the varied look
    windows=(--scale 1 --view 320 320 --spp 4-24 "${varied[@]}")
    ipm generate --out "$DATA-look-detail/train" --count 2000 --seed 0 "${windows[@]}"
    ipm generate --out "$DATA-look-detail/val" --count 200 --seed 1 --split val "${windows[@]}"
    retune=(--preset ensemble --data "$DATA-look-detail/train" --val "$DATA-look-detail/val"
            --blur 1.5 --seed 0 --lr 3e-4 --input-scale 1 --crop 256 256 "${augment[@]}")
    (OMP_NUM_THREADS=1 ipm train "${retune[@]}" --init "$RUNS/make-e" --nets alpha --epochs 6 \
       --out "$RUNS/tune-e") & first=$!
    (OMP_NUM_THREADS=1 ipm train "${retune[@]}" --init "$RUNS/make-f" --nets m --epochs 6 \
       --out "$RUNS/tune-f") & second=$!
    wait "$first"; wait "$second"
    tune_runs+=("$RUNS/tune-e=-detail" "$RUNS/tune-f=-detail")
  fi
  python3 "$(dirname "$0")/gather_nets.py" "$OUT" "$OUT" "${tune_runs[@]}"
fi
if [ "$FINE" = 1 ]; then
  # fine spun yarns as a microscope sees them: 3.2 x 3.2 mm windows at 0.01 mm per pixel of
  # yarns of the fine sampler (`ipm generate --yarns fine`), every net of the ensemble and
  # the raw net trained on random 256 x 256 crops, gathered beside the 0.04 mm nets with the
  # suffix -fine: the ensemble reads photos of 0.0125 mm per pixel or finer with them
  fine=(--scale 1 --view 320 320 --spp 4-24 --yarns fine "${look[@]}")
  ipm generate --out "$DATA-fine/train" --count 2000 --seed 0 "${fine[@]}"
  ipm generate --out "$DATA-fine/val" --count 200 --seed 1 --split val "${fine[@]}"
  ipm generate --out "$DATA-fine/test" --count 200 --seed 20261122 --split test "${fine[@]}"
  fine_recipe=(--data "$DATA-fine/train" --val "$DATA-fine/val" --blur 1.5 --seed 0 --lr 1e-3
               --input-scale 1 --crop 256 256 "${augment[@]}")
  ftrain() { OMP_NUM_THREADS=1 ipm train --preset ensemble "${fine_recipe[@]}" "$@"; }
  (ftrain --nets n,thickness,alpha,m --epochs 12 --out "$RUNS/fine-a" &&
   ftrain --nets flyaways --epochs 8 --out "$RUNS/fine-c") & first=$!
  (ftrain --nets alpha_ply,R_ply,r_x,r_y --epochs 12 --out "$RUNS/fine-b" &&
   if [ "$RAW" = 1 ]; then
     OMP_NUM_THREADS=1 ipm train --preset reg --nets raw --epochs 12 "${fine_recipe[@]}" \
       --out "$RUNS/fine-r"
   fi) & second=$!
  wait "$first"; wait "$second"
  fine_runs=("$RUNS/fine-a=-fine" "$RUNS/fine-b=-fine" "$RUNS/fine-c=-fine")
  if [ "$RAW" = 1 ]; then fine_runs+=("$RUNS/fine-r=-fine"); fi
  python3 "$(dirname "$0")/gather_nets.py" "$OUT" "$OUT" "${fine_runs[@]}"
fi
