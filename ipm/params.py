"""The one parameter object of ipm: :class:`YarnParams`.

It is the input of the generator and the renderer, the label in the dataset, the output of
the nets and the state of the refiner.  Field names are the paper's symbols (Table 1 and the
supplemental "Value intervals"); lengths are millimetres, angles radians.

Deviations from the paper's value-interval table, and why:

* ``t_x``/``t_y``: the table gives t_x in [0.006, 0.01] and t_y in [0.006, 0.02], but its own
  sampler draws t_y in [0.006, 0.01] and t_x in [t_y, 2.5 t_y], and both thickness classes
  have t_x > t_y (thin 0.01/0.007, thick 0.018/0.01).  We read the table's columns as swapped:
  t_x (the major fiber radius) in [0.006, 0.02], t_y in [0.006, 0.01].
* ``j_z`` (z jitter of fiber vertices) has no interval in the paper; as in the authors'
  script it is a fraction of the fiber pitch (each vertex moves by ``U(-1/2, 1/2) |alpha|
  j_z`` along the axis); we allow [0, 0.05] and use 0.005 where a value is needed (presets).
* ``g`` is a density, flyaways per 10 mm of yarn, and ``d_mean``, ``d_std`` are in units of
  0.1 mm: what the authors' script makes of them (see :mod:`ipm.generator`).
* A fourth hierarchy level (plied yarns twisted into a cabled yarn, the paper's Fig. 14 d-e)
  is reachable through ``n_yarn`` > 1 with its helix ``alpha_yarn``, ``R_yarn``; the paper's
  dataset has none, so the sampler keeps ``n_yarn = 1`` and the nets do not infer them.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, NamedTuple

import numpy as np

from ipm.errors import ParamError


class Interval(NamedTuple):
    lo: float
    hi: float
    unit: str
    meaning: str
    integer: bool = False

    @property
    def width(self) -> float:
        return self.hi - self.lo


#: The paper's learnable parameters, in the fixed order of the normalised vector.
PAPER_INTERVALS: dict[str, Interval] = {
    "n": Interval(2, 6, "", "number of plies in the yarn", True),
    "m": Interval(20, 200, "", "number of fibers in each ply", True),
    "t_x": Interval(0.006, 0.02, "mm", "fiber ellipse radius (major)"),
    "t_y": Interval(0.006, 0.01, "mm", "fiber ellipse radius (minor, faces the ply centre)"),
    "alpha": Interval(-25.778, -0.476, "mm", "fiber twist: pitch of the fiber helix in a ply"),
    "r_x": Interval(0.029, 0.789, "mm", "ply ellipse radius (major)"),
    "r_y": Interval(0.042, 0.830, "mm", "ply ellipse radius (minor, faces the yarn centre)"),
    "alpha_ply": Interval(0.639, 31.655, "mm", "ply twist: pitch of the ply helix in the yarn"),
    "R_ply": Interval(0.053, 1.486, "mm", "ply twist: radius of the ply helix in the yarn"),
    "j": Interval(0.0, 0.3, "", "fiber migration: amplitude of the radial modulation"),
    "j_xy": Interval(0.0, 0.03, "mm", "fiber distribution: jitter of fiber positions"),
    "j_z": Interval(0.0, 0.05, "", "fiber migration: z jitter of fiber vertices / |alpha|"),
    "g": Interval(30, 300, "", "flyaway amount: flyaways per 10 mm of yarn", True),
    "p": Interval(0.35, 0.65, "", "loop probability of a flyaway"),
    "beta": Interval(0.050, 1.571, "rad", "hair flyaway angle to the yarn axis"),
    "l_hair": Interval(0.222, 14.5, "mm", "hair flyaway length"),
    "s": Interval(0.0, 1.0, "", "hair squeeze (fuzziness)"),
    "l_loop": Interval(0.407, 34.627, "mm", "loop flyaway length"),
    "d_mean": Interval(0.394, 30.469, "0.1 mm", "mean radial loop amplitude"),
    "d_std": Interval(0.007, 5.0, "0.1 mm", "std of the radial loop amplitude"),
}
PARAM_ORDER: tuple[str, ...] = tuple(PAPER_INTERVALS)

#: Parameters beyond the paper's table: the fourth level and the fiber appearance.
EXTRA_INTERVALS: dict[str, Interval] = {
    "n_yarn": Interval(1, 6, "", "yarns twisted into a cabled yarn (1: no fourth level)", True),
    "alpha_yarn": Interval(-60.0, 60.0, "mm", "pitch of the cabling helix (fourth level)"),
    "R_yarn": Interval(0.0, 5.0, "mm", "radius of the cabling helix (fourth level)"),
}
INTERVALS: dict[str, Interval] = {**PAPER_INTERVALS, **EXTRA_INTERVALS}

#: The continuous raw-yarn parameters: one regression net each in the paper's ensemble, the
#: ones the reports score against the paper and the search may refine.
RAW_CONTINUOUS: tuple[str, ...] = ("m", "alpha", "r_x", "r_y", "alpha_ply", "R_ply")
#: The flyaway and fiber-migration parameters, decided together by one net.
FLYAWAY: tuple[str, ...] = ("j", "j_xy", "j_z", "g", "p", "beta", "l_hair", "s", "l_loop",
                            "d_mean", "d_std")
#: The paper's validation MAE of its parameter-specific networks (Table 2), raw units.
PAPER_VALIDATION_MAE: dict[str, float] = {"r_x": 0.0080, "r_y": 0.0066, "m": 12,
                                          "alpha": 0.0807, "alpha_ply": 0.0614,
                                          "R_ply": 0.00444}


def to_unit(name: str, value: float) -> float:
    """A paper parameter's value as a fraction of its interval (0 at ``lo``, 1 at ``hi``): the
    normalised scale the nets regress."""
    iv = PAPER_INTERVALS[name]
    return (value - iv.lo) / iv.width


def from_unit(name: str, x: float) -> float | int:
    """Inverse of :func:`to_unit`: ``x`` clipped to [0, 1], integers rounded."""
    iv = PAPER_INTERVALS[name]
    x = min(max(float(x), 0.0), 1.0)
    return clipped(name, iv.lo + x * iv.width)  # lo + 1.0 * width can round past hi


def clipped(name: str, value: float) -> float | int:
    """A paper parameter's ``value`` clipped to its interval, integers rounded."""
    iv = PAPER_INTERVALS[name]
    val = min(max(float(value), iv.lo), iv.hi)
    return int(round(val)) if iv.integer else val


#: The paper's two fiber thickness classes (section "Inference of yarn parameters").
THICKNESS_CLASSES: dict[str, tuple[float, float]] = {"thin": (0.01, 0.007), "thick": (0.018, 0.01)}

DEFAULT_J_Z = 0.005
DEFAULT_COLOR = (0.8, 0.78, 0.72)


def _check_number(name: str, value: Any, iv: Interval) -> float | int:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        kind = "an integer" if iv.integer else "a number"
        raise ParamError(f"{name}: expected {kind}, got {value!r}")
    if iv.integer:
        if float(value) != int(value):
            raise ParamError(f"{name}: expected an integer, got {value!r}")
        value = int(value)
    else:
        value = float(value)
    if not math.isfinite(value) or not iv.lo <= value <= iv.hi:
        raise ParamError(f"{name} = {value!r} is outside its allowed range "
                         f"[{iv.lo:g}, {iv.hi:g}] {iv.unit}".rstrip())
    return value


#: What :meth:`YarnParams.load` reads, for the commands' help.
YARN_HELP = ("yarn parameters: JSON as `ipm sample` or `ipm predict` write, a render's "
             "sidecar, or a fit's params.json (its refined yarn)")


@dataclass(frozen=True)
class YarnParams:
    """Parameters of the hierarchical procedural yarn model (paper Table 1).

    Raw yarn: ``n`` plies of ``m`` fibers each; fibers have elliptical cross-sections with
    radii ``t_x``, ``t_y`` and wind around their ply centre on helices of pitch ``alpha``
    (negative: opposite to the ply twist); plies have elliptical cross-sections ``r_x``,
    ``r_y`` and wind around the yarn centre on a helix of pitch ``alpha_ply`` and radius
    ``R_ply``.  Fiber migration ``j``, jitters ``j_xy`` and ``j_z``.  Flyaways: ``g`` per
    10 mm of yarn, each a loop with probability ``p`` (length ``l_loop``, radial amplitude
    ``0.1 d`` mm, ``d = d_mean + |N(0, d_std)|``) or else a hair (length ``l_hair``,
    squeeze ``s``, angle ``beta``).  ``color`` is the linear RGB albedo of the fibers (not
    inferred by the paper).
    """

    n: int
    m: int
    t_x: float
    t_y: float
    alpha: float
    r_x: float
    r_y: float
    alpha_ply: float
    R_ply: float
    j: float
    j_xy: float
    j_z: float
    g: int
    p: float
    beta: float
    l_hair: float
    s: float
    l_loop: float
    d_mean: float
    d_std: float
    n_yarn: int = 1
    alpha_yarn: float = 0.0
    R_yarn: float = 0.0
    color: tuple[float, float, float] = field(default=DEFAULT_COLOR)

    def __post_init__(self) -> None:
        for name, iv in INTERVALS.items():
            object.__setattr__(self, name, _check_number(name, getattr(self, name), iv))
        c = self.color
        if (not isinstance(c, (list, tuple, np.ndarray)) or len(c) != 3
                or not all(isinstance(v, (int, float)) and 0 <= v <= 1 for v in c)):
            raise ParamError(f"color: expected three numbers in [0, 1], got {c!r}")
        object.__setattr__(self, "color", tuple(float(v) for v in c))
        if self.n_yarn > 1 and (self.alpha_yarn == 0 or self.R_yarn <= 0):
            raise ParamError("n_yarn > 1 needs alpha_yarn != 0 and R_yarn > 0 "
                             f"(got alpha_yarn = {self.alpha_yarn}, R_yarn = {self.R_yarn})")

    # -- derived -----------------------------------------------------------------------------
    @property
    def thickness(self) -> str:
        """The paper's fiber thickness class nearest to (t_x, t_y): ``thin`` or ``thick``."""
        return min(THICKNESS_CLASSES, key=lambda k: math.dist(THICKNESS_CLASSES[k],
                                                              (self.t_x, self.t_y)))

    def replace(self, **changes: Any) -> YarnParams:
        return replace(self, **changes)

    # -- JSON ---------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["color"] = list(self.color)
        return d

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_dict(cls, d: Any) -> YarnParams:
        if not isinstance(d, dict):
            raise ParamError(f"expected a JSON object of yarn parameters, got {type(d).__name__}")
        known = {f.name for f in fields(cls)}
        missing = [k for k in PARAM_ORDER if k not in d]
        if missing:
            raise ParamError(f"missing parameter(s): {', '.join(missing)}")
        unknown = sorted(k for k in d if k not in known)
        if unknown:
            import warnings

            warnings.warn(f"ignored unknown parameter(s): {', '.join(unknown)}", stacklevel=2)
        return cls(**{k: v for k, v in d.items() if k in known})

    @classmethod
    def from_json(cls, text: str) -> YarnParams:
        try:
            d = json.loads(text)
        except json.JSONDecodeError as e:
            raise ParamError(f"not valid JSON: {e}") from None
        return cls.from_dict(d)

    @classmethod
    def load(cls, path: str | os.PathLike) -> YarnParams:
        """The yarn of a JSON file: flat (``ipm sample``, ``ipm predict``), a render's sidecar
        (its ``params``) or a fit's ``params.json`` (its ``refined`` yarn, else ``neural``),
        so that every command that takes a yarn takes what the others write."""
        if os.path.exists(path):
            import stat

            if not stat.S_ISREG(os.stat(path).st_mode):
                raise ParamError(f"{path} is not a regular file (a folder, FIFO, device or "
                                 "socket); give a JSON file")
        try:
            text = open(path, encoding="utf-8").read()
        except FileNotFoundError:
            raise ParamError(f"{path}: no such file") from None
        except (OSError, UnicodeDecodeError) as e:
            raise ParamError(f"cannot read parameters from {path}: {e}") from None
        try:
            d = json.loads(text)
        except json.JSONDecodeError as e:
            raise ParamError(f"{path}: not valid JSON: {e}") from None
        for key in ("refined", "neural", "params"):
            if isinstance(d, dict) and isinstance(d.get(key), dict):
                d = d[key]
                break
        try:
            return cls.from_dict(d)
        except ParamError as e:
            raise ParamError(f"{path}: {e}") from None

    # -- normalised vector (nets, optimiser) -------------------------------------------------
    def to_vector(self) -> np.ndarray:
        """(20,) float64 in [0, 1]: the paper's parameters in :data:`PARAM_ORDER`."""
        return np.array([to_unit(k, getattr(self, k)) for k in PARAM_ORDER])

    @classmethod
    def from_vector(cls, v: np.ndarray, base: YarnParams | None = None) -> YarnParams:
        """Inverse of :meth:`to_vector`; values are clipped into [0, 1] and integers
        rounded.  Fields outside the vector (colour, fourth level) come from ``base``."""
        v = np.asarray(v, dtype=float)
        if v.shape != (len(PARAM_ORDER),):
            raise ParamError(f"expected a vector of {len(PARAM_ORDER)} values, got {v.shape}")
        vals: dict[str, Any] = {k: from_unit(k, x) for k, x in zip(PARAM_ORDER, v, strict=True)}
        extra = {} if base is None else {k: getattr(base, k) for k in (*EXTRA_INTERVALS, "color")}
        return cls(**vals, **extra)
