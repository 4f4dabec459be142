"""The guided parameter sampler (supplemental "Yarn sampler").

Raw yarn parameters are drawn through auxiliary variables so that sampled yarns look
natural: the ply squeeze ``r_frac = r_y / r_x`` by ply count, the fiber density in a ply
``area_frac_ply``, the ply density in the yarn ``area_frac_yarn`` and the helix angles
``gamma`` (fibers in a ply) and ``gamma_ply`` (plies in the yarn); flyaway parameters are
uniform in ranges.  A draw with any parameter outside the value intervals is redrawn whole,
so the prior's support lies in the intervals' box.

Deviations: ``m`` is drawn in [40, 200] as the sampler text says (the table allows 20);
``j_z``, which the paper does not sample, is uniform in [0, 0.02] (a fraction of |alpha|);
fiber colour is uniform in a range of plausible dyed-yarn albedos (the paper varied colour
but gives no interval).  The flyaway amounts and shapes (``g p beta l_hair s l_loop d_mean
d_std``) are uniform in :data:`FLYAWAY_RANGES`, the span of the paper's 12 real yarns
widened by half of it on each side (within the intervals), not in the paper's whole
intervals: with the authors' meaning of these parameters (``g`` per 10 mm, arches of ``0.1
d`` mm) the intervals' far corners (300 flyaways per 10 mm, 35 mm loops, 14 mm hairs) wrap
the core in a cage of fibers that hides its plies, which no real yarn of the paper shows,
and nets trained on them did not learn the ply count (``nets/models/README.md``).
``GuidedPrior(flyaways="paper")`` draws them in the whole intervals, as the paper does.

Extension: ``GuidedPrior(yarns="fine")`` draws fine spun yarns (:data:`YARNS`), for the
real photos of hairiness testers and microscopes, which are thinner and denser than any
knitting yarn of the paper; the paper's sampler is ``yarns="knitting"``, the default.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ipm.errors import UserError
from ipm.params import PAPER_INTERVALS, YarnParams
from ipm.presets import PRESET_NAMES, preset

R_FRAC = {2: (0.67, 0.9), 3: (0.72, 0.91)}
R_FRAC_MANY = (0.85, 0.95)
J_Z_RANGE = (0.0, 0.02)
#: The helix angles of the fibers and of the plies, from the cross-section's plane: every
#: kind of yarn's (the search bounds the ply pitch by it too, :mod:`ipm.refine.search`).
GAMMA_DEG = (50.0, 80.0)


@dataclass(frozen=True)
class YarnRanges:
    """The sampler's ranges for one kind of yarn: fiber radius ``t_y`` (and ``t_x`` up to
    ``t_x_factor`` times it), plies ``n``, fibers per ply ``m``, the fiber density in a ply
    ``area_frac_ply``, the ply density in the yarn ``area_frac_yarn``, the helix angles
    ``gamma_deg`` (of the fibers and of the plies, from the cross-section's plane), and the
    yarn's envelope diameter ``2 (R_ply + max(r_x, r_y))`` a draw must have (None: any)."""

    t_y: tuple[float, float] = (0.006, 0.01)
    t_x_factor: float = 2.5
    n: tuple[int, int] = (2, 6)
    m: tuple[int, int] = (40, 200)
    area_frac_ply: tuple[float, float] = (0.035, 0.215)
    area_frac_yarn: tuple[float, float] = (0.55, 0.82)
    gamma_deg: tuple[float, float] = GAMMA_DEG
    diameter_mm: tuple[float, float] | None = None


#: The kinds of yarn the sampler draws (``ipm generate --yarns``).  knitting: the paper's
#: sampler, its fluffy knitting yarns (0.6-4 mm).  fine: spun yarns as a microscope or a
#: hairiness tester sees them (an ipm extension for real microscope photos, issue 51):
#: envelope 0.15-0.6 mm, fibers 12-20 um thick and round (cotton), packed densely in 2-4
#: plies (20-200 fibers each), so that a core is dark in transmitted light as real cores
#: are.
YARNS: dict[str, YarnRanges] = {
    "knitting": YarnRanges(),
    "fine": YarnRanges(t_x_factor=1.3, n=(2, 4), m=(20, 200), area_frac_ply=(0.3, 0.6),
                       diameter_mm=(0.15, 0.6)),
}
_FLYAWAY_UNIFORM = ("j", "j_xy", "p", "beta", "l_hair", "s", "l_loop", "d_mean", "d_std")
_FLYAWAY_LIKE_REAL = ("g", "p", "beta", "l_hair", "s", "l_loop", "d_mean", "d_std")


def _real_yarn_ranges(widen: float = 0.5) -> dict[str, tuple[float, float]]:
    """The span of each flyaway parameter over the paper's 12 yarns, widened by ``widen``
    of it on each side and clipped to the parameter's interval."""
    out = {}
    for k in _FLYAWAY_LIKE_REAL:
        v = [getattr(preset(name), k) for name in PRESET_NAMES]
        lo, hi, iv = min(v), max(v), PAPER_INTERVALS[k]
        pad = widen * (hi - lo)
        out[k] = (max(iv.lo, lo - pad), min(iv.hi, hi + pad))
    return out


FLYAWAY_RANGES: dict[str, tuple[float, float]] = _real_yarn_ranges()
#: The flyaways of fine spun yarns (``GuidedPrior(yarns="fine")``): the short hairs and
#: small loops close to the core that real microscope photos show, within the intervals
#: (hairs 0.22-1.5 mm, loops 0.4-2 mm long arching 0.04-0.3 mm), 30-200 per 10 mm of ply.
FINE_FLYAWAY_RANGES: dict[str, tuple[float, float]] = {
    **FLYAWAY_RANGES, "g": (30, 200), "l_hair": (0.222, 1.5), "l_loop": (0.407, 2.0),
    "d_mean": (0.394, 3.0), "d_std": (0.007, 1.0)}


@dataclass(frozen=True)
class GuidedPrior:
    """The paper's sampler.  ``sample(rng)`` returns one :class:`YarnParams`.

    >>> p = GuidedPrior().sample(np.random.default_rng(0))
    >>> 2 <= p.n <= 6
    True
    """

    max_tries: int = 10_000
    flyaways: str = "real"  # "real": in FLYAWAY_RANGES; "paper": in the whole intervals
    yarns: str = "knitting"  # a key of YARNS

    def __post_init__(self) -> None:
        if self.yarns not in YARNS:
            raise UserError(f"unknown kind of yarns {self.yarns!r}; one of {', '.join(YARNS)}")
        if self.flyaways not in ("real", "paper"):
            raise ValueError(f"flyaways must be 'real' or 'paper', got {self.flyaways!r}")

    def _raw(self, rng: np.random.Generator) -> dict:
        y = YARNS[self.yarns]
        t_y = rng.uniform(*y.t_y)
        t_x = rng.uniform(t_y, y.t_x_factor * t_y)
        n = int(rng.integers(y.n[0], y.n[1] + 1))
        m = int(rng.integers(y.m[0], y.m[1] + 1))
        r_frac = rng.uniform(*R_FRAC.get(n, R_FRAC_MANY))
        area_ply = rng.uniform(*y.area_frac_ply)
        r_x = math.sqrt(m * t_x * t_y / (area_ply * r_frac))
        r_y = r_frac * r_x
        area_yarn = rng.uniform(*y.area_frac_yarn)
        gamma_ply, gamma = np.deg2rad(rng.uniform(*y.gamma_deg, size=2))
        a = r_x / math.sin(gamma_ply)
        R_ply = math.sqrt(n * r_frac * a * a / area_yarn) - r_frac * a
        return dict(t_x=t_x, t_y=t_y, n=n, m=m, r_x=r_x, r_y=r_y, R_ply=R_ply,
                    alpha_ply=2 * math.pi * R_ply * math.tan(gamma_ply),
                    alpha=-2 * math.pi * r_x * math.tan(gamma))

    def _flyaways(self, rng: np.random.Generator) -> dict:
        box = {k: (iv.lo, iv.hi) for k, iv in PAPER_INTERVALS.items()}
        if self.flyaways == "real":
            box.update(FINE_FLYAWAY_RANGES if self.yarns == "fine" else FLYAWAY_RANGES)
        d = {k: rng.uniform(*box[k]) for k in _FLYAWAY_UNIFORM}
        d["g"] = int(rng.integers(math.ceil(box["g"][0]), math.floor(box["g"][1]) + 1))
        d["j_z"] = rng.uniform(*J_Z_RANGE)
        return d

    def _fits(self, d: dict) -> bool:
        """Inside every interval, and of the kind's diameter."""
        span = YARNS[self.yarns].diameter_mm
        diameter = 2 * (d["R_ply"] + max(d["r_x"], d["r_y"]))
        return (all(iv.lo <= d[k] <= iv.hi for k, iv in PAPER_INTERVALS.items())
                and (span is None or span[0] <= diameter <= span[1]))

    def sample(self, rng: np.random.Generator) -> YarnParams:
        for _ in range(self.max_tries):
            d = {**self._raw(rng), **self._flyaways(rng)}
            color = tuple(float(c) for c in rng.uniform(0.03, 0.9, size=3))
            if self._fits(d):
                return YarnParams(**d, color=color)
        raise RuntimeError(f"no draw inside the value intervals in {self.max_tries} tries")

    def sample_many(self, count: int, seed: int) -> list[YarnParams]:
        rng = np.random.default_rng(seed)
        return [self.sample(rng) for _ in range(count)]
