"""Synthetic samples shared by the SH tests: hemisphere directions and lobe filters."""

from __future__ import annotations

import numpy as np

from freqbrdf import sh


def upper_hemisphere(n: int) -> np.ndarray:
    """Fibonacci points on the local upper hemisphere (z = normal), (n, 3)."""
    p = sh.fibonacci_hemisphere(n)  # about +Y
    return np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=-1)


def random_unit(shape: tuple[int, ...], rng: np.random.Generator) -> np.ndarray:
    d = rng.normal(size=shape + (3,))
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def filter_coeffs(coeffs: np.ndarray, alpha: float) -> np.ndarray:
    """Specular-lobe filter exp(-(alpha l)^2) on a (n_coeffs, ...) coefficient array."""
    lmax = round(np.sqrt(coeffs.shape[0])) - 1
    f = np.exp(-((alpha * sh.sh_degrees(lmax)) ** 2))
    return coeffs * f.reshape((-1,) + (1,) * (coeffs.ndim - 1))
