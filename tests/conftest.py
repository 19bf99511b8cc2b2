"""Shared fixtures. Mitsuba's variant is set once per session, here, never at import."""

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def mi():
    from freqbrdf.util.mitsuba_setup import setup_mitsuba

    return setup_mitsuba("llvm_ad_rgb", threads=2)


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO
