"""LLVM discovery for Mitsuba's CPU backend."""

from pathlib import Path

import pytest

from freqbrdf.util import mitsuba_setup
from freqbrdf.util.mitsuba_setup import LLVMNotFoundError, find_llvm, llvm_major_version


@pytest.mark.parametrize(
    "name, major", [("libLLVM.so.23.1", 23), ("libLLVM-15.so", 15), ("libLLVM-17.so.1", 17), ("libLLVM.so", None)]
)
def test_version_from_file_name(name, major):
    assert llvm_major_version(Path("/nonexistent") / name) == major


def test_the_packaged_llvm_is_found_and_recent(monkeypatch):
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    path = find_llvm()
    assert path.is_file() and llvm_major_version(path) >= 17


def test_an_old_or_missing_llvm_is_refused_with_a_fix(monkeypatch, tmp_path):
    old = tmp_path / "libLLVM-15.so"
    old.write_bytes(b"")
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", str(old))
    with pytest.raises(LLVMNotFoundError, match="LLVM 15.*karellen-llvm-core"):
        find_llvm()
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", str(tmp_path / "nope.so"))
    with pytest.raises(LLVMNotFoundError, match="not a file"):
        find_llvm()


def test_missing_package_says_how_to_install(monkeypatch):
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    monkeypatch.setattr(mitsuba_setup, "LLVM_PACKAGE", "no-such-package-freqbrdf")
    with pytest.raises(LLVMNotFoundError, match="pip install"):
        find_llvm()


@pytest.mark.parametrize("requested, devices, expected", [
    ("llvm_ad_rgb", 1, "llvm_ad_rgb"),  # the CPU when asked for, GPU or not
    ("auto", 0, "llvm_ad_rgb"),
    ("auto", 2, "cuda_ad_rgb"),
    ("cuda_ad_rgb", 1, "cuda_ad_rgb"),
])
def test_variant_follows_the_config_and_the_devices(requested, devices, expected):
    assert mitsuba_setup.resolve_variant(requested, devices) == expected


def test_a_gpu_variant_without_a_device_or_an_unknown_one_names_the_key():
    with pytest.raises(ValueError, match="mitsuba.variant: cuda_ad_rgb needs a CUDA device"):
        mitsuba_setup.resolve_variant("cuda_ad_rgb", 0)
    with pytest.raises(ValueError, match="mitsuba.variant: 'scalar_rgb' is not one of"):
        mitsuba_setup.resolve_variant("scalar_rgb")


def test_a_run_plans_for_the_variant_it_names_and_resolves_auto_here():
    """A run planned on a head node without a GPU for GPU nodes keeps cuda_ad_rgb (its jobs check
    the device where they run); auto is this machine's answer."""
    assert mitsuba_setup.planned_variant("cuda_ad_rgb") == "cuda_ad_rgb"
    assert mitsuba_setup.planned_variant("llvm_ad_rgb") == "llvm_ad_rgb"
    assert mitsuba_setup.planned_variant("auto") == mitsuba_setup.resolve_variant("auto")
    with pytest.raises(ValueError, match="mitsuba.variant: 'scalar_rgb' is not one of"):
        mitsuba_setup.planned_variant("scalar_rgb")


def test_auto_asks_the_driver():
    # on a machine without libcuda this is the CPU; with a working GPU, the GPU
    expected = "cuda_ad_rgb" if mitsuba_setup.cuda_devices() > 0 else "llvm_ad_rgb"
    assert mitsuba_setup.resolve_variant("auto") == expected
