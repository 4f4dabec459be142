"""ipm: neural inverse procedural modeling of knitting yarns from images.

The core package (this folder) holds the yarn model and has no heavy imports:
:class:`~ipm.params.YarnParams`, the guided prior, the hierarchical fiber generator and the
fiber export.  ``ipm.render`` (Mitsuba), ``ipm.nets`` (torch) and ``ipm.refine`` (kornia,
NLopt) build on it.
"""

from ipm.fibers import FiberKind, FiberSet
from ipm.generator import generate
from ipm.params import PARAM_ORDER, YarnParams
from ipm.presets import PRESET_NAMES, preset
from ipm.prior import GuidedPrior

__all__ = ["FiberKind", "FiberSet", "GuidedPrior", "PARAM_ORDER", "PRESET_NAMES", "YarnParams",
           "generate", "preset"]
__version__ = "0.1.0"
