"""THE scene of one yarn as Mitsuba XML, so that a user can render it elsewhere
(``ipm render --format xml``): ``<out>.xml`` plus the yarn's curve file beside it.  The XML
names Mitsuba's own ``path`` integrator: ipm's ``ipm_path`` is a Python plugin that other
Mitsuba installs do not have, and ``path`` renders the same image with more noise."""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

from ipm.generator import generate
from ipm.io import write_text
from ipm.params import YarnParams
from ipm.render.scene import DEFAULT_OPTIONS, SAMPLERS, SceneOptions, scene_dict
from ipm.render.variant import mitsuba

#: The XML element of each plugin type used by :func:`scene_dict`.
_TAGS = {"path": "integrator", "orthographic": "sensor", **dict.fromkeys(SAMPLERS, "sampler"),
         "hdrfilm": "film", "box": "rfilter", "linearcurve": "shape", "rectangle": "shape",
         "principled": "bsdf", "diffuse": "bsdf", "mask": "bsdf", "area": "emitter",
         "constant": "emitter"}


def _value(name: str, v: Any, indent: str, top: bool = False) -> str:
    n = quoteattr(name)
    if isinstance(v, bool):
        return f'{indent}<boolean name={n} value="{str(v).lower()}"/>'
    if isinstance(v, int):
        return f'{indent}<integer name={n} value="{v}"/>'
    if isinstance(v, float):
        return f'{indent}<float name={n} value="{v!r}"/>'
    if isinstance(v, str):
        return f"{indent}<string name={n} value={quoteattr(v)}/>"
    if isinstance(v, dict) and v.get("type") == "rgb":
        rgb = v["value"] if isinstance(v["value"], list) else [v["value"]] * 3
        return f'{indent}<rgb name={n} value="{", ".join(repr(float(c)) for c in rgb)}"/>'
    if isinstance(v, dict):
        return _plugin(name, v, indent, top)
    matrix = " ".join(repr(float(x)) for row in v.matrix.numpy() for x in row)  # a transform
    return f'{indent}<transform name={n}>\n{indent}  <matrix value="{matrix}"/>\n' \
           f"{indent}</transform>"


def _plugin(name: str, d: dict[str, Any], indent: str, top: bool) -> str:
    tag = _TAGS[d["type"]]
    ident = f" id={quoteattr(name)}" if top else ""
    body = [_value(k, v, indent + "  ") for k, v in d.items() if k != "type"]
    return "\n".join([f"{indent}<{tag} type={quoteattr(d['type'])}{ident}>", *body,
                      f"{indent}</{tag}>"])


def scene_xml(d: dict[str, Any]) -> str:
    """Mitsuba 3 XML of a :func:`scene_dict` dict."""
    body = [_value(k, v, "  ", top=True) for k, v in d.items() if k != "type"]
    return "\n".join(['<scene version="3.0.0">', *body, "</scene>"]) + "\n"


def save_scene_xml(out: str | os.PathLike, params: YarnParams, seed: int, scale: float,
                   spp: int, variant: str | None = None,
                   options: SceneOptions = DEFAULT_OPTIONS) -> list[Path]:
    """Write ``out`` (.xml) and ``<out stem>_curves.txt``; returns both paths.  The XML
    refers to the curve file by its name, so the two move together."""
    mitsuba(variant)  # transforms in the dict are Mitsuba objects
    out = Path(out).with_suffix(".xml")
    curves = out.with_name(out.stem + "_curves.txt")
    generate(params, seed).save_mitsuba(curves)
    portable = replace(options, integrator="path")
    write_text(out, scene_xml(scene_dict(scale, spp, curves.name, params.color, portable)))
    return [out, curves]
