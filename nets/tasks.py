"""What each net of an ensemble predicts: a :class:`Task`.

A regression task predicts some of the paper's parameters normalised to [0, 1] (the
intervals of :data:`ipm.params.PAPER_INTERVALS`); a classification task picks one of a few
classes: the ply count ``n`` (2..6, softmax over 5) or the fiber thickness class (the
paper's thin / thick fibers, which set ``t_x`` and ``t_y``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ipm.params import (
    FLYAWAY,
    PAPER_INTERVALS,
    PARAM_ORDER,
    RAW_CONTINUOUS,
    THICKNESS_CLASSES,
    YarnParams,
    from_unit,
)

RAW_PARAMS = ("n", "m", "t_x", "t_y", "alpha", "r_x", "r_y", "alpha_ply", "R_ply")
PLY_COUNTS = (2, 3, 4, 5, 6)
THICKNESSES = tuple(THICKNESS_CLASSES)


@dataclass(frozen=True)
class Task:
    """One net's job.  ``params``: the yarn parameters it decides; ``classes``: non-empty
    for a classification (then ``params`` has the class attribute: ``n`` or ``thickness``)."""

    name: str
    params: tuple[str, ...]
    classes: tuple = ()

    @property
    def is_classification(self) -> bool:
        return bool(self.classes)

    @property
    def outputs(self) -> int:
        return len(self.classes) if self.classes else len(self.params)

    @property
    def decides(self) -> tuple[str, ...]:
        """The :class:`YarnParams` fields set by this net's prediction."""
        return ("t_x", "t_y") if self.name == "thickness" else self.params

    def target(self, p: YarnParams) -> np.ndarray:
        """The label: a class index (int64 scalar) or normalised parameters ``(K,)``."""
        if self.is_classification:
            return np.int64(self.classes.index(getattr(p, self.params[0])))
        v = p.to_vector()
        return np.array([v[PARAM_ORDER.index(k)] for k in self.params], dtype=np.float32)

    def decode(self, out: np.ndarray) -> dict[str, float | int]:
        """Parameter values from one output ``(K,)``: class probabilities or normalised
        parameters (clipped to the intervals, integers rounded)."""
        if self.is_classification:
            cls = self.classes[int(np.argmax(out))]
            if self.name == "thickness":
                return dict(zip(("t_x", "t_y"), THICKNESS_CLASSES[cls], strict=True))
            return {self.params[0]: cls}
        return {k: from_unit(k, x) for k, x in zip(self.params, out, strict=True)}


def regression(*params: str, name: str | None = None) -> Task:
    unknown = [k for k in params if k not in PAPER_INTERVALS]
    if unknown:
        raise ValueError(f"not a learnable parameter: {', '.join(unknown)}")
    return Task(name or params[0], tuple(params))


PLY_COUNT = Task("n", ("n",), PLY_COUNTS)
THICKNESS = Task("thickness", ("thickness",), THICKNESSES)
FLYAWAYS = regression(*FLYAWAY, name="flyaways")
RAW = regression(*RAW_PARAMS, name="raw")

#: The paper's best: one net per raw-yarn parameter plus the flyaway net.
ENSEMBLE_TASKS = (PLY_COUNT, THICKNESS, *(regression(k) for k in RAW_CONTINUOUS), FLYAWAYS)
#: The paper's alternatives: one net for all raw-yarn parameters plus the flyaway net.
REG_TASKS = (RAW, FLYAWAYS)
TASKS = {t.name: t for t in (*ENSEMBLE_TASKS, *REG_TASKS)}
