"""Colour: luminance of linear RGB, the sRGB transfer function and tone mapping."""

from __future__ import annotations

import numpy as np

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 weights of linear RGB


def to_srgb(linear: np.ndarray) -> np.ndarray:
    """sRGB transfer curve of linear values clipped to [0, 1].

    Parameters
    ----------
    linear : ndarray
        Linear radiance or reflectance, any shape.

    Returns
    -------
    ndarray
        Display values in [0, 1], same shape.
    """
    x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def tonemap(hdr: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Display an HDR image: exposure, extended Reinhard (white point 4), then sRGB.

    Parameters
    ----------
    hdr : ndarray, shape (..., 3)
        Linear radiance.
    exposure : float
        Multiplier applied before the curve.

    Returns
    -------
    ndarray, same shape, values in [0, 1]
    """
    x = np.maximum(np.asarray(hdr, dtype=np.float64) * exposure, 0.0)
    # Extended Reinhard keeps mid-tones almost linear and maps 4.0 to white,
    # so highlights of sunny captures stay readable in previews.
    return to_srgb(x * (1.0 + x / 16.0) / (1.0 + x))
