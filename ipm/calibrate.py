"""Pixel size from a photo of a millimetre scale taken with the same setup (``ipm
calibrate``): every length ipm reports is in mm, so a photo's scale decides them all.

The scale's ticks are a comb of lines 1 mm apart; in the image's power spectrum (Hann
window, zero-padded) they are a row of peaks along the scale's direction at multiples of
one cycle per mm.  The strongest peak is taken, then the lowest of its sub-harmonics (1/2,
1/3, 1/4 of its frequency, in the same direction) that is still strong: thin ticks give
harmonics as strong as the fundamental.  The peak is refined by a parabola through its
neighbours in both axes.  Any angle of the scale is fine; the ticks must be at least
:data:`MIN_PERIOD_PX` apart and at least :data:`MIN_TICKS` must be visible.  An image
without such a comb is refused in one line: the peak must stand :data:`MIN_PEAK_RATIO`
times above the spectrum's median, and the spectrum must fall between the harmonics (at
0.5 and 1.5 times the peak's frequency, at most :data:`MAX_BETWEEN` of the peak), which an
edge, a yarn or a texture does not, and its second harmonic must hold at least
:data:`MIN_HARMONIC` of the peak's power (ticks are thin lines, not a sinusoid like the
fibers of a yarn).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, fields

import numpy as np

from ipm.errors import UserError

MIN_PERIOD_PX = 3.0
MIN_TICKS = 5
MIN_PEAK_RATIO = 10000.0
MAX_BETWEEN = 0.25
MIN_HARMONIC = 0.05
SUBHARMONIC_SHARE = 0.25
#: Calibration files written by ``ipm calibrate`` carry this format tag.
FORMAT = "ipm.calibration/1"


@dataclass(frozen=True)
class Calibration:
    """mm per pixel of a setup, and how it was found."""

    pixel_size_mm: float
    tick_period_px: float
    angle_deg: float
    tick_mm: float
    source: str

    def to_json(self) -> str:
        return json.dumps({"format": FORMAT, **asdict(self)}, indent=2)

    @classmethod
    def load(cls, path: str | os.PathLike) -> Calibration:
        """Read a calibration file; a file that is not one, or a field of the wrong type
        (``true`` is not a number), is a one-line error naming the field."""
        from ipm.io import check_regular_file

        check_regular_file(path, "calibration file")
        make = "make one with `ipm calibrate ruler.png -o calib.json`"
        try:
            d = json.loads(open(path, encoding="utf-8").read())
        except (ValueError, OSError):
            d = None
        if not isinstance(d, dict) or d.pop("format", None) != FORMAT:
            raise UserError(f"{path} is not an ipm calibration file ({make})")
        for name in ("pixel_size_mm", "tick_period_px", "angle_deg", "tick_mm", "source"):
            if name not in d:
                raise UserError(f"{path}: field {name} is missing ({make})")
            v = d[name]
            ok = (isinstance(v, str) if name == "source" else
                  isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                  and (v > 0 or name == "angle_deg"))
            if not ok:
                kind = "text" if name == "source" else ("a number" if name == "angle_deg"
                                                        else "a positive number")
                raise UserError(f"{path}: field {name} must be {kind}, got {json.dumps(v)}")
        unknown = sorted(set(d) - {f.name for f in fields(cls)})
        if unknown:
            raise UserError(f"{path}: unknown field(s) {', '.join(unknown)} ({make})")
        return cls(**d)


def _peak(power: np.ndarray, i: int, j: int) -> tuple[float, float]:
    """Sub-bin position of the spectral peak at (i, j): a parabola along each axis."""
    def offset(a: float, b: float, c: float) -> float:
        denom = a - 2 * b + c
        return 0.5 * (a - c) / denom if denom != 0 else 0.0

    h, w = power.shape
    di = offset(power[(i - 1) % h, j], power[i, j], power[(i + 1) % h, j])
    dj = offset(power[i, (j - 1) % w], power[i, j], power[i, (j + 1) % w])
    return i + di, j + dj


def tick_period(gray: np.ndarray) -> tuple[float, float, float, float, float]:
    """The strongest comb in a grayscale image: (period in px, angle of the scale in degrees,
    peak / median power in the band of allowed periods, and how comb-like it is: the
    largest of the powers at 0.5 and 1.5 times its frequency relative to the peak's, near 0
    for a comb of many ticks, near 1 or above for an edge or a band; and the power of its
    second harmonic relative to the peak's, large for thin ticks, small for a sinusoid)."""
    h, w = gray.shape
    img = (gray - gray.mean()) * np.outer(np.hanning(h), np.hanning(w))
    fh, fw = 2 * int(2 ** math.ceil(math.log2(h))), 2 * int(2 ** math.ceil(math.log2(w)))
    power = np.abs(np.fft.rfft2(img, s=(fh, fw))) ** 2
    fy = np.fft.fftfreq(fh)[:, None]
    fx = np.fft.rfftfreq(fw)[None, :]
    band = (np.hypot(fy, fx) >= MIN_TICKS / max(h, w)) & (np.hypot(fy, fx) <= 1 / MIN_PERIOD_PX)
    if not band.any():
        raise UserError(f"the image ({w}x{h} px) is too small to hold a scale")
    masked = np.where(band, power, 0.0)

    def near(f_y: float, f_x: float, spectrum: np.ndarray = masked) -> tuple[float, int, int]:
        """Largest power within a bin of the frequency (f_y, f_x), and where."""
        if f_x < 0:
            f_y, f_x = -f_y, -f_x
        i, j = int(round(f_y * fh)) % fh, int(round(f_x * fw))
        rows = [(i + d) % fh for d in (-1, 0, 1)]
        cols = [c for c in (j - 1, j, j + 1) if 0 <= c < spectrum.shape[1]]
        if not cols:
            return 0.0, i, j
        win = spectrum[np.ix_(rows, cols)]
        a, b = np.unravel_index(int(np.argmax(win)), win.shape)
        return float(win[a, b]), rows[a], cols[b]

    i, j = np.unravel_index(int(np.argmax(masked)), masked.shape)
    top = masked[i, j]
    ratio = float(top / max(np.median(power[band]), 1e-30))
    for k in (4, 3, 2):  # the lowest strong sub-harmonic is the fundamental
        p, si, sj = near(fy[i, 0] / k, fx[0, j] / k)
        if p >= SUBHARMONIC_SHARE * top:
            i, j = si, sj
            break
    pi, pj = _peak(power, i, j)
    f_y, f_x = (pi if pi < fh / 2 else pi - fh) / fh, pj / fw
    peak = max(power[i, j], 1e-30)
    between = max(near(m * f_y, m * f_x, power)[0] for m in (0.5, 1.5)) / peak
    harmonic = near(2 * f_y, 2 * f_x, power)[0] / peak
    return (1 / max(math.hypot(f_y, f_x), 1e-12), math.degrees(math.atan2(f_y, f_x)), ratio,
            between, harmonic)


def calibrate(gray: np.ndarray, source: str, tick_mm: float = 1.0) -> Calibration:
    """The pixel size of a photo of a scale with ticks ``tick_mm`` apart."""
    try:
        period, angle, ratio, between, harmonic = tick_period(gray)
    except UserError as e:
        raise UserError(f"{source}: {e}") from None
    extent = max(gray.shape)
    if (ratio < MIN_PEAK_RATIO or between > MAX_BETWEEN or harmonic < MIN_HARMONIC
            or not MIN_PERIOD_PX <= period <= extent / MIN_TICKS):
        raise UserError(f"{source}: no millimetre scale found (no row of {MIN_TICKS} or more "
                        f"thin regular ticks at least {MIN_PERIOD_PX:g} px apart; the strongest "
                        f"repeat, every {period:.1f} px, stands {ratio:.0f}x above the background)")
    return Calibration(pixel_size_mm=tick_mm / period, tick_period_px=period,
                       angle_deg=angle, tick_mm=tick_mm, source=source)
