"""What ``ipm measure`` writes: per photo a JSON of its measures and the photo with what was
measured drawn over it; for several photos a CSV (one row a photo, in the order given: the
frames of a bobbin in the order they were taken) and a page of plots a lab would file."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from ipm.io import atomic_path, write_text
from ipm.textile.image import HAIR_PITCH_MM, Drawing, TextileMeasures

#: The hair pieces' colours by length (mm, upper bounds), shortest first: (bound, RGB).
LENGTH_COLOURS = ((0.2, (60, 200, 60)), (0.5, (240, 200, 0)), (1.0, (255, 120, 0)),
                  (float("inf"), (230, 0, 40)))
EDGE_COLOUR = (0, 170, 255)
#: The CSV's columns: every scalar measure (the lists and counts are in each JSON).
COLUMNS = ("photo", "pixel_size_mm", "length_mm", "diameter_mm", "diameter_cv_pct",
           "ply_period_mm", "plies", "ply_twist_tpm", "twist_direction", "twist_slant",
           "hairiness_h", "s3", "hair_pieces", "hair_length_median_mm")


def write_json(path: Path, m: TextileMeasures) -> None:
    """The measures as JSON, written atomically."""
    write_text(path, json.dumps(m.to_dict(), indent=1) + "\n")


def overlay(gray: np.ndarray, m: TextileMeasures, drawing: Drawing) -> np.ndarray:
    """The photo (grey, H x W in [0, 1]) with the core's edges and every counted hair
    (coloured by its piece's length: :data:`LENGTH_COLOURS`) drawn over it, and the
    measures written in its top left corner: (H, W, 3) uint8, for
    :func:`ipm.photo.write_png`."""
    im = Image.fromarray(np.round(np.clip(gray, 0, 1) * 255).astype(np.uint8)).convert("RGB")
    draw = ImageDraw.Draw(im)
    w = gray.shape[1]
    for side in (-1, 1):
        off = drawing.offset + side * drawing.radius_px
        draw.line([(0, off), (w - 1, drawing.slope * (w - 1) + off)], fill=EDGE_COLOUR,
                  width=max(1, w // 700))
    dot = max(1.0, 0.6 * max(m.pixel_size_mm, HAIR_PITCH_MM) / m.pixel_size_mm)
    for (x, y), length in zip(drawing.hair_xy, drawing.hair_length_mm, strict=True):
        colour = next(c for bound, c in LENGTH_COLOURS if length <= bound)
        draw.ellipse([x - dot, y - dot, x + dot, y + dot], fill=colour)
    text = "\n".join(m.summary() + ["hairs by piece length: green < 0.2 mm, yellow < 0.5, "
                                    "orange < 1, red longer; blue: the core's edges"])
    box = draw.multiline_textbbox((8, 8), text)
    draw.rectangle([box[0] - 4, box[1] - 4, box[2] + 4, box[3] + 4], fill=(255, 255, 255))
    draw.multiline_text((8, 8), text, fill=(0, 0, 0))
    return np.asarray(im)


def row(name: str, m: TextileMeasures) -> dict:
    """The CSV row of one photo (:data:`COLUMNS`)."""
    brief = m.brief()
    return {"photo": name, **{k: brief[k] for k in COLUMNS[1:]}}


def write_csv(path: Path, rows: list[dict]) -> None:
    """One row a photo, written atomically."""
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_text(path, buf.getvalue())


def write_plots(path: Path, names: list[str], measures: list[TextileMeasures]) -> None:
    """A lab's page of the photos in the order given: the diameter along the yarn (each
    photo's profile laid after the last), the hairiness H per photo, and the hair pieces'
    lengths pooled (histogram)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(9, 9))
    start = 0.0
    for m in measures:
        prof = np.asarray(m.diameter_profile_mm)
        step = m.length_mm / max(len(prof), 1)
        axes[0].plot(start + step * (np.arange(len(prof)) + 0.5), prof, ".-", ms=3, lw=0.8)
        start += m.length_mm
    axes[0].set(xlabel="yarn seen, frames laid end to end (mm)", ylabel="diameter (mm)",
                title="diameter along the yarn")
    axes[1].bar(range(len(measures)), [m.hairiness_h for m in measures], color="#777")
    axes[1].set(ylabel="hairiness H", title="hairiness H per photo")
    axes[1].set_xticks(range(len(names)), names, rotation=60, ha="right", fontsize=7)
    pooled = np.concatenate([m.hair_lengths_mm for m in measures] + [np.zeros(0)])
    if len(pooled):
        axes[2].hist(pooled, bins=np.linspace(0, max(0.5, float(pooled.max())), 30),
                     color="#777")
    axes[2].set(xlabel="hair piece length, projected (mm)", ylabel="pieces",
                title=f"hair lengths, {len(pooled)} pieces in {len(measures)} photos")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    with atomic_path(path) as tmp:
        tmp.write_bytes(buf.getvalue())
