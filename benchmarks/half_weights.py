"""The shipped nets stored in float16 against the same nets in float32, on held-out renders:
per parameter the MAE of each against the truth and the mean difference between their
readings; what storing them in half the bytes (:func:`ipm.nets.store.halve`) rests on.

    python -m ipm.benchmarks.half_weights --data data/test --models nets/models \\
        --data data-backlit/test --models nets/models-backlit --count 60 \\
        --out benchmarks/results/half_weights.md
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

import numpy as np

from ipm.benchmarks.machine import markdown_header, publish
from ipm.benchmarks.nets_accuracy import mae_by_param
from ipm.dataset import read_manifest
from ipm.params import RAW_CONTINUOUS


def compare(data: str, models: str, count: int) -> tuple[list[str], dict]:
    from ipm.nets.ensemble import Ensemble
    from ipm.nets.store import halve

    records = read_manifest(data)[:count]
    photos = [r.photo() for r in records]
    true = [r.params for r in records]
    with tempfile.TemporaryDirectory(prefix="ipm-half-") as tmp:
        half = Path(tmp) / "models"
        shutil.copytree(models, half)
        halve(half)
        reads = {name: [Ensemble.load(folder, setup=records[0].setup).predict(p)
                        for p in photos]
                 for name, folder in (("float32", models), ("float16", half))}
    mae = {name: mae_by_param(r, true, RAW_CONTINUOUS) for name, r in reads.items()}
    diff = mae_by_param(reads["float16"], reads["float32"], RAW_CONTINUOUS)
    same_n = float(np.mean([a.n == b.n for a, b in zip(*reads.values(), strict=True)]))
    rows = [f"| `{data}` ({records[0].setup}, {len(records)}) | {k} | {mae['float32'][k]:.4g} | "
            f"{mae['float16'][k]:.4g} | {diff[k]:.2g} |" for k in RAW_CONTINUOUS]
    rows.append(f"| | ply count: same reading | {100 * same_n:.0f}% | | |")
    return rows, {"mae": mae, "difference": diff, "same_ply_count": same_n}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", action="append", required=True)
    ap.add_argument("--models", action="append", required=True)
    ap.add_argument("--count", type=int, default=60)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    if len(args.data) != len(args.models):
        ap.error("give one --models per --data")
    lines = ["| held-out set | parameter | MAE float32 | MAE float16 | mean difference of "
             "the readings |", "|---|---|---|---|---|"]
    data = {}
    for d, m in zip(args.data, args.models, strict=True):
        rows, data[d] = compare(d, m, args.count)
        lines += rows
    command = ("python -m ipm.benchmarks.half_weights "
               + " ".join(f"--data {d} --models {m}" for d, m in zip(args.data, args.models,
                                                                    strict=True))
               + f" --count {args.count}" + (f" --out {args.out}" if args.out else ""))
    text = (markdown_header("The nets in float16 and float32", command, "torch")
            + "\nThe first renders of each held-out set read by the nets as trained (float32) "
            "and stored in float16 (loaded back into float32).\n\n" + "\n".join(lines) + "\n")
    publish(text, args.out, data)


if __name__ == "__main__":
    main()
