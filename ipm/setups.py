"""The capture setups: how a yarn is photographed, as data that every layer reads.

A setup says what the scene builds (:mod:`ipm.render.scene`: its lights and background, its
fiber material), which shipped nets read its photos (:mod:`ipm.nets.ensemble`), which
groups of the loss score a fit's stages (:mod:`ipm.refine.objective`), how a fit shows its
renders in the photo's capture (:mod:`ipm.refine.capture`) and which stages a fit runs by
default (:mod:`ipm.refine.plan`).  Only this module names a setup; the others look one up
by the name a photo or a dataset records (``--setup``).

>>> setup_of(DEFAULT_SETUP).light_behind
False
>>> sorted(s.light_behind for s in SETUPS.values())
[False, True]
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ipm.errors import UserError


@dataclass(frozen=True)
class CaptureSetup:
    """One capture setup.

    name: what ``--setup`` and the manifests call it.  summary: one line for the user.
    light_behind: the light is a panel behind the yarn that the camera sees, so the
    background is the light itself (the yarn a dark, partly translucent silhouette whose
    fibers let some light through; the exposure is the background's level); otherwise
    lamps in front light the yarn over a dark card (the card's albedo is the background's
    level).  grey: the photos are grey (a monochrome sensor: renders and fiber albedo are
    grey).  scene: :class:`ipm.render.scene.SceneOptions` fields that differ from the
    scene's defaults.  models: the folder of the shipped nets, beside :mod:`ipm.nets`.
    pitch_groups: the loss groups that score a stage searching the ply pitch alone.
    count_groups: the loss groups that choose the ply count before the pitch is searched
    (none: the nets' count stands).  stages: a fit's default search (``ipm fit --params``
    syntax).  outside_stages: the search of a yarn whose core renders far wider or narrower
    than the photo's at the nets' reading (None: this setup's core width does not tell
    such a yarn, and the default search stands).  card_linear: the level (linear grey) of
    the card in the scene's own renders, lamps in front; the nets read a photo with its card
    brought to it (:func:`ipm.photo.card_normalised`), so that they read a yarn on any card
    as on the one they were trained on, and a fit renders on the photo's card, this many
    times the scene's (:func:`ipm.refine.capture.search_card`) (None: the background is the
    light)."""

    name: str
    summary: str
    light_behind: bool
    grey: bool
    scene: dict[str, Any] = field(default_factory=dict)
    models: str = "models"
    pitch_groups: tuple[str, ...] = ("period", "stripes")
    count_groups: tuple[str, ...] = ()
    stages: str = "alpha_ply"
    outside_stages: str | None = None
    card_linear: float | None = None


#: The setups, the default first.  Why these groups and stages: the docstrings of
#: :mod:`ipm.refine.objective` and :mod:`ipm.refine.plan`.
SETUPS: dict[str, CaptureSetup] = {s.name: s for s in (
    CaptureSetup("frontlit", "colour macro photo under soft boxes, the paper's",
                 light_behind=False, grey=False, card_linear=0.016),
    CaptureSetup("backlit", "grey silhouette on a light panel, as hairiness testers and "
                 "microscopes", light_behind=True, grey=True,
                 scene={"integrator": "path", "max_depth": 16, "room_light": 0.05},
                 models="models-backlit", pitch_groups=("period", "stripes", "contour"),
                 count_groups=("silhouette",),
                 outside_stages="R_ply,r_x,r_y;g,l_hair,l_loop,d_mean;alpha_ply"),
)}
NAMES = tuple(SETUPS)
#: The setup of a photo or dataset that names none.
DEFAULT_SETUP = NAMES[0]
#: ``--setup``'s help, every command alike.
SETUP_HELP = "capture setup: " + " or ".join(f"{s.name} ({s.summary})" for s in SETUPS.values())
#: ``--setup auto``: the setup told from the photo (:func:`ipm.photo.detect_setup`).
AUTO_SETUP = "auto"


def lit(behind: bool) -> str:
    """The name of the setup that lights the yarn from behind (``behind``) or in front."""
    return next(s.name for s in SETUPS.values() if s.light_behind is behind)


#: ``--invert``'s help: a dark yarn on a light panel is a setup of its own, not a negative.
INVERT_HELP = ("invert the photos first (an odd case, e.g. negatives; a dark yarn on a light "
               f"panel takes --setup {lit(True)})")
#: ``--setup``'s help where the setup may be told from the photo.
PHOTO_SETUP_HELP = (f"capture setup of the photo: {', '.join(NAMES)}, or {AUTO_SETUP} (told "
                    f"from the photo: a dark yarn on a light background is {lit(True)}; the "
                    "choice is said)")


def setup_of(name: str) -> CaptureSetup:
    """The setup called ``name`` (one line naming the choices if unknown)."""
    if name not in SETUPS:
        raise UserError(f"unknown capture setup {name!r}; one of {', '.join(NAMES)}")
    return SETUPS[name]


def check_setup_name(setup: str) -> None:
    """A one-line :class:`UserError` for a setup that is neither a setup's name nor
    :data:`AUTO_SETUP`."""
    if setup != AUTO_SETUP:
        setup_of(setup)
