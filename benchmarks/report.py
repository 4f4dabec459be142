"""``ipm bench``: one report of accuracy per parameter and speed, neural-only vs refined,
beside the paper.

Stages, each cached under ``OUT/cache`` so that a killed run resumes where it stopped (the
refinement per photo, the others per stage):

1. the held-out set: ``ipm generate`` at ``seed`` (never a training seed: the shipped nets
   were trained on seeds 0 and 1) with the photometric variation on, or a given folder;
2. predictions of the shipped ensemble and of the paper's alternatives (``--variants``: run
   folders ``reg``, ``reg-ae``, ``reg-latent``, ``reg-ae-latent`` made by
   ``benchmarks/train_variants.sh``) on every held-out photo;
3. the refinement (``ipm fit --refine`` with its defaults) on the first ``refine_count``;
4. robustness: the ensemble on the first ``robust_count`` photos under exposure changes,
   noise, blur and small rotations;
5. speed, with medians over ``repeats``.

Then ``index.md``, ``results.json`` and the plots (:mod:`ipm.benchmarks.plots`).  The
accuracy numbers depend only on the held-out images and the models, so two runs with the
same seeds give the same numbers.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ipm.benchmarks.machine import machine_info
from ipm.errors import UserError
from ipm.io import check_same_settings, write_text
from ipm.params import (
    FLYAWAY,
    PAPER_INTERVALS,
    PAPER_VALIDATION_MAE,
    RAW_CONTINUOUS,
    THICKNESS_CLASSES,
    YarnParams,
)
from ipm.photo import Photo
from ipm.refine.compare import summary as refine_summary
from ipm.refine.plan import FitConfig
from ipm.setups import DEFAULT_SETUP

PAPER = PAPER_VALIDATION_MAE
#: The paper's costs (Experiments): generator, Blender render, training on three GPUs.
PAPER_SPEED = {"generate_s": "6-12", "render_s": "60-240",
               "train_h_one_net": "2.5 (ResNet18, one parameter, 1000 epochs, 3 GPUs)",
               "train_h_reg": "about 11 (full regression net, 3 GPUs)"}
RAW = RAW_CONTINUOUS
VARIANTS = ("reg", "reg-ae", "reg-latent", "reg-ae-latent")
ENSEMBLE = "ensemble"
#: (kind, level) perturbations of the robustness stage: exposure in stops (the paper's
#: exposure series), Gaussian noise std in sRGB, Gaussian blur std in pixels, rotation in
#: degrees.
PERTURBATIONS = (("clean", 0.0), ("exposure", -1.0), ("exposure", -0.5), ("exposure", 0.5),
                 ("exposure", 1.0), ("noise", 0.01), ("noise", 0.03), ("blur", 0.7),
                 ("blur", 1.5), ("rotation", 2.0), ("rotation", 5.0))


@dataclass(frozen=True)
class BenchOptions:
    """count: held-out photos; seed: their master seed; refine_count, robust_count: photos
    refined / perturbed; repeats: of each timing; throughput_count: images generated for
    the dataset throughput; train_steps: training steps timed per net kind."""

    count: int = 200
    seed: int = 20261122
    refine_count: int = 30
    robust_count: int = 40
    repeats: int = 5
    throughput_count: int = 40
    train_steps: int = 10
    budget: int = FitConfig.budget

    @classmethod
    def quick(cls) -> BenchOptions:
        """3.4 minutes on an idle 2-core machine (measured; target: about 10)."""
        return cls(count=40, refine_count=3, robust_count=10, repeats=3, throughput_count=8,
                   train_steps=4, budget=20)

    def __post_init__(self) -> None:
        if self.count < 1 or not 0 <= self.refine_count <= self.count \
                or not 0 <= self.robust_count <= self.count or self.repeats < 1:
            raise UserError("bench: count >= 1, 0 <= refine/robust counts <= count, "
                            "repeats >= 1")


def span(k: str) -> float:
    return PAPER_INTERVALS[k].width


def _cache(folder: Path, name: str, make: Callable[[], object]):
    """The JSON stored at ``folder/cache/name.json``, made (and stored atomically) once."""
    path = folder / "cache" / f"{name}.json"
    if path.is_file():
        return json.loads(path.read_text(encoding="utf-8"))
    value = make()
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, json.dumps(value))
    return json.loads(json.dumps(value))  # the same types as a cached value


# --- stage 1: held-out set ------------------------------------------------------------------

def heldout_set(folder: Path, opts: BenchOptions, progress=None) -> Path:
    """Generate (or complete) the held-out set in ``folder``; returns it."""
    from ipm.render.dataset import GenerateOptions, generate_dataset

    generate_dataset(folder, GenerateOptions(count=opts.count, seed=opts.seed, split="test"),
                     progress=progress)
    return folder


def load_records(folder: Path, count: int) -> list:
    """The first ``count`` records by image name (a manifest lists them in the order the
    workers finished), each with its fiber seed."""
    from ipm.dataset import read_manifest

    records = sorted(read_manifest(folder), key=lambda r: str(r.image))
    if len(records) < count:
        raise UserError(f"{folder} holds {len(records)} photos, the bench needs {count}")
    if any(r.seed is None for r in records[:count]):
        raise UserError(f"{folder}/manifest.jsonl has records without a fiber seed; the bench "
                        "needs a dataset made with `ipm generate`")
    return records[:count]


# --- stage 2: predictions -------------------------------------------------------------------

def load_approaches(models: Path | None, variants: Path | None,
                    setup: str | None = None) -> dict:
    """``{name: Ensemble}``: the ensemble (of ``setup``'s shipped nets when ``models`` is
    None), and each trained variant whose raw-yarn net is in ``variants/<name>/raw``, with
    the ensemble's flyaway net (the paper trains that net the same way in every variant)."""
    from ipm.nets.ensemble import Ensemble
    from ipm.nets.store import load_net

    ens = Ensemble.load(models, setup=setup)
    out = {ENSEMBLE: ens}
    if variants is not None and not any((Path(variants) / n / "raw" / "model.json").is_file()
                                        for n in VARIANTS):
        raise UserError(f"--variants {variants} holds none of {', '.join(VARIANTS)} (each "
                        "as <name>/raw/model.json; benchmarks/train_variants.sh makes them)")
    for name in VARIANTS:
        folder = Path(variants or "-") / name / "raw"
        if variants is not None and (folder / "model.json").is_file():
            net, info = load_net(folder)
            out[name] = Ensemble({"raw": net, "flyaways": ens.nets["flyaways"]},
                                 {"raw": info, "flyaways": ens.info["flyaways"]}, folder.parent,
                                 ens.setup)
    return out


def predict_all(approaches: dict, records: list, progress=None) -> dict:
    """``{approach: [params dict per photo]}`` and the ensemble's predict time per photo."""
    preds: dict[str, list] = {name: [] for name in approaches}
    seconds = []
    for i, r in enumerate(records):
        photo = r.photo()
        for name, ens in approaches.items():
            t0 = time.perf_counter()
            preds[name].append(ens.predict(photo).to_dict())
            if name == ENSEMBLE:
                seconds.append(time.perf_counter() - t0)
        if progress:
            progress(i + 1, len(records))
    return {"predictions": preds, "predict_seconds": seconds}


def accuracy(preds: list[dict], truth: list[YarnParams], names=RAW + FLYAWAY) -> dict:
    """Per parameter: MAE in raw units and in % of the interval; ply-count and thickness
    accuracy."""
    out: dict = {"params": {}}
    for k in names:
        err = np.abs([p[k] - getattr(t, k) for p, t in zip(preds, truth, strict=True)])
        out["params"][k] = {"mae": float(err.mean()), "pct": float(100 * err.mean() / span(k))}
    out["n_accuracy"] = float(np.mean([p["n"] == t.n for p, t in zip(preds, truth,
                                                                         strict=True)]))
    out["thickness_accuracy"] = float(np.mean([
        YarnParams.from_dict(p).thickness == t.thickness
        for p, t in zip(preds, truth, strict=True)]))
    return out


def baseline_accuracy(base: dict[str, float], truth: list[YarnParams]) -> dict:
    out = {}
    for k in RAW + FLYAWAY:
        err = np.abs([base[k] - getattr(t, k) for t in truth])
        out[k] = {"mae": float(err.mean()), "pct": float(100 * err.mean() / span(k))}
    out["n_majority"] = float(max(np.mean([t.n == c for t in truth]) for c in range(2, 7)))
    out["thickness_majority"] = float(max(np.mean([t.thickness == c for t in truth])
                                          for c in THICKNESS_CLASSES))
    return out


def flyaway_distribution(preds: list[dict], truth: list[YarnParams], seeds: list[int],
                         base: dict[str, float]) -> dict:
    """The paper argues only the flyaways' distribution matters: MAE of the distribution
    statistics (:func:`ipm.measure.flyaway_stats`: counts, mean length and reach of hairs
    and loops) of the fibers generated from the predicted vs the true parameters, same fiber
    seed, beside the same for the predict-the-mean baseline."""
    from ipm.generator import generate
    from ipm.measure import flyaway_stats

    def stats(p: YarnParams, seed: int) -> dict[str, float]:
        return flyaway_stats(generate(p, seed))

    err: dict[str, list] = {}
    err_base: dict[str, list] = {}
    for p, t, seed in zip(preds, truth, seeds, strict=True):
        s_true = stats(t, seed)
        flyaways = {k: p[k] for k in FLYAWAY}
        s_pred = stats(t.replace(**flyaways), seed)
        s_base = stats(t.replace(**{k: base[k] for k in FLYAWAY}), seed)
        for k, v in s_true.items():
            err.setdefault(k, []).append(abs(s_pred[k] - v))
            err_base.setdefault(k, []).append(abs(s_base[k] - v))
    return {k: {"mae": float(np.mean(err[k])), "baseline": float(np.mean(err_base[k]))}
            for k in err}


# --- stage 3: refinement ----------------------------------------------------------------------

def refine_all(folder: Path, records: list, neural: list[dict], sigma: dict, budget: int,
               progress=None) -> list[dict]:
    """``ipm fit --refine`` with its defaults on each record, resumable: the loop of
    ``ipm compare`` (:func:`ipm.refine.compare.fit_all`) into ``folder/cache/refine.jsonl``."""
    from ipm.refine.compare import fit_all
    from ipm.refine.plan import FitConfig

    path = folder / "cache" / "refine.jsonl"
    path.parent.mkdir(parents=True, exist_ok=True)
    return fit_all(path, records, lambda i, _: YarnParams.from_dict(neural[i]),
                   FitConfig(budget=budget),
                   None if sigma is None else (lambda _: sigma), progress=progress)


# --- stage 4: robustness ----------------------------------------------------------------------

def perturb(photo: Photo, kind: str, level: float) -> Photo:
    """The photo under one capture change (deterministic: the noise is seeded); blur
    ``level`` is a sigma in photo pixels (:meth:`~ipm.photo.Photo.defocused`)."""
    from dataclasses import replace

    from ipm.photo import linear_to_srgb

    image = photo.image
    if kind == "clean":
        return photo
    if kind == "blur":
        return photo.defocused(level * photo.pixel_size_mm)
    if kind == "exposure":
        image = linear_to_srgb(np.clip(photo.linear * 2.0 ** level, 0, 1))
    elif kind == "noise":
        rng = np.random.default_rng(0)
        image = np.clip(image + rng.normal(0, level, image.shape), 0, 1).astype(np.float32)
    elif kind == "rotation":
        import kornia
        import torch

        x = torch.from_numpy(np.ascontiguousarray(image, dtype=np.float32)).permute(2, 0, 1)
        y = kornia.geometry.transform.rotate(x[None], torch.tensor([level]),
                                             padding_mode="border")
        image = y[0].permute(1, 2, 0).numpy()
    else:
        raise ValueError(f"unknown perturbation {kind!r}")
    return replace(photo, image=image)


def robustness(ens, records: list, progress=None) -> list[dict]:
    """The ensemble's MAE (% of range) per raw-yarn parameter under each perturbation."""
    photos = [r.photo() for r in records]
    rows = []
    for j, (kind, level) in enumerate(PERTURBATIONS):
        preds = [ens.predict(perturb(photo, kind, level)) for photo in photos]
        pct = {k: float(100 * np.mean([abs(getattr(p, k) - getattr(r.params, k))
                                       for p, r in zip(preds, records, strict=True)]) / span(k))
               for k in RAW}
        rows.append({"kind": kind, "level": level, "pct": pct,
                     "mean_pct": float(np.mean(list(pct.values())))})
        if progress:
            progress(j + 1, len(PERTURBATIONS))
    return rows


# --- stage 5: speed ---------------------------------------------------------------------------

def speed(opts: BenchOptions, predict_seconds: list[float], fit_seconds: list[float]) -> dict:
    """Medians over ``opts.repeats``: fiber generation, render at the dataset and the full
    scale, dataset throughput on all cores, predict and fit per photo (from the accuracy
    stages), training seconds per epoch of one ensemble net and of the Reg^ae net."""
    from ipm.benchmarks.generator_speed import time_generate
    from ipm.benchmarks.nets_speed import epoch_seconds
    from ipm.benchmarks.render_speed import YARNS, generate_throughput, median_time
    from ipm.render.renderer import Renderer

    gen = [time_generate(p, opts.repeats)[0] for p in YARNS]
    renderer = Renderer()
    out = {"generate_s": float(np.median(gen)),
           "render_s_scale_0.25_8spp": median_time(renderer, 0.25, 8, opts.repeats),
           "render_s_scale_1_16spp": median_time(renderer, 1.0, 16, opts.repeats)}
    out["dataset_images_per_hour"] = (generate_throughput(opts.throughput_count,
                                                          os.cpu_count() or 1)[0]
                                      if opts.throughput_count else None)
    out["predict_s"] = float(np.median(predict_seconds))
    out["fit_s"] = float(np.median(fit_seconds)) if fit_seconds else None
    for name, task, recon in (("train_epoch_s_ensemble_net", "alpha", False),
                              ("train_epoch_s_reg_ae_net", "raw", True)):
        out[name] = epoch_seconds(task, "resnet18", 0.25, 0.25, 32, opts.train_steps, 2000,
                                  200, recon)[1]
    return out


# --- the whole run ----------------------------------------------------------------------------

def run(out: Path, opts: BenchOptions, data: Path | None = None, models: Path | None = None,
        variants: Path | None = None, progress=None, command: str = "ipm bench") -> dict:
    """Run (or resume) every stage and write ``out/index.md``, ``out/results.json`` and the
    plots.  ``progress(stage, done, total)`` reports each stage."""
    from ipm.benchmarks import plots

    def stage(name: str):
        return (lambda done, total: progress(name, done, total)) if progress else None

    out.mkdir(parents=True, exist_ok=True)
    settings = {**asdict(opts), "data": str(data) if data else None,
                "models": str(models) if models else "shipped",
                "variants": str(variants) if variants else None}
    check_same_settings(out / "cache" / "settings.json", settings, "a run")
    approaches = load_approaches(models, variants)  # before anything is written
    ens = approaches[ENSEMBLE]
    folder = data or heldout_set(out / "heldout", opts, stage("held-out set"))
    records = load_records(folder, opts.count)
    truth = [r.params for r in records]
    _cache(out, "settings", lambda: settings)
    pred = _cache(out, "predictions", lambda: predict_all(approaches, records,
                                                          stage("predict")))
    pixel_size = records[0].pixel_size_mm  # a dataset has one scale
    base = ens.mean_prediction(pixel_size)
    results: dict = {"settings": settings, "machine": machine_info("mitsuba", "drjit", "torch",
                                                                  "nlopt", "kornia"),
                     "heldout": str(folder), "paper": PAPER, "paper_speed": PAPER_SPEED}
    results["accuracy"] = {name: accuracy(p, truth) for name, p in
                           pred["predictions"].items()}
    results["variant_best_epoch"] = {name: approaches[name].info["raw"].get("epoch")
                                     for name in approaches if name != ENSEMBLE}
    results["baseline"] = baseline_accuracy(base, truth)
    results["flyaway_distribution"] = _cache(out, "flyaway", lambda: flyaway_distribution(
        pred["predictions"][ENSEMBLE], truth, [r.seed for r in records], base))
    rows = refine_all(out, records[: opts.refine_count],
                      pred["predictions"][ENSEMBLE][: opts.refine_count], ens.sigma(pixel_size),
                      opts.budget, stage("refine"))
    results["refine"] = refine_summary(rows, truth[: len(rows)])
    results["robustness"] = _cache(out, "robustness", lambda: robustness(
        ens, records[: opts.robust_count], stage("robustness")))
    results["speed"] = _cache(out, "speed", lambda: speed(
        opts, pred["predict_seconds"], [r["seconds"] for r in rows]))
    figures = plots.make_all(out, results, pred["predictions"], truth, rows, records)
    write_text(out / "results.json", json.dumps(results, indent=2) + "\n")
    write_text(out / "index.md", markdown(results, figures, command))
    return results


# --- the report -------------------------------------------------------------------------------

def _f(x: float | None, digits: int = 4) -> str:
    return "-" if x is None else f"{x:.{digits}g}"


def heldout_sentence(settings: dict) -> str:
    if settings["data"]:
        return f"Held-out set: the first {settings['count']} photos of `{settings['data']}`."
    return (f"Held-out set: {settings['count']} renders of `ipm generate` at seed "
            f"{settings['seed']} (split `test`, photometric variation on; the shipped nets "
            "were trained on seeds 0 and 1).")


def markdown(results: dict, figures: dict[str, str], command: str) -> str:
    acc, base, ref = results["accuracy"], results["baseline"], results["refine"]
    names = list(acc)
    m = results["machine"]
    lines = ["# ipm benchmark report", "", f"Made by `{command}` "
             f"(commit {m['commit']}; {m['cpu']}, {m['cores']} cores; python {m['python']}, "
             f"mitsuba {m['mitsuba']}, drjit {m['drjit']}, torch {m['torch']}, "
             f"nlopt {m['nlopt']}, kornia {m['kornia']}).", "",
             heldout_sentence(results["settings"]) + "  Method: `benchmarks/README.md`.",
             "", "## Accuracy per parameter", "",
             "MAE in raw units (mm, radians, counts) and, below it, in % of the parameter's "
             "interval.  `baseline`: predict the mean training label (the ensemble's nets "
             "store it), for `n` and the thickness the majority class of the held-out set.  "
             "The refinement ran on fewer photos and has its own table below.", ""]
    head = ["parameter", *names, "baseline", "paper (val.)"]
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for k in RAW + FLYAWAY:
        cells = [f"{_f(acc[n]['params'][k]['mae'])}<br>{acc[n]['params'][k]['pct']:.1f}%"
                 for n in names]
        lines.append(f"| {'**' + k + '**' if k in RAW else k} | " + " | ".join(cells)
                     + f" | {_f(base[k]['mae'])}<br>{base[k]['pct']:.1f}% | "
                     + f"{PAPER.get(k, '')} |")
    lines.append("| ply count n (accuracy) | " + " | ".join(
        f"{100 * acc[n]['n_accuracy']:.1f}%" for n in names)
        + f" | {100 * base['n_majority']:.1f}% (majority) | |")
    lines.append("| thickness class (accuracy) | " + " | ".join(
        f"{100 * acc[n]['thickness_accuracy']:.1f}%" for n in names)
        + f" | {100 * base['thickness_majority']:.1f}% (majority) | |")
    lines += ["", "The paper's numbers are the validation losses of full-width ResNets "
              "trained at 1200x584 px (0.01 mm per pixel) for 850-1000 epochs on 4000 images "
              "with three GPUs; "
              + ("ours are held-out MAE of the shipped models (ResNet18 at a quarter of its "
                 "width on 300x146 px crops at 0.04 mm per pixel, for `alpha` and `m` on "
                 "photos of 0.0125 mm per pixel or finer detail nets on 256x256 px crops at "
                 "0.01 mm; 8-28 epochs on 2000 images, the detail nets on 4000, on two CPU "
                 "cores; `nets/models/README.md`)" if results["settings"]["models"]
                 == "shipped" else f"ours are held-out MAE of the models in "
                 f"`{results['settings']['models']}`")
              + "".join(f"; `{n}`: its best epoch on the validation set, {e}"
                        for n, e in results.get("variant_best_epoch", {}).items())
              + ".  The paper does not state the units of its table (its `m` of 12 reads as "
              "a raw fiber count; the others could be raw mm or normalised), so its values "
              "stand as printed.", "",
              "## Ensemble + refinement", "",
              f"`ipm fit --refine` with its defaults (the search refines "
              f"{', '.join(FitConfig().searched(DEFAULT_SETUP))}; the other parameters "
              "keep the nets' "
              f"values) on {ref['count']} photos; the search kept a candidate other than the "
              "nets' guess "
              f"for {ref['improved']}; fit time per photo: median "
              f"{_f(ref['fit_seconds_median'], 3)} s.", "",
              "| parameter | neural MAE | % of range | refined MAE | % of range | change |",
              "|---|---|---|---|---|---|"]
    for k, v in ref["params"].items():
        lines.append(f"| {k} | {_f(v['neural'])} | {100 * v['neural'] / span(k):.1f} | "
                     f"{_f(v['refined'])} | {100 * v['refined'] / span(k):.1f} | "
                     f"{v['change_pct']:+.0f}% |")
    lines += ["", "## Flyaways as distributions", "",
              "MAE of distribution statistics of the fibers generated from the ensemble's "
              "flyaway parameters (raw-yarn parameters true, same fiber seed) against those "
              "of the true parameters, beside the predict-the-mean baseline.", "",
              "| statistic | ensemble | baseline |", "|---|---|---|"]
    for k, v in results["flyaway_distribution"].items():
        lines.append(f"| {k} | {_f(v['mae'])} | {_f(v['baseline'])} |")
    lines += ["", "## Robustness", "",
              "The ensemble's MAE in % of range under capture changes, on the first "
              f"{results['settings']['robust_count']} held-out photos.", "",
              "| change | " + " | ".join(RAW) + " | mean |", "|" + "---|" * (len(RAW) + 2)]
    for r in results["robustness"]:
        label = "none" if r["kind"] == "clean" else f"{r['kind']} {r['level']:+g}"
        lines.append(f"| {label} | " + " | ".join(f"{r['pct'][k]:.1f}" for k in RAW)
                     + f" | {r['mean_pct']:.1f} |")
    lines += ["", "Units: exposure in stops, noise as the std of added Gaussian noise in "
              "sRGB, blur as a Gaussian std in pixels, rotation in degrees.", ""]
    s, ps = results["speed"], results["paper_speed"]
    lines += ["## Speed", "", f"Medians over {results['settings']['repeats']} repeats on this "
              "machine, except the dataset throughput (one run of "
              f"{results['settings']['throughput_count']} images) and the training epochs "
              f"(extrapolated from {results['settings']['train_steps']} timed steps to 2000 "
              "images).", "",
              "| what | ipm | paper |", "|---|---|---|",
              f"| fiber generation per yarn | {_f(s['generate_s'], 3)} s | "
              f"{ps['generate_s']} s |",
              f"| render 500x150, 8 spp (dataset) | {_f(s['render_s_scale_0.25_8spp'], 3)} s "
              f"| {ps['render_s']} s (Blender, 2000x600) |",
              f"| render 2000x600, 16 spp (full) | {_f(s['render_s_scale_1_16spp'], 3)} s | "
              f"{ps['render_s']} s |",
              f"| dataset images per hour, all cores | "
              f"{_f(s['dataset_images_per_hour'], 4)} | |",
              f"| predict per photo (whole ensemble) | {_f(s['predict_s'], 3)} s | |",
              f"| fit per photo (`--refine`) | {_f(s['fit_s'], 3)} s | |",
              f"| training epoch, one ensemble net (2000 images) | "
              f"{_f(s['train_epoch_s_ensemble_net'], 3)} s | {ps['train_h_one_net']} h |",
              f"| training epoch, Reg^ae net | {_f(s['train_epoch_s_reg_ae_net'], 3)} s | "
              f"{ps['train_h_reg']} h |",
              "", "## Figures", ""]
    lines += [f"![{title}]({path})" for title, path in figures.items()]
    return "\n".join(lines) + "\n"
