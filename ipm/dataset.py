"""A folder of yarn images with one manifest line per image: the contract between ``ipm
generate`` (which writes it), the nets (which train on it) and the reports (which score
against its labels).

``DIR/manifest.jsonl`` holds one JSON object per image: ``index``, ``image`` (path relative
to ``DIR``), ``params`` (flat :meth:`~ipm.params.YarnParams.to_dict`; the label),
``pixel_size_mm``, ``setup`` (the capture setup, :data:`ipm.setups.DEFAULT_SETUP` if
absent), ``seed`` (the fiber seed) and whatever else the writer records about how the
image was made (for ``ipm generate``: :mod:`ipm.render.dataset`).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ipm.errors import UserError
from ipm.frame import PIXEL_SIZE_MM
from ipm.params import YarnParams
from ipm.photo import Photo
from ipm.setups import DEFAULT_SETUP

MANIFEST = "manifest.jsonl"
#: The files a folder of photos is made of.
PHOTO_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp")
_CORE = ("index", "image", "params", "pixel_size_mm", "setup", "seed")


@dataclass(frozen=True)
class Record:
    """One image of a folder: its path, pixel size, setup and, for a labelled dataset, its
    true parameters and fiber seed.  ``info``: the other fields of its manifest line."""

    image: Path
    pixel_size_mm: float = PIXEL_SIZE_MM
    params: YarnParams | None = None
    seed: int | None = None
    setup: str = DEFAULT_SETUP
    index: int = 0
    info: dict[str, Any] = field(default_factory=dict)

    def photo(self) -> Photo:
        """The image, decoded, with its pixel size, setup and truth."""
        return Photo.read(self.image, self.pixel_size_mm, self.setup, self.params)

    def to_dict(self, folder: str | os.PathLike) -> dict[str, Any]:
        """The manifest line of this record in ``folder``."""
        return {"index": self.index, "image": Path(self.image).relative_to(folder).as_posix(),
                "params": self.params.to_dict(), "seed": self.seed,
                "pixel_size_mm": self.pixel_size_mm, "setup": self.setup, **self.info}

    @classmethod
    def from_dict(cls, d: dict[str, Any], folder: str | os.PathLike, index: int) -> Record:
        seed = d.get("seed")
        return cls(Path(folder) / d["image"], float(d.get("pixel_size_mm", PIXEL_SIZE_MM)),
                   YarnParams.from_dict(d["params"]), None if seed is None else int(seed),
                   str(d.get("setup", DEFAULT_SETUP)), int(d.get("index", index)),
                   {k: v for k, v in d.items() if k not in _CORE})


def read_manifest(folder: str | os.PathLike, allow_empty: bool = False) -> list[Record]:
    """The records of a dataset folder sorted by index, one per index (the last line of an
    index wins).  A torn last line (a killed writer) is skipped; a missing manifest, any
    other bad line or (unless ``allow_empty``) no record is a one-line :class:`UserError`."""
    folder = Path(folder)
    path = folder / MANIFEST
    if not path.is_file():
        raise UserError(f"{folder} is not a dataset: {MANIFEST} not found "
                        "(make one with `ipm generate`)")
    lines = path.read_text(encoding="utf-8").splitlines()
    records: dict[int, Record] = {}
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            rec = Record.from_dict(json.loads(line), folder, i)
        except json.JSONDecodeError:
            if i == len(lines) - 1:
                continue
            raise UserError(f"{path}:{i + 1}: not a JSON object") from None
        except (KeyError, TypeError, ValueError, AttributeError) as e:
            raise UserError(f"{path}:{i + 1}: bad record ({e})") from None
        records[rec.index] = rec
    if not records and not allow_empty:
        raise UserError(f"{path} lists no images")
    return [records[i] for i in sorted(records)]


def manifest_line(folder: str | os.PathLike, record: Record) -> str:
    """``record`` as one line of the manifest of ``folder``."""
    return json.dumps(record.to_dict(folder)) + "\n"


def write_manifest(folder: str | os.PathLike, records: list[Record]) -> None:
    """Write the manifest of ``folder`` (atomically), sorted by index."""
    from ipm.io import write_text

    write_text(Path(folder) / MANIFEST, "".join(
        manifest_line(folder, r) for r in sorted(records, key=lambda r: r.index)))


def photo_files(folder: str | os.PathLike) -> list[Path]:
    """The image files of a folder of photos, sorted by name."""
    return sorted(p for p in Path(folder).iterdir() if p.suffix.lower() in PHOTO_SUFFIXES)
