"""``ipm bench``: the user's entry point to the benchmark report (:mod:`ipm.benchmarks.report`).
Heavy imports happen inside the command."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path
from typing import Annotated

import typer

from ipm.io import prepare_folder


def bench(
    out: Annotated[Path, typer.Option("--out", "-o", help="report folder (index.md, "
                                      "results.json, plots); a stopped run resumes")]
    = Path("report"),
    quick: Annotated[bool, typer.Option("--quick", help="a small run, 3-4 minutes on "
                                        "2 cores")] = False,
    data: Annotated[Path | None, typer.Option(help="held-out set made with `ipm generate` "
                                              "(default: generated into OUT/heldout)")] = None,
    models: Annotated[Path | None, typer.Option(help="ensemble folder (default: the shipped "
                                                "models)")] = None,
    variants: Annotated[Path | None, typer.Option(help="folder with the runs reg, reg-ae, "
                                                  "reg-latent, reg-ae-latent "
                                                  "(benchmarks/train_variants.sh)")] = None,
    count: Annotated[int | None, typer.Option(help="held-out photos (200; quick: 40)")] = None,
    refine_count: Annotated[int | None, typer.Option(help="photos refined (30; quick: 3)")]
    = None,
    seed: Annotated[int, typer.Option(help="master seed of the held-out set")] = 20261122,
) -> None:
    """Benchmark report per parameter: accuracy of the nets and of the refinement beside the
    paper, flyaway distributions, robustness to capture changes, and speed."""
    from dataclasses import replace

    from ipm.benchmarks.report import BenchOptions, run
    from ipm.progress import progress_bar

    opts = BenchOptions.quick() if quick else BenchOptions()
    opts = replace(opts, seed=seed, **({"count": count} if count is not None else {}),
                   **({"refine_count": refine_count} if refine_count is not None else {}))
    opts = replace(opts, robust_count=min(opts.robust_count, opts.count),
                   refine_count=min(opts.refine_count, opts.count))
    prepare_folder(out, "report folder")
    with progress_bar() as bar:
        tasks: dict[str, int] = {}

        def progress(stage: str, done: int, total: int) -> None:
            if stage not in tasks:
                tasks[stage] = bar.add_task(stage, total=total)
            bar.update(tasks[stage], completed=done, total=total)

        run(out, opts, data, models, variants, progress,
            command="ipm " + " ".join(shlex.quote(a) for a in sys.argv[1:]))
    typer.echo(f"wrote {out}/index.md, {out}/results.json and the plots", err=True)
