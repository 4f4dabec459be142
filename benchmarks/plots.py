"""The figures of ``ipm bench`` (matplotlib, no display needed): predicted vs true and error
vs value per parameter (neural-only and refined in two colours), the loss traces of the
refinements, error growth under capture changes, and photo | neural | refined for the best
and worst refinements."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ipm.benchmarks.report import ENSEMBLE, RAW, span
from ipm.params import PAPER_INTERVALS, YarnParams

NEURAL, REFINED_C = "#1f77b4", "#ff7f0e"


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> None:
    """Write atomically: a killed run leaves the old figure or the new one."""
    tmp = path.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=90, bbox_inches="tight")
    tmp.replace(path)
    _pyplot().close(fig)


def _grid(n: int):
    plt = _pyplot()
    cols = 3
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 3.4 * rows), squeeze=False,
                             layout="constrained")
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    return fig, axes.flat


def predicted_vs_true(path: Path, preds: list[dict], truth: list[YarnParams],
                      refined: list[dict]) -> None:
    fig, axes = _grid(len(RAW))
    for ax, k in zip(axes, RAW, strict=False):
        t = np.array([getattr(p, k) for p in truth])
        ax.scatter(t, [p[k] for p in preds], s=8, c=NEURAL, label="neural", alpha=0.7)
        if refined:
            ax.scatter(t[: len(refined)], [r["refined"][k] for r in refined], s=14,
                       c=REFINED_C, marker="^", label="refined")
        iv = PAPER_INTERVALS[k]
        ax.plot([iv.lo, iv.hi], [iv.lo, iv.hi], "k--", lw=0.8)
        ax.set_title(k)
        ax.set_xlabel("true")
        ax.set_ylabel("predicted")
    axes[RAW.index("alpha")].legend(loc="upper left", fontsize=8)
    _save(fig, path)


def error_vs_value(path: Path, preds: list[dict], truth: list[YarnParams],
                   refined: list[dict]) -> None:
    fig, axes = _grid(len(RAW))
    for ax, k in zip(axes, RAW, strict=False):
        t = np.array([getattr(p, k) for p in truth])
        ax.scatter(t, 100 * np.abs([p[k] for p in preds] - t) / span(k), s=8, c=NEURAL,
                   label="neural", alpha=0.7)
        if refined:
            ax.scatter(t[: len(refined)],
                       100 * np.abs([r["refined"][k] for r in refined] - t[: len(refined)])
                       / span(k), s=14, c=REFINED_C, marker="^", label="refined")
        ax.set_title(k)
        ax.set_xlabel("true value")
        ax.set_ylabel("|error|, % of range")
    axes[RAW.index("alpha")].legend(loc="upper left", fontsize=8)
    _save(fig, path)


def loss_traces(path: Path, refined: list[dict], count: int = 6) -> None:
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    for i, r in enumerate(refined[:count]):
        trace = np.asarray(r["trace"])
        if len(trace):
            ax.plot(np.minimum.accumulate(trace) / trace[0], label=f"photo {i}")
    ax.set_xlabel("evaluation")
    ax.set_ylabel("best image loss / loss at the nets' guess")
    ax.set_title("refinement loss traces")
    ax.legend(fontsize=8)
    _save(fig, path)


def robustness(path: Path, rows: list[dict]) -> None:
    plt = _pyplot()
    kinds = [k for k in dict.fromkeys(r["kind"] for r in rows) if k != "clean"]
    clean = next(r["mean_pct"] for r in rows if r["kind"] == "clean")
    fig, axes = plt.subplots(1, len(kinds), figsize=(3.2 * len(kinds), 3), squeeze=False,
                             layout="constrained")
    for ax, kind in zip(axes[0], kinds, strict=True):
        pts = sorted([(0.0, clean)] + [(r["level"], r["mean_pct"]) for r in rows
                                      if r["kind"] == kind])
        ax.plot(*zip(*pts, strict=True), "o-")
        ax.set_title(kind)
        ax.set_ylabel("mean MAE, % of range")
    _save(fig, path)


def best_and_worst(path: Path, refined: list[dict], truth: list[YarnParams], records: list,
                   count: int = 2) -> None:
    """Rows of photo | neural | refined for the refinements with the lowest and the highest
    mean error (% of range over the refined parameters)."""
    from ipm.refine.compare import contact_sheet

    def err(i: int) -> float:
        return float(np.mean([abs(refined[i]["refined"][k] - getattr(truth[i], k)) / span(k)
                              for k in RAW]))

    order = sorted(range(len(refined)), key=err)
    picks = list(dict.fromkeys(order[:count] + order[-count:]))
    tags = {i: f"{'best' if i in order[:count] else 'worst'} (error {100 * err(i):.1f}% of "
               "range)" for i in picks}
    contact_sheet(path, refined, records, picks, tags)


def make_all(out: Path, results: dict, preds: dict[str, list], truth: list[YarnParams],
             refined: list[dict], records: list) -> dict[str, str]:
    """Every figure into ``out``; returns {title: file name} for the report."""
    figs = {"predicted vs true": "pred_vs_true.png", "error vs value": "error_vs_value.png",
            "robustness": "robustness.png"}
    predicted_vs_true(out / figs["predicted vs true"], preds[ENSEMBLE], truth, refined)
    error_vs_value(out / figs["error vs value"], preds[ENSEMBLE], truth, refined)
    robustness(out / figs["robustness"], results["robustness"])
    if refined:
        figs["refinement loss traces"] = "loss_traces.png"
        figs["best and worst refinements: photo | neural | refined"] = "best_worst.png"
        loss_traces(out / figs["refinement loss traces"], refined)
        best_and_worst(out / figs["best and worst refinements: photo | neural | refined"],
                       refined, truth, records)
    return figs
