"""What rendering and training need on this machine, and how to fix what is missing.

Each Mitsuba variant is probed by rendering a tiny yarn in a child process: a bad libLLVM
aborts the process that loads it, and a probe must not take ``ipm doctor`` down with it.
"""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import dataclass

from ipm.render.variant import ENV_LLVM, MIN_LLVM_MAJOR, VARIANTS, find_libllvm, llvm_major

_PROBE = """
import warnings, numpy as np
warnings.simplefilter("error")
from ipm.presets import preset
from ipm.render.renderer import Renderer
img = Renderer({variant!r}).render(preset("grey_thin"), 0, scale=0.05, spp=1)
assert np.isfinite(img).all() and img.max() > 0
"""


@dataclass(frozen=True)
class Check:
    name: str
    ok: bool
    detail: str
    fix: str = ""
    required: bool = True


def probe_variant(variant: str, timeout_s: float = 120.0) -> Check:
    """Render a 100 x 30 px yarn with ``variant`` in a child process."""
    try:
        r = subprocess.run([sys.executable, "-c", _PROBE.format(variant=variant)],
                           capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return Check(f"variant {variant}", False, f"no image in {timeout_s:.0f} s")
    if r.returncode == 0:
        return Check(f"variant {variant}", True, "renders")
    last = (r.stderr.strip().splitlines() or [f"exit status {r.returncode}"])[-1]
    last = last.removeprefix("ipm.errors.UserError: ")
    fix = {"llvm_ad_rgb": f"install libLLVM >= {MIN_LLVM_MAJOR} (Debian/Ubuntu: apt-get install "
                          f"libllvm19) or point {ENV_LLVM} at it",
           "cuda_ad_rgb": "needs an NVIDIA GPU and driver; the CPU variant works without",
           "scalar_rgb": "reinstall mitsuba (pip install -e .)"}[variant]
    return Check(f"variant {variant}", False, last[:160], fix, required=variant != "cuda_ad_rgb")


def libllvm_check() -> Check:
    current = os.environ.get(ENV_LLVM)
    lib = find_libllvm()
    if current:
        major = llvm_major(current)
        ok = os.path.exists(current) and (major is None or major >= MIN_LLVM_MAJOR)
        return Check("libLLVM", ok, f"{ENV_LLVM}={current}",
                     "" if ok else f"unset {ENV_LLVM} or point it at libLLVM >= "
                                   f"{MIN_LLVM_MAJOR}" + (f" (found {lib})" if lib else ""))
    if lib:
        return Check("libLLVM", True, f"{lib} (LLVM {llvm_major(lib)}; ipm sets {ENV_LLVM})")
    return Check("libLLVM", False, f"no libLLVM >= {MIN_LLVM_MAJOR} found",
                 "apt-get install libllvm19 (or set DRJIT_LIBLLVM_PATH); until then ipm renders "
                 "with the slow scalar_rgb variant")


def torch_check() -> Check:
    try:
        import torch
    except ImportError:
        return Check("torch", False, "not installed", "pip install -e .")
    device = "cuda (" + torch.cuda.get_device_name(0) + ")" if torch.cuda.is_available() else "cpu"
    return Check("torch", True, f"{torch.__version__}, device {device}, "
                                f"{torch.get_num_threads()} threads")


def checks(variants: tuple[str, ...] = VARIANTS) -> list[Check]:
    cores = os.cpu_count() or 1
    return [Check("cpu", True, f"{cores} cores (ipm generate uses all of them)"),
            libllvm_check(), *(probe_variant(v) for v in variants), torch_check()]
