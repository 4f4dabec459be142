"""Image analysis of a yarn photo that uses neither the nets nor the renderer: the yarn's
core diameter and the period of its ply stripes, in pixels.  It is the independent yardstick
for fits on photos ipm did not make (the real backlit photos, the Cycles sets): a fit is
judged by whether its render measures like the photo.

* Signal: how much the yarn differs from the background, in [0, 1]: the background level is
  the median of the top and bottom tenths of the frame; backlit (dark yarn on a light panel)
  ``(bg - I) / bg``, frontlit (light yarn on a dark card) ``(I - bg) / (1 - bg)``.
* Axis: the signal's centroid in each column, a line fitted through them (a photo's yarn is
  rarely exactly level); every column is shifted so the axis is the middle row.
* Core diameter: the half-contrast width of the row profile (the median over columns, which
  flyaways do not move): the width of the run of rows around the peak where the profile is
  above half its peak, with linear interpolation at both edges.
* Ply-stripe period: in the band of rows within half the core radius of the axis, each row's
  autocorrelation along the axis (mean removed), averaged over rows; the period is the lag of
  the first of its maxima after its first zero crossing that reaches 60 % of the highest
  (parabolic interpolation): a yarn repeats exactly only after a whole ply turn
  ``alpha_ply``, since its plies differ, and that later maximum can be the highest.  On a plied yarn
  this is the distance between neighbouring plies' crossings, ``alpha_ply / n``.
* Fiber width (for a photo's unknown scale): the flyaway fibers in the rows beyond 0.8 core
  diameters from the axis, thresholded at half the median darkness of their skeleton (their
  half contrast); the width at each skeleton pixel is twice its distance to the background
  minus one.  The median over the skeleton pixels of components of at least
  :data:`MIN_FIBER_PIXELS` px; defocused fibers look wider, so this errs large.
* Hairiness (as a Zweigle-type hairiness tester counts it in transmitted light): the fibers
  that cross a line parallel to the axis at a distance beyond the core's edge, per mm of
  yarn, both sides averaged, at :data:`HAIR_DISTANCES_MM`.  The image is first brought to
  :data:`HAIR_PITCH_MM` (box filter) and blurred by one of its pixels, so that a sharp
  render and a photo of the same fibers count alike; a fiber counts where the signal
  exceeds :data:`HAIR_SHARE` of the core's (the row profile's peak), so that faint
  out-of-focus fibers count too.  Each line's count is the mean over its row and the two
  next to it.

    python -m ipm.benchmarks.photo_measures IMAGE... [--frontlit] [--pixel-size MM]
    python -m ipm.benchmarks.photo_measures --data DIR [--out FILE]

With ``--data``, a labelled dataset (``ipm generate``, the Cycles sets): how the yardstick
reads the true yarns, per image the core diameter over ``2 (R_ply + max(r_x, r_y))`` and
the stripe period over ``alpha_ply / n`` (medians, and the share within 15 %).
"""

from __future__ import annotations

import argparse

import numpy as np
from PIL import Image
from scipy import ndimage

#: A maximum of the autocorrelation counts as the period if it reaches this share of the
#: highest one (see the module notes).
FIRST_PEAK_SHARE = 0.6
#: Flyaway components smaller than this (px) are dust or noise, not fibers.
MIN_FIBER_PIXELS = 300
#: Hairiness: distances (mm) beyond the core's edge at which crossing fibers are counted, the
#: pitch (mm per pixel) they are counted at, and the signal, as a share of the core's, above
#: which a pixel is fiber.
HAIR_DISTANCES_MM = (0.05, 0.1, 0.2, 0.4)
HAIR_PITCH_MM = 0.01
HAIR_SHARE = 0.2


def gray(path: str) -> np.ndarray:
    """The image as float grayscale in [0, 1] (the mean of its channels)."""
    with Image.open(path) as im:
        a = np.asarray(im.convert("RGB"), dtype=np.float64) / 255.0
    return a.mean(axis=2)


def yarn_signal(img: np.ndarray, backlit: bool) -> np.ndarray:
    """How much each pixel differs from the background, towards the yarn, clipped to [0, 1]."""
    h = img.shape[0]
    edge = max(1, h // 10)
    bg = float(np.median(np.concatenate([img[:edge].ravel(), img[-edge:].ravel()])))
    sig = (bg - img) / max(bg, 1e-6) if backlit else (img - bg) / max(1 - bg, 1e-6)
    return np.clip(sig, 0.0, 1.0)


def levelled(sig: np.ndarray) -> np.ndarray:
    """The signal with every column shifted so that the yarn's fitted axis is the middle row."""
    h, w = sig.shape
    rows = np.arange(h, dtype=np.float64)[:, None]
    weight = sig ** 2
    centroid = (weight * rows).sum(0) / np.maximum(weight.sum(0), 1e-9)
    x = np.arange(w)
    slope, offset = np.polyfit(x, centroid, 1, w=np.sqrt(weight.sum(0)) + 1e-9)
    shift = (slope * x + offset) - (h - 1) / 2
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    return ndimage.map_coordinates(sig, [yy + shift[None, :], xx], order=1, mode="nearest")


def _crossing(profile: np.ndarray, i: int, j: int, level: float) -> float:
    """Where the profile crosses ``level`` between neighbouring rows i and j (linear)."""
    a, b = profile[i], profile[j]
    return i + (level - a) / (b - a) * (j - i) if b != a else float(i)


def core_diameter_px(sig: np.ndarray) -> float:
    """Half-contrast width (px) of the row profile of a levelled signal."""
    profile = ndimage.uniform_filter1d(np.median(sig, axis=1), 3)
    peak = int(np.argmax(profile))
    half = profile[peak] / 2
    top = peak
    while top > 0 and profile[top - 1] > half:
        top -= 1
    bottom = peak
    while bottom < len(profile) - 1 and profile[bottom + 1] > half:
        bottom += 1
    lo = _crossing(profile, top - 1, top, half) if top > 0 else 0.0
    hi = _crossing(profile, bottom, bottom + 1, half) if bottom < len(profile) - 1 else bottom
    return float(hi - lo)


def stripe_period_px(sig: np.ndarray, diameter_px: float) -> float:
    """Period (px) of the stripes along the axis in the core band of a levelled signal, or
    NaN when the autocorrelation has no maximum after its first zero crossing."""
    h, w = sig.shape
    half = max(1, int(diameter_px / 4))
    band = sig[(h - 1) // 2 - half:(h - 1) // 2 + half + 1]
    band = band - band.mean(axis=1, keepdims=True)
    n = 2 * w
    spec = np.fft.rfft(band, n=n, axis=1)
    ac = np.fft.irfft(spec * np.conj(spec), n=n, axis=1)[:, : w // 2].mean(axis=0)
    ac /= max(ac[0], 1e-12)
    below = np.flatnonzero(ac < 0)
    if not len(below):
        return float("nan")
    k = np.arange(below[0] + 1, len(ac) - 1)
    peaks = k[(ac[k] > ac[k - 1]) & (ac[k] >= ac[k + 1]) & (ac[k] > 0)]
    if not len(peaks):
        return float("nan")
    k = int(peaks[np.argmax(ac[peaks] >= FIRST_PEAK_SHARE * ac[peaks].max())])
    a, b, c = ac[k - 1], ac[k], ac[k + 1]
    denom = a - 2 * b + c
    return float(k + (0.5 * (a - c) / denom if denom != 0 else 0.0))


def fiber_width_px(sig: np.ndarray, diameter_px: float) -> tuple[float, int]:
    """(median width in px of the flyaway fibers outside the core, skeleton pixels it rests
    on) of a levelled signal; NaN and 0 without fibers."""
    from skimage.morphology import skeletonize

    h, w = sig.shape
    outside = np.broadcast_to((np.abs(np.arange(h) - (h - 1) / 2) > 0.8 * diameter_px)[:, None],
                              (h, w))
    smooth = ndimage.gaussian_filter(sig, 0.7)
    fibers = ndimage.binary_opening((smooth > 0.25) & outside)
    labels, count = ndimage.label(fibers)
    sizes = ndimage.sum(fibers, labels, range(1, count + 1))
    skeleton = skeletonize(np.isin(labels, 1 + np.flatnonzero(sizes >= MIN_FIBER_PIXELS)))
    if not skeleton.any():
        return float("nan"), 0
    half = (smooth > np.median(smooth[skeleton]) / 2) & outside
    widths = 2 * ndimage.distance_transform_edt(half)[skeleton & half] - 1
    widths = widths[widths > 1]
    return (float(np.median(widths)), len(widths)) if len(widths) else (float("nan"), 0)


def at_pitch(img: np.ndarray, pixel_size_mm: float, pitch_mm: float) -> np.ndarray:
    """A grey image (H, W) at ``pixel_size_mm`` brought to the coarser ``pitch_mm`` by a box
    filter (returned as it is if it is not finer)."""
    if pixel_size_mm >= pitch_mm:
        return img
    f = pixel_size_mm / pitch_mm
    size = (max(1, round(img.shape[1] * f)), max(1, round(img.shape[0] * f)))
    im = Image.fromarray(img.astype(np.float32), mode="F").resize(size, Image.Resampling.BOX)
    return np.asarray(im, dtype=np.float64)


def hairiness(img: np.ndarray, pixel_size_mm: float, backlit: bool = True
              ) -> dict[float, float]:
    """Fibers per mm of yarn crossing the lines at each of :data:`HAIR_DISTANCES_MM` beyond
    the core's edge (module notes) in a grey image (H, W) at ``pixel_size_mm``; NaN where a
    line leaves the frame on both sides."""
    img = at_pitch(img, pixel_size_mm, HAIR_PITCH_MM)
    pitch = max(pixel_size_mm, HAIR_PITCH_MM)
    sig = ndimage.gaussian_filter(levelled(yarn_signal(img, backlit)), 1.0)
    h, w = sig.shape
    radius = core_diameter_px(sig) / 2
    fiber = sig > HAIR_SHARE * np.median(sig, axis=1).max()
    crossings = np.count_nonzero(fiber[:, 1:] & ~fiber[:, :-1], axis=1) + fiber[:, 0]
    out = {}
    for dist in HAIR_DISTANCES_MM:
        rows = [round((h - 1) / 2 + side * (radius + dist / pitch)) + k
                for side in (-1, 1) for k in (-1, 0, 1)]
        rows = [r for r in rows if 0 <= r < h]
        out[dist] = float(np.mean(crossings[rows])) / (w * pitch) if rows else float("nan")
    return out


def measure_image(img: np.ndarray, backlit: bool) -> dict[str, float]:
    """Core diameter and ply-stripe period (px) of a grey image (H, W) in [0, 1]."""
    sig = levelled(yarn_signal(img, backlit))
    d = core_diameter_px(sig)
    return {"core_diameter_px": d, "stripe_period_px": stripe_period_px(sig, d)}


def measure(path: str, backlit: bool) -> dict[str, float]:
    """Core diameter and ply-stripe period (px) of the photo at ``path``."""
    return measure_image(gray(path), backlit)


def agreement(folder: str, count: int | None = None) -> dict[str, float]:
    """The yardstick against the truth on a labelled dataset (each image's own setup):
    medians of the measured over the true core diameter and stripe period, and the share
    of periods within 15 %."""
    from ipm.dataset import read_manifest

    core, period = [], []
    for r in read_manifest(folder)[:count]:
        m = measure(str(r.image), backlit=r.setup == "backlit")
        p = r.params
        core.append(m["core_diameter_px"] * r.pixel_size_mm / (2 * (p.R_ply + max(p.r_x, p.r_y))))
        period.append(m["stripe_period_px"] * r.pixel_size_mm / (p.alpha_ply / p.n))
    period_ok = np.array(period)[np.isfinite(period)]
    return {"images": len(core), "core_ratio": float(np.median(core)),
            "period_ratio": float(np.median(period_ok)) if len(period_ok) else float("nan"),
            "period_within_15pct": float(np.mean(np.abs(np.array(period) - 1) < 0.15))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("images", nargs="*")
    ap.add_argument("--frontlit", action="store_true", help="light yarn on a dark background")
    ap.add_argument("--pixel-size", type=float, default=None, help="mm per pixel, for mm")
    ap.add_argument("--data", action="append", default=[], help="labelled dataset(s): the "
                    "yardstick against their truth")
    ap.add_argument("--count", type=int, default=None, help="first N images of each dataset")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    if args.data:
        from ipm.benchmarks.machine import markdown_header, publish

        lines = ["| dataset | images | core measured / 2 (R_ply + r) | period measured / "
                 "(alpha_ply / n) | periods within 15 % |", "|---|---|---|---|---|"]
        for folder in args.data:
            a = agreement(folder, args.count)
            lines.append(f"| `{folder}` | {a['images']} | {a['core_ratio']:.2f} | "
                         f"{a['period_ratio']:.2f} | {100 * a['period_within_15pct']:.0f}% |")
        command = "python -m ipm.benchmarks.photo_measures " + " ".join(
            [f"--data {d}" for d in args.data] + ([f"--count {args.count}"] if args.count
                                                  else []) + ([f"--out {args.out}"]
                                                              if args.out else []))
        publish(markdown_header("The net-free yardstick on labelled renders", command,
                                "numpy") + "\n" + "\n".join(lines) + "\n", args.out)
        return
    if not args.images:
        ap.error("give images, or --data DIR")
    scale = args.pixel_size or 1.0
    unit = "mm" if args.pixel_size else "px"
    print(f"| image | core diameter ({unit}) | stripe period ({unit}) |\n|---|---|---|")
    for path in args.images:
        m = measure(path, backlit=not args.frontlit)
        print(f"| {path} | {m['core_diameter_px'] * scale:.4g} | "
              f"{m['stripe_period_px'] * scale:.4g} |")


if __name__ == "__main__":
    main()
