"""Inference: an ensemble of trained nets -> :class:`~ipm.params.YarnParams` from a
:class:`~ipm.photo.Photo` (``Ensemble.load().predict(Photo.read("yarn.png", 0.01))``).

Each net sees the photo at its own pixel pitch (``PIXEL_SIZE_MM / input_scale``); its
outputs are averaged over a few crops evenly spaced along the yarn (class probabilities for
``n`` and the thickness class).  Where two nets read a parameter (a multi-task ``raw`` net
beside the per-parameter ones), the one with the lower validation error gives it
(:meth:`Ensemble.deciders`).  Parameters no net decides (fiber colour, the fourth
hierarchy level) keep :class:`YarnParams`' defaults.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np
import torch

from ipm import frame
from ipm.errors import UserError
from ipm.frame import PIXEL_SIZE_MM, pitch_factor
from ipm.nets.data import centre_crops
from ipm.nets.model import YarnNet
from ipm.nets.store import ENSEMBLE, load_net, read_json
from ipm.params import PARAM_ORDER, YarnParams
from ipm.photo import Photo
from ipm.setups import DEFAULT_SETUP, SETUPS, setup_of

#: The shipped nets of each capture setup (:attr:`ipm.setups.CaptureSetup.models`).
SHIPPED_FOR = {name: Path(__file__).parent / s.models for name, s in SETUPS.items()}
#: Default models: those of the default setup.
SHIPPED = SHIPPED_FOR[DEFAULT_SETUP]
#: How much a net's input may be upsampled from the photo before a finer net is not used.
MAX_UPSAMPLING = 1.25


@dataclass
class Ensemble:
    """Trained nets that together decide every parameter of :data:`PARAM_ORDER`, for the
    photos of one capture ``setup`` (the setup of their training renders)."""

    nets: dict[str, YarnNet]
    info: dict[str, dict]
    folder: Path
    setup: str = DEFAULT_SETUP
    #: False: the nets read a photo's card as it shows (:meth:`Photo.scene_view` brings it to
    #: the scene's); what benchmarks/card_sweep.py compares with.
    card_normalised: bool = True

    @classmethod
    def load(cls, folder: str | Path | None = None, device: str = "cpu",
             setup: str | None = None) -> Ensemble:
        """Load the nets listed in ``folder/ensemble.json`` (default: those shipped for
        ``setup``, the default setup's if None); with ``setup`` given, nets trained on another
        setup's renders are refused (they read such photos wrongly)."""
        name = setup_of(setup or DEFAULT_SETUP).name
        shipped = SHIPPED_FOR[name]
        folder = Path(folder) if folder is not None else shipped
        if not (folder / ENSEMBLE).is_file():
            hint = (f"no {name} models are shipped in this build of ipm yet; "
                    f"train them with `ipm train --setup {name} --data DIR --val "
                    "DIR --out runs/x` and pass --models runs/x" if folder == shipped else
                    "train with `ipm train ... --out DIR`")
            raise UserError(f"{folder} holds no trained models ({ENSEMBLE} missing); {hint}")
        manifest = read_json(folder / ENSEMBLE)
        names = manifest.get("nets") if isinstance(manifest, dict) else None
        if not isinstance(names, list) or not names:
            raise UserError(f"{folder / ENSEMBLE} lists no nets")
        nets, info = {}, {}
        for name in names:
            nets[name], info[name] = load_net(folder / str(name), device)
        decided = {k for net in nets.values() for k in net.config.spec.decides}
        missing = [k for k in PARAM_ORDER if k not in decided]
        if missing:
            raise UserError(f"the models in {folder} do not predict {', '.join(missing)} "
                            "(an unfinished run? train the remaining nets)")
        trained_on = str(manifest.get("setup", DEFAULT_SETUP))
        if setup is not None and setup != trained_on:
            raise UserError(f"the models in {folder} were trained on {trained_on} renders, "
                            f"not {setup}: give --models of {setup} nets")
        return cls(nets, info, folder, trained_on)

    def chosen(self, pixel_size_mm: float = PIXEL_SIZE_MM) -> dict[str, YarnNet]:
        """The nets that predict for a photo of ``pixel_size_mm``.  Where several nets decide
        the same parameters at different input scales (e.g. ``m`` at 0.04 and ``m-0.5`` at
        0.02 mm per pixel), the finest one the photo supplies without upsampling by more
        than :data:`MAX_UPSAMPLING`, else the coarsest: an upsampled photo is blurred, off
        the net's training data (a 0.02 mm ``m`` net on 0.04 mm renders is worse than
        predicting the mean, ``nets/models/README.md``)."""
        groups: dict[tuple[str, ...], list[str]] = {}
        for name, net in self.nets.items():
            groups.setdefault(net.config.spec.decides, []).append(name)

        def upsampling(name: str) -> float:
            return pitch_factor(pixel_size_mm, self.nets[name].config.input_scale)

        keep = set()
        for names in groups.values():
            fine = [n for n in names if upsampling(n) <= MAX_UPSAMPLING]
            keep.add(max(fine, key=upsampling) if fine else min(names, key=upsampling))
        return {name: net for name, net in self.nets.items() if name in keep}

    def _val_mae(self, name: str, param: str) -> float | None:
        mae = self.info[name].get("val", {}).get("mae", {}).get(param)
        return None if mae is None else float(mae)

    def deciders(self, pixel_size_mm: float = PIXEL_SIZE_MM) -> dict[str, str]:
        """``{parameter: net}``: which of the nets :meth:`chosen` for this pixel size gives
        each parameter.  A classification net decides its class (``n``, the thickness);
        where several regressions read a parameter (a multi-task ``raw`` net beside the
        per-parameter nets), the one with the lowest validation MAE on it, which the
        validation set, not a test set, decides; a net with no stored MAE comes last, and
        ties go to the first in the ensemble's order."""
        nets = self.chosen(pixel_size_mm)

        def rank(name: str, k: str) -> tuple[int, float]:
            if nets[name].config.spec.is_classification:
                return 0, 0.0
            mae = self._val_mae(name, k)
            return (1, mae) if mae is not None else (2, 0.0)

        out = {}
        for k in PARAM_ORDER:
            names = [n for n, net in nets.items() if k in net.config.spec.decides]
            if names:
                out[k] = min(names, key=lambda n, k=k: rank(n, k))
        return out

    def sigma(self, pixel_size_mm: float = PIXEL_SIZE_MM) -> dict[str, float]:
        """The error per continuous parameter of the nets that decide it for this pixel size
        (:meth:`deciders`), as a Gaussian standard deviation: the validation MAE each net
        stored with its best epoch, times sqrt(pi / 2) (for a Gaussian error, MAE = sigma
        sqrt(2 / pi)).  The refinement's prior (:func:`ipm.refine.search.search`)."""
        out = {}
        for k, name in self.deciders(pixel_size_mm).items():
            mae = self._val_mae(name, k)
            if mae is not None:
                out[k] = mae * float(np.sqrt(np.pi / 2))
        return out

    def mean_prediction(self, pixel_size_mm: float = PIXEL_SIZE_MM) -> dict[str, float]:
        """The predict-the-mean baseline for this pixel size: for each parameter, the mean
        training label of the net that decides it (:meth:`deciders`), decoded."""
        nets = self.chosen(pixel_size_mm)
        decoded = {name: net.config.spec.decode(np.asarray(self.info[name]["train_mean"]))
                   for name, net in nets.items()}
        return {k: decoded[name][k] for k, name in self.deciders(pixel_size_mm).items()}

    def upsampling_warning(self, pixel_size_mm: float) -> str | None:
        """A warning naming the nets (of those :meth:`chosen`) whose input pixels are finer
        than the photo's by more than :data:`MAX_UPSAMPLING`: they see an upsampled, blurred
        photo, off their training data, and their parameters are less reliable."""
        nets = self.chosen(pixel_size_mm)
        coarse = sorted(name for name, net in nets.items()
                        if pitch_factor(pixel_size_mm, net.config.input_scale) > MAX_UPSAMPLING)
        if not coarse:
            return None
        finest = min(frame.pixel_size_mm(nets[n].config.input_scale) for n in coarse)
        return (f"the photo's pixels ({pixel_size_mm:g} mm) are coarser than the "
                f"{', '.join(coarse)} net{'s' if len(coarse) > 1 else ''} need "
                f"({finest:g} mm): upsampled, so these parameters are less reliable")

    @torch.no_grad()
    def outputs(self, photo: Photo, crops: int = 3, names: tuple[str, ...] | None = None
                ) -> dict[str, np.ndarray]:
        """Each net's output ``(K,)`` for ``photo``, averaged over ``crops`` crops (only the
        nets ``names``, when given)."""
        if photo.image.ndim != 3 or photo.image.shape[2] != 3:
            raise ValueError(f"expected an (H, W, 3) image, got shape {photo.image.shape}")
        if photo.setup != self.setup:
            raise UserError(f"{photo.name} is a {photo.setup} photo; the nets "
                            f"in {self.folder} read {self.setup} ones")
        scaled: dict[float, np.ndarray] = {}
        result = {}
        for name, net in self.chosen(photo.pixel_size_mm).items():
            if names is not None and name not in names:
                continue
            s = net.config.input_scale
            if s not in scaled:
                scaled[s] = (photo.scene_view if self.card_normalised else photo.at_pitch)(
                    s, net.config.crop)
            x = centre_crops(scaled[s], net.config.crop, crops)
            device = next(net.parameters()).device
            result[name] = net.predict(x.to(device)).mean(0).cpu().numpy()
        return result

    def readings(self, image_srgb: np.ndarray, pixel_size_mm: float, crops: int = 3,
                 names: tuple[str, ...] | None = None) -> dict[str, torch.Tensor]:
        """What the regression nets read in an sRGB image ``(H, W, 3)`` of ``pixel_size_mm``:
        each one's output (its parameters, normalised to their prior range), averaged over
        ``crops`` crops, as statistics groups ``net_<name>`` ``(1, K)`` float64.  The
        refinement compares them between the photo and each render
        (:class:`ipm.refine.objective.RenderObjective`): a render the nets read as they read
        the photo looks like it to them, whatever bias they have in common.  Why: the
        hand-made statistics do not identify ``r_y`` or ``alpha``, which the nets read.
        ``names``: only these nets (of those :meth:`chosen` for the pixel size)."""
        names = tuple(n for n, net in self.nets.items()
                      if not net.config.spec.is_classification and (names is None or n in names))
        outputs = self.outputs(Photo(image_srgb, pixel_size_mm, self.setup), crops, names)
        return {f"net_{k}": torch.from_numpy(v.astype(np.float64))[None]
                for k, v in outputs.items()}

    def detail_nets(self, pixel_size_mm: float) -> tuple[tuple[str, ...], float]:
        """The regression nets :meth:`chosen` for ``pixel_size_mm`` that read a small window
        (a ``crop_px`` of their own: the detail nets), and their pixel pitch in mm; ``((),
        0.0)`` when the photo's pixels are too coarse for them."""
        names = tuple(n for n, net in self.chosen(pixel_size_mm).items()
                      if net.config.crop_px is not None
                      and not net.config.spec.is_classification)
        if not names:
            return (), 0.0
        return names, frame.pixel_size_mm(self.nets[names[0]].config.input_scale)

    def detail_readings(self, pixel_size_mm: float):
        """``(readings, pitch_mm)``: :meth:`readings` of the :meth:`detail_nets` alone and
        their pitch, for :class:`ipm.refine.objective.Detail`; None when the photo's pixels
        are too coarse for them."""
        names, pitch = self.detail_nets(pixel_size_mm)
        return (partial(self.readings, names=names), pitch) if names else None

    def ply_count_probabilities(self, photo: Photo, crops: int = 3) -> dict[int, float]:
        """The ``n`` net's probability of each ply count for ``photo`` (empty without an
        ``n`` net): the prior of a fit's choice of the count
        (:func:`ipm.refine.measure.choose_ply_count`)."""
        prob = self.outputs(photo, crops, names=("n",)).get("n")
        if prob is None:
            return {}
        classes = self.chosen(photo.pixel_size_mm)["n"].config.spec.classes
        return {int(c): float(q) for c, q in zip(classes, prob, strict=True)}

    def predict(self, photo: Photo, crops: int = 3, base: YarnParams | None = None
                ) -> YarnParams:
        """The inferred parameters of ``photo``; fields no net decides come from ``base``."""
        decoded = {name: self.nets[name].config.spec.decode(out)
                   for name, out in self.outputs(photo, crops).items()}
        values = {k: decoded[name][k]
                  for k, name in self.deciders(photo.pixel_size_mm).items()}
        extra = {} if base is None else {k: v for k, v in base.to_dict().items()
                                         if k not in PARAM_ORDER}
        return YarnParams(**values, **extra)
