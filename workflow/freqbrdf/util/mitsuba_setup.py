"""Choose Mitsuba's variant (CPU or GPU), locate a usable LLVM and initialise Mitsuba.

Mitsuba's ``llvm_*`` variants JIT-compile kernels through ``libLLVM``. Dr.Jit
needs LLVM >= 17; the LLVM 15 that Debian may ship crashes at the first kernel
compile, so the project never relies on the system library. The PyPI wheel
``karellen-llvm-core`` (a pinned dependency) ships a recent one, and we point
``DRJIT_LIBLLVM_PATH`` at it before Mitsuba is imported.
"""

from __future__ import annotations

import ctypes
import importlib.metadata
import os
import re
from pathlib import Path
from types import ModuleType

VARIANTS = ("auto", "llvm_ad_rgb", "cuda_ad_rgb")
"""Values of config ``mitsuba.variant``: ``auto`` takes the GPU where a CUDA device and driver work."""
MIN_LLVM_MAJOR = 17
LLVM_PACKAGE = "karellen-llvm-core"
_HOW_TO_FIX = (
    f"install it with `pip install {LLVM_PACKAGE}` (the project's `make run` does), "
    "or set DRJIT_LIBLLVM_PATH to a libLLVM.so of version >= "
    f"{MIN_LLVM_MAJOR}"
)


class LLVMNotFoundError(RuntimeError):
    """No libLLVM >= 17 could be found for Mitsuba's CPU backend."""


def llvm_major_version(path: Path) -> int | None:
    """LLVM major version read from a library file name, e.g. ``libLLVM.so.23.1`` -> 23.

    Parameters
    ----------
    path : Path
        Path to a ``libLLVM`` shared library (symlinks are resolved).

    Returns
    -------
    int or None
        The major version, or None when the name does not carry one.
    """
    for name in (Path(os.path.realpath(path)).name, Path(path).name):
        match = re.search(r"libLLVM(?:-(\d+))?\.so(?:\.(\d+))?", name)
        if match and (match.group(1) or match.group(2)):
            return int(match.group(1) or match.group(2))
    return None


def find_llvm() -> Path:
    """Path of a ``libLLVM`` shared library with version >= 17.

    ``DRJIT_LIBLLVM_PATH`` wins if it is set; otherwise the library shipped by
    the ``karellen-llvm-core`` wheel is used.

    Raises
    ------
    LLVMNotFoundError
        With a message that says how to get a usable LLVM.
    """
    explicit = os.environ.get("DRJIT_LIBLLVM_PATH")
    if explicit:
        path = Path(explicit)
        if not path.is_file():
            raise LLVMNotFoundError(f"DRJIT_LIBLLVM_PATH={explicit} is not a file; {_HOW_TO_FIX}")
        major = llvm_major_version(path)
        if major is not None and major < MIN_LLVM_MAJOR:
            raise LLVMNotFoundError(
                f"DRJIT_LIBLLVM_PATH={explicit} is LLVM {major}, which crashes Dr.Jit; {_HOW_TO_FIX}"
            )
        return path
    try:
        files = importlib.metadata.files(LLVM_PACKAGE) or []
    except importlib.metadata.PackageNotFoundError:
        raise LLVMNotFoundError(f"no usable LLVM: package {LLVM_PACKAGE} is not installed; {_HOW_TO_FIX}") from None
    candidates = sorted(
        (Path(f.locate()).resolve() for f in files if re.fullmatch(r"libLLVM(-\d+)?\.so(\.[\d.]+)?", f.name)),
        key=lambda p: -(llvm_major_version(p) or 0),
    )
    for path in candidates:
        if path.is_file() and (llvm_major_version(path) or 0) >= MIN_LLVM_MAJOR:
            return path
    raise LLVMNotFoundError(f"no libLLVM >= {MIN_LLVM_MAJOR} found in package {LLVM_PACKAGE}; {_HOW_TO_FIX}")


def setup_mitsuba(variant: str = "llvm_ad_rgb", threads: int | None = None) -> ModuleType:
    """Point Dr.Jit at a usable LLVM, import Mitsuba and select ``variant``.

    Call this once, from an entry script, before any other use of Mitsuba.

    Parameters
    ----------
    variant : {"auto", "llvm_ad_rgb", "cuda_ad_rgb"}
        Mitsuba variant (`resolve_variant`); the CPU variant ``llvm_ad_rgb`` by default.
    threads : int, optional
        Worker threads for Dr.Jit's thread pool (e.g. Snakemake's ``threads``).

    Returns
    -------
    module
        The imported ``mitsuba`` module with the variant set.
    """
    variant = resolve_variant(variant)
    if variant.startswith("llvm"):
        os.environ["DRJIT_LIBLLVM_PATH"] = str(find_llvm())
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(variant)
    if threads is not None:
        dr.set_thread_count(int(threads))
    return mi


def cuda_devices() -> int:
    """Number of CUDA devices the driver reports; 0 without a working driver (``libcuda``)."""
    try:
        cuda = ctypes.CDLL("libcuda.so.1")
    except OSError:
        return 0
    count = ctypes.c_int(0)
    if cuda.cuInit(0) != 0 or cuda.cuDeviceGetCount(ctypes.byref(count)) != 0:
        return 0
    return int(count.value)


def resolve_variant(requested: str, devices: int | None = None) -> str:
    """The Mitsuba variant to run: ``requested``, or for ``auto`` the GPU one where a CUDA device works.

    Parameters
    ----------
    requested : {"auto", "llvm_ad_rgb", "cuda_ad_rgb"}
        Config ``mitsuba.variant``.
    devices : int, optional
        CUDA devices available (default: ask the driver, `cuda_devices`).

    Raises
    ------
    ValueError
        Naming the config key, for an unknown variant or ``cuda_ad_rgb`` without a CUDA device.
    """
    if requested not in VARIANTS:
        raise ValueError(f"config key mitsuba.variant: {requested!r} is not one of {VARIANTS}")
    if requested == "llvm_ad_rgb":
        return requested
    devices = cuda_devices() if devices is None else devices
    if requested == "cuda_ad_rgb" and devices == 0:
        raise ValueError("config key mitsuba.variant: cuda_ad_rgb needs a CUDA device and driver (libcuda), "
                         "and none works on this machine; use auto or llvm_ad_rgb")
    return "cuda_ad_rgb" if devices > 0 else "llvm_ad_rgb"


def planned_variant(requested: str) -> str:
    """The variant a run plans for: ``auto`` resolved on this machine, an explicit one as given.

    Unlike `resolve_variant` it accepts ``cuda_ad_rgb`` on a machine without a GPU, where a run is
    planned for GPU nodes (a cluster's head node); the jobs check the device where they run.
    """
    if requested not in VARIANTS:
        raise ValueError(f"config key mitsuba.variant: {requested!r} is not one of {VARIANTS}")
    return resolve_variant(requested) if requested == "auto" else requested


def timing_note(variant: str) -> str:
    """Where a run's times were taken, as its tables and figures say it, e.g.
    ``jobs of at most 2 CPU threads, Mitsuba on the GPU (cuda_ad_rgb)``.

    The 2 threads are what the rules declare (``threads: 2``); Snakemake gives fewer under ``--cores 1``.
    """
    where = "the GPU" if variant.startswith("cuda") else "the CPU"
    return f"jobs of at most 2 CPU threads, Mitsuba on {where} ({variant})"
