"""Edits of a yarn's parameters (``ipm edit``), to make new yarns from a fitted one as the
paper's editing figure does (twist changed, flyaways doubled).

An edit is ``NAME=VALUE`` (set) or ``NAME=*FACTOR`` (scale); integer parameters are rounded
after scaling.  Every edit names a parameter of :class:`ipm.params.YarnParams` and the
result must stay inside the parameter's interval; otherwise a one-line
:class:`~ipm.errors.ParamError` names the edit.
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
                         f"{', '.join(INTERVALS)}")
    factor = value.startswith("*")
    try:
        number = float(value[1:] if factor else value)
    except ValueError:
        raise ParamError(f"edit {spec!r}: {value!r} is not a number") from None
    if not math.isfinite(number):
        raise ParamError(f"edit {spec!r}: {value!r} is not a finite number")
    return name, factor, number


def apply_edits(params: YarnParams, specs: list[str]) -> YarnParams:
    """``params`` with every edit applied in order."""
    for spec in specs:
        name, factor, number = parse_edit(spec)
        value = getattr(params, name) * number if factor else number
        if INTERVALS[name].integer:
            value = int(round(value))
        try:
            params = params.replace(**{name: value})
        except ParamError as e:
            raise ParamError(f"edit {spec!r}: {e}") from None
    return params
