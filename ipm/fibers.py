"""The generator's output: a plain structure of arrays that any renderer can read.

Coordinates are millimetres in the yarn's own frame: the yarn axis is ``z``, centred on
``z = 0``; ``x``, ``y`` span the cross-section.  A fiber is a polyline
``points[offsets[f]:offsets[f + 1]]`` with an elliptical cross-section of radii
``radii[f] = (t_x, t_y)``.
"""

from __future__ import annotations

import io
import os
import zipfile
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from ipm.io import atomic_path, write_bytes


class FiberKind(IntEnum):
    CORE = 0
    HAIR = 1
    LOOP = 2


@dataclass(frozen=True)
class FiberSet:
    """All fibers of one yarn.

    points: (V, 3) float32, mm.  offsets: (F + 1,) int64.  radii: (F, 2) float32 (t_x, t_y).
    kind: (F,) uint8 (:class:`FiberKind`).  ply: (F,) int16, the ply a fiber (or the source
    fiber of a flyaway) belongs to.
    """

    points: np.ndarray
    offsets: np.ndarray
    radii: np.ndarray
    kind: np.ndarray
    ply: np.ndarray

    def __post_init__(self) -> None:
        f = len(self.offsets) - 1
        if self.points.ndim != 2 or self.points.shape[1] != 3:
            raise ValueError(f"points must be (V, 3), got {self.points.shape}")
        if f < 0 or self.offsets[0] != 0 or self.offsets[-1] != len(self.points):
            raise ValueError("offsets must start at 0 and end at len(points)")
        if np.any(np.diff(self.offsets) < 2):
            raise ValueError("every fiber needs at least two vertices")
        for name, arr, shape in (("radii", self.radii, (f, 2)), ("kind", self.kind, (f,)),
                                 ("ply", self.ply, (f,))):
            if arr.shape != shape:
                raise ValueError(f"{name} must be {shape}, got {arr.shape}")

    @property
    def num_fibers(self) -> int:
        return len(self.offsets) - 1

    def fiber(self, f: int) -> np.ndarray:
        return self.points[self.offsets[f]:self.offsets[f + 1]]

    def fibers(self) -> list[np.ndarray]:
        return np.split(self.points, self.offsets[1:-1])

    def fiber_index(self) -> np.ndarray:
        """(V,) the fiber each vertex belongs to."""
        return np.repeat(np.arange(self.num_fibers), np.diff(self.offsets))

    # -- .npz ------------------------------------------------------------------------------
    def to_npz_bytes(self) -> bytes:
        buf = io.BytesIO()
        np.savez_compressed(buf, points=self.points.astype(np.float32),
                            offsets=self.offsets.astype(np.int64),
                            radii=self.radii.astype(np.float32), kind=self.kind.astype(np.uint8),
                            ply=self.ply.astype(np.int16))
        return buf.getvalue()

    def save_npz(self, path: str | os.PathLike) -> None:
        write_bytes(path, self.to_npz_bytes())

    @classmethod
    def load_npz(cls, path: str | os.PathLike) -> FiberSet:
        try:
            with np.load(path, allow_pickle=False) as z:
                return cls(points=z["points"], offsets=z["offsets"], radii=z["radii"],
                           kind=z["kind"], ply=z["ply"])
        except (OSError, KeyError, ValueError, zipfile.BadZipFile) as e:
            raise ValueError(f"{path}: not a fiber file ({e})") from None

    # -- Mitsuba ---------------------------------------------------------------------------
    def round_radii(self) -> np.ndarray:
        """(F,) radius of the round curve with the fiber ellipse's area, sqrt(t_x t_y).

        Mitsuba's curves are round; keeping the area keeps the occlusion a fiber casts.
        """
        return np.sqrt(self.radii[:, 0] * self.radii[:, 1])

    def mitsuba_curve_text(self) -> str:
        """Mitsuba ``linearcurve``/``bsplinecurve`` file: ``x y z radius`` per line, fibers
        separated by a blank line."""
        r = np.repeat(self.round_radii(), np.diff(self.offsets))
        rows = np.column_stack([self.points, r]).astype(np.float32)
        out = io.StringIO()
        for f, chunk in enumerate(np.split(rows, self.offsets[1:-1])):
            if f:
                out.write("\n")
            np.savetxt(out, chunk, fmt="%.6g")
        return out.getvalue()

    def save_mitsuba(self, path: str | os.PathLike) -> None:
        with atomic_path(path) as tmp:
            tmp.write_text(self.mitsuba_curve_text())
