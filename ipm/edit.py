"""Edits of a yarn's parameters (``ipm edit``), to make new yarns from a fitted one as the
paper's editing figure does (twist changed, flyaways doubled).

An edit is ``NAME=VALUE`` (set) or ``NAME=*FACTOR`` (scale), or ``color=R,G,B`` (the linear
albedo, each in [0, 1]).  Every edit names a parameter of :class:`ipm.params.YarnParams` and
the result must stay inside the parameter's interval, and be a whole number for an integer
parameter (``n=2.5`` or ``n=*1.5`` on n = 3 is refused, not rounded, as a parameter file's
would be); otherwise a one-line :class:`~ipm.errors.ParamError` names the edit.
"""

from __future__ import annotations

import math

from ipm.errors import ParamError
from ipm.params import INTERVALS, YarnParams


def parse_edit(spec: str) -> tuple[str, bool, float]:
    """``(name, is_factor, number)`` of one edit."""
    name, sep, value = spec.partition("=")
    name, value = name.strip(), value.strip()
    if not sep or not name or not value:
        raise ParamError(f"edit {spec!r}: expected NAME=VALUE or NAME=*FACTOR")
    if name not in INTERVALS:
        raise ParamError(f"edit {spec!r}: unknown parameter {name!r}; choose one of: "
                         f"{', '.join(INTERVALS)}, color")
    factor = value.startswith("*")
    try:
        number = float(value[1:] if factor else value)
    except ValueError:
        raise ParamError(f"edit {spec!r}: {value!r} is not a number") from None
    if not math.isfinite(number):
        raise ParamError(f"edit {spec!r}: {value!r} is not a finite number")
    return name, factor, number


def parse_color(spec: str) -> tuple[float, float, float]:
    """The colour of an edit ``color=R,G,B``."""
    value = spec.partition("=")[2]
    try:
        rgb = tuple(float(v) for v in value.split(","))
    except ValueError:
        rgb = ()
    if len(rgb) != 3 or not all(0 <= v <= 1 for v in rgb):
        raise ParamError(f"edit {spec!r}: color takes three numbers in [0, 1], e.g. "
                         "color=0.6,0.4,0.3 (linear RGB albedo)")
    return rgb


def apply_edits(params: YarnParams, specs: list[str]) -> YarnParams:
    """``params`` with every edit applied in order."""
    for spec in specs:
        if spec.partition("=")[0].strip() == "color":
            params = params.replace(color=parse_color(spec))
            continue
        name, factor, number = parse_edit(spec)
        value = getattr(params, name) * number if factor else number
        iv = INTERVALS[name]
        if iv.integer:
            if iv.lo <= value <= iv.hi and value != round(value):  # (outside: said below)
                raise ParamError(f"edit {spec!r}: {name} is an integer, and this gives "
                                 f"{value:g}; give a whole number")
            value = int(round(value))
        try:
            params = params.replace(**{name: value})
        except ParamError as e:
            raise ParamError(f"edit {spec!r}: {e}") from None
    return params
