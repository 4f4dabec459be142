"""The one place where ipm chooses Mitsuba's variant (and the libLLVM that drives it).

``llvm_ad_rgb`` (CPU, vectorised, multi-threaded) is the default; ``cuda_ad_rgb`` when asked
(``variant=`` or the ``IPM_VARIANT`` environment variable); ``scalar_rgb`` is the fallback,
with a warning, where no usable libLLVM exists.  Dr.Jit reads ``DRJIT_LIBLLVM_PATH`` when it
is imported, so the path is settled here before mitsuba is imported: LLVM 15 aborts the
process on the first real render (``Cannot select: fminimum``) and 14 is refused, hence the
search for LLVM >= 16 on the usual Debian/Ubuntu paths.
"""

from __future__ import annotations

import glob
import os
import re
import sys
import warnings
from pathlib import Path
from types import ModuleType

from ipm.errors import UserError

DEFAULT_VARIANT = "llvm_ad_rgb"
VARIANTS = ("llvm_ad_rgb", "cuda_ad_rgb", "scalar_rgb")
MIN_LLVM_MAJOR = 16
LLVM_GLOBS = (
    "/usr/lib/*-linux-gnu/libLLVM.so.*", "/usr/lib/*-linux-gnu/libLLVM-*.so*",
    "/usr/lib/llvm-*/lib/libLLVM.so*", "/usr/lib/llvm-*/lib/libLLVM-*.so*",
    "/usr/local/lib/libLLVM*.so*", "/opt/homebrew/opt/llvm/lib/libLLVM.dylib",
    "/usr/local/opt/llvm/lib/libLLVM.dylib",
)
ENV_LLVM = "DRJIT_LIBLLVM_PATH"
ENV_VARIANT = "IPM_VARIANT"


def llvm_major(path: str | os.PathLike) -> int | None:
    """The LLVM major version in a library's file or folder name (``libLLVM.so.19.1``,
    ``libLLVM-15.so``, ``llvm-14/lib/libLLVM.so``), or None if the name does not tell."""
    m = re.search(r"libLLVM(?:\.so\.|-)(\d+)", str(path)) or re.search(r"llvm-(\d+)/", str(path))
    return int(m.group(1)) if m else None


def find_libllvm() -> Path | None:
    """The newest libLLVM >= 16 on the usual paths, or None."""
    found = [(llvm_major(p), p) for pattern in LLVM_GLOBS for p in glob.glob(pattern)]
    usable = sorted((v, p) for v, p in found if v is not None and v >= MIN_LLVM_MAJOR)
    return Path(usable[-1][1]) if usable else None


def configure_libllvm() -> Path | None:
    """Point ``DRJIT_LIBLLVM_PATH`` at a usable libLLVM unless the user set a usable one;
    returns the library in effect (None: none usable).  Must run before drjit is imported."""
    current = os.environ.get(ENV_LLVM)
    if current and Path(current).exists() and (llvm_major(current) or MIN_LLVM_MAJOR) >= 16:
        return Path(current)
    lib = find_libllvm()
    if "drjit" in sys.modules:  # too late to change the library; report what is in effect
        return Path(current) if current else lib
    if lib is not None:
        os.environ[ENV_LLVM] = str(lib)
    return lib


def requested_variant(variant: str | None = None) -> str:
    name = variant or os.environ.get(ENV_VARIANT) or DEFAULT_VARIANT
    if name not in VARIANTS:
        raise UserError(f"unknown Mitsuba variant {name!r}; choose one of: {', '.join(VARIANTS)}")
    return name


def mitsuba(variant: str | None = None) -> ModuleType:
    """Import mitsuba with the chosen variant set and return the module.

    The first call in a process decides; later calls with another variant switch Mitsuba
    (kernels are cached per variant).  Raises :class:`UserError` for an unknown variant or
    one that cannot run here.
    """
    name = requested_variant(variant)
    lib = configure_libllvm()
    if name == "llvm_ad_rgb" and lib is None:
        warnings.warn(f"no libLLVM >= {MIN_LLVM_MAJOR} found (install e.g. Debian's libllvm19 "
                      f"or set {ENV_LLVM}); falling back to the slow scalar_rgb variant",
                      RuntimeWarning, stacklevel=2)
        name = "scalar_rgb"
    import mitsuba as mi

    if mi.variant() != name:
        try:
            mi.set_variant(name)
        except (ImportError, AttributeError, RuntimeError) as e:
            raise UserError(f"Mitsuba variant {name} is not available here: "
                            f"{str(e).splitlines()[0] if str(e) else type(e).__name__}") from None
    if name == "cuda_ad_rgb":
        import drjit as dr

        if not dr.has_backend(dr.JitBackend.CUDA):
            raise UserError("Mitsuba variant cuda_ad_rgb needs a CUDA GPU and driver; "
                            "none found (use llvm_ad_rgb)")
    return mi
