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

from ipm.io import atomic_path


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
    def _write_npz(self, f) -> None:
        """The arrays, compressed, into the open binary file ``f`` (numpy streams each
        array in chunks; the arrays are not copied when already of their type)."""
        np.savez_compressed(f, points=self.points.astype(np.float32, copy=False),
                            offsets=self.offsets.astype(np.int64, copy=False),
                            radii=self.radii.astype(np.float32, copy=False),
                            kind=self.kind.astype(np.uint8, copy=False),
                            ply=self.ply.astype(np.int16, copy=False))

    def to_npz_bytes(self) -> bytes:
        buf = io.BytesIO()
        self._write_npz(buf)
        return buf.getvalue()

    def save_npz(self, path: str | os.PathLike) -> None:
        """Write the .npz straight to the file (atomically), without a copy in memory."""
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            self._write_npz(f)

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
        """The :meth:`mitsuba_curve_text` file, written a fiber at a time (atomically)."""
        r = np.repeat(self.round_radii(), np.diff(self.offsets))
        with atomic_path(path) as tmp, open(tmp, "w") as out:
            for f in range(self.num_fibers):
                lo, hi = self.offsets[f], self.offsets[f + 1]
                if f:
                    out.write("\n")
                np.savetxt(out, np.column_stack([self.points[lo:hi], r[lo:hi]]).astype(
                    np.float32), fmt="%.6g")

    # -- USD and PLY: for other tools --------------------------------------------------------
    def save_usd(self, path: str | os.PathLike) -> None:
        """A USD stage (``.usda`` text or ``.usd``/``.usdc`` binary, by suffix) with one
        ``BasisCurves`` prim ``/Yarn/Fibers``: linear curves, one per fiber, each with its
        round width ``2 sqrt(t_x t_y)`` (uniform), and the primvars ``kind`` and ``ply``;
        millimetres (``metersPerUnit`` 0.001), the yarn axis z up (``upAxis`` Z)."""
        from pxr import Sdf, Usd, UsdGeom, Vt

        with atomic_path(path) as tmp:
            stage = Usd.Stage.CreateNew(str(tmp))
            UsdGeom.SetStageMetersPerUnit(stage, 0.001)
            UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
            root = UsdGeom.Xform.Define(stage, "/Yarn")
            stage.SetDefaultPrim(root.GetPrim())
            curves = UsdGeom.BasisCurves.Define(stage, "/Yarn/Fibers")
            curves.CreateTypeAttr(UsdGeom.Tokens.linear)
            curves.CreateCurveVertexCountsAttr(Vt.IntArray.FromNumpy(
                np.diff(self.offsets).astype(np.int32)))
            curves.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(self.points.astype(np.float32)))
            curves.CreateWidthsAttr(Vt.FloatArray.FromNumpy(
                (2 * self.round_radii()).astype(np.float32)))
            curves.SetWidthsInterpolation(UsdGeom.Tokens.uniform)
            api = UsdGeom.PrimvarsAPI(curves)
            for name, values in (("kind", self.kind), ("ply", self.ply)):
                api.CreatePrimvar(name, Sdf.ValueTypeNames.IntArray, UsdGeom.Tokens.uniform
                                  ).Set(Vt.IntArray.FromNumpy(values.astype(np.int32)))
            stage.GetRootLayer().Save()

    def save_ply(self, path: str | os.PathLike) -> None:
        """A binary PLY of polylines: ``vertex`` (x, y, z in mm, and its ``fiber``), ``edge``
        (vertex1, vertex2: each fiber's consecutive vertices) and ``fiber`` (``radius_x``,
        ``radius_y``, ``kind``, ``ply``, ``first``, ``count``)."""
        from plyfile import PlyData, PlyElement

        v = np.empty(len(self.points), dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"),
                                              ("fiber", "i4")])
        v["x"], v["y"], v["z"] = self.points.T
        v["fiber"] = self.fiber_index()
        last = np.zeros(len(self.points), dtype=bool)
        last[self.offsets[1:] - 1] = True
        starts = np.flatnonzero(~last)
        e = np.empty(len(starts), dtype=[("vertex1", "i4"), ("vertex2", "i4")])
        e["vertex1"], e["vertex2"] = starts, starts + 1
        f = np.empty(self.num_fibers, dtype=[("radius_x", "f4"), ("radius_y", "f4"),
                                             ("kind", "u1"), ("ply", "i2"), ("first", "i4"),
                                             ("count", "i4")])
        f["radius_x"], f["radius_y"] = self.radii.T
        f["kind"], f["ply"] = self.kind, self.ply
        f["first"], f["count"] = self.offsets[:-1], np.diff(self.offsets)
        data = PlyData([PlyElement.describe(v, "vertex"), PlyElement.describe(e, "edge"),
                        PlyElement.describe(f, "fiber")], text=False)
        with atomic_path(path) as tmp:
            data.write(str(tmp))
