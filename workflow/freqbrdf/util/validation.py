"""Checks of arguments at the library's boundary, shared by every module.

Each raises with a one-line message that names the argument and the bad value.
"""

from __future__ import annotations

import numpy as np


def check_int(value: object, name: str, minimum: int) -> int:
    """``value`` as an int, at least ``minimum`` (bools are refused)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an int, got {type(value).__name__} {value!r}")
    if int(value) < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value}")
    return int(value)


def check_positive(value: float, name: str) -> float:
    """``value`` as a finite float > 0."""
    value = float(value)
    if not (np.isfinite(value) and value > 0.0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return value


def check_choice(value: str, name: str, choices: tuple[str, ...]) -> str:
    """``value`` if it is one of ``choices``."""
    if value not in choices:
        raise ValueError(f"{name} must be one of {choices}, got {value!r}")
    return value


def check_shape(a: np.ndarray, name: str, shape: tuple[int | None, ...]) -> None:
    """Check ``a.shape`` against ``shape``, whose None entries match any size."""
    if a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape)):
        want = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name} must have shape {want}, got shape {a.shape}")


def check_finite(a: np.ndarray, name: str) -> None:
    """Check that every value of ``a`` is finite, naming the first that is not."""
    if not np.all(np.isfinite(a)):
        idx = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
        raise ValueError(f"{name} must be finite, got {float(a[idx])!r} at index {idx}")


def lmax_of(n: int, name: str) -> int:
    """The SH degree lmax of ``n = (lmax + 1)**2`` coefficients."""
    lmax = int(round(np.sqrt(n))) - 1
    if n < 1 or (lmax + 1) ** 2 != n:
        raise ValueError(f"{name} has {n} coefficients, which is not (lmax + 1)**2 for any lmax >= 0")
    return lmax
