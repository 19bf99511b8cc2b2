"""Directions on the sphere: the equirectangular pixel grid with its quadrature weights, and Fibonacci point sets.

Directions are unit vectors in the Y-up frame of :mod:`freqbrdf.sphere.sh`::

    d = (sin(theta) sin(phi), cos(theta), -sin(theta) cos(phi))

Equirectangular maps
    Matches the Mitsuba 3 envmap lookup (measured): an ``(H, W)`` image has
    row ``i`` at polar angle ``theta_i = pi * i / (H - 1)`` (row 0 is exactly
    the +Y pole, row ``H - 1`` exactly the -Y pole) and column ``j`` at
    azimuth ``phi_j = 2 pi (j + 0.5) / W`` (this lies in (0, 2 pi); it is the
    same direction as the wrapped angle in (-pi, pi]).  The pixel grid is
    thus a trapezoidal-rule grid in theta: a pixel of row ``i`` covers the
    band ``theta in [theta_i - dtheta/2, theta_i + dtheta/2]`` clipped to
    ``[0, pi]``, with ``dtheta = pi / (H - 1)``, and an azimuthal width
    ``2 pi / W``.  Its exact solid angle is
    ``2 pi / W * (cos(a) - cos(b))``; the map sums to exactly ``4 pi``.

All functions are pure (no global mutable state) and return float64 arrays.
"""

from __future__ import annotations

import numpy as np

from freqbrdf.util.validation import check_int

__all__ = [
    "check_grid",
    "row_cos_sin",
    "equirect_directions",
    "equirect_solid_angles",
    "fibonacci_sphere",
    "fibonacci_hemisphere",
]


# --------------------------------------------------------------------------
# equirectangular grid
# --------------------------------------------------------------------------
def check_grid(height: int, width: int) -> tuple[int, int]:
    """``(height, width)`` of an equirectangular map, checked: ``H >= 2``, ``W >= 1``."""
    height = check_int(height, "height", 2)
    width = check_int(width, "width", 1)
    return height, width


def row_cos_sin(height: int) -> tuple[np.ndarray, np.ndarray]:
    """cos/sin of theta_i = pi i / (H-1), exactly symmetric about the equator."""
    i = np.arange(height)
    k = np.minimum(i, height - 1 - i)
    ang = np.pi * k / (height - 1)
    sign = np.where(i <= (height - 1) - i, 1.0, -1.0)
    return sign * np.cos(ang), np.sin(ang)


def equirect_directions(height: int, width: int) -> np.ndarray:
    """Pixel-centre directions of an equirectangular map (Mitsuba layout).

    Parameters
    ----------
    height, width : int
        Map size ``H >= 2``, ``W >= 1``.

    Returns
    -------
    numpy.ndarray
        Shape ``(H, W, 3)``; pixel ``(i, j)`` is at ``theta_i = pi i / (H-1)``,
        ``phi_j = 2 pi (j + 0.5) / W``.  Row 0 is exactly ``(0, 1, 0)`` and row
        ``H-1`` exactly ``(0, -1, 0)``.
    """
    height, width = check_grid(height, width)
    ct, st = row_cos_sin(height)
    phi = 2.0 * np.pi * (np.arange(width) + 0.5) / width
    out = np.empty((height, width, 3))
    out[..., 0] = st[:, None] * np.sin(phi)[None, :]
    out[..., 1] = ct[:, None]
    out[..., 2] = -st[:, None] * np.cos(phi)[None, :]
    return out


def equirect_solid_angles(height: int, width: int) -> np.ndarray:
    """Solid angle of one pixel in each row of an equirectangular map.

    Parameters
    ----------
    height, width : int
        Map size ``H >= 2``, ``W >= 1``.

    Returns
    -------
    numpy.ndarray
        Shape ``(H,)`` in sr: ``2 pi / W * (cos a_i - cos b_i)`` with
        ``[a_i, b_i] = [theta_i - dtheta/2, theta_i + dtheta/2]`` clipped to
        ``[0, pi]``, ``dtheta = pi / (H-1)``.  ``W * sum`` equals ``4 pi``.
    """
    height, width = check_grid(height, width)
    # band edges theta_e = pi (e - 1/2) / (H - 1), e = 0..H, clipped to [0, pi];
    # cos computed symmetrically so the edge list is exactly antisymmetric.
    e = np.arange(height + 1)
    twice = np.clip(2 * e - 1, 0, 2 * (height - 1))  # 2 (H-1) theta_e / pi
    k = np.minimum(twice, 2 * (height - 1) - twice)
    sign = np.where(twice <= 2 * (height - 1) - twice, 1.0, -1.0)
    cos_edges = sign * np.cos(np.pi * k / (2.0 * (height - 1)))
    return (2.0 * np.pi / width) * (cos_edges[:-1] - cos_edges[1:])

# --------------------------------------------------------------------------
# Fibonacci point sets
# --------------------------------------------------------------------------
_GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))


def _spiral(y: np.ndarray) -> np.ndarray:
    k = np.arange(y.shape[0])
    phi = _GOLDEN_ANGLE * k
    r = np.sqrt(np.clip(1.0 - y * y, 0.0, None))
    return np.stack([r * np.sin(phi), y, -r * np.cos(phi)], axis=-1)


def fibonacci_sphere(n: int) -> np.ndarray:
    """Nearly uniform points on the unit sphere (golden-angle spiral).

    Parameters
    ----------
    n : int
        Number of points, ``>= 1``.

    Returns
    -------
    numpy.ndarray
        Shape ``(n, 3)`` unit vectors; ``y_k = 1 - (2k + 1)/n`` (equal-area
        latitude bands), azimuth advancing by the golden angle.
    """
    n = check_int(n, "n", 1)
    y = 1.0 - (2.0 * np.arange(n) + 1.0) / n
    return _spiral(y)


def fibonacci_hemisphere(n: int) -> np.ndarray:
    """Nearly uniform points on the upper (+Y) unit hemisphere.

    Parameters
    ----------
    n : int
        Number of points, ``>= 1``.

    Returns
    -------
    numpy.ndarray
        Shape ``(n, 3)`` unit vectors with ``y_k = 1 - (k + 0.5)/n`` in
        ``(0, 1)`` (equal-area bands, so ``y > 0`` and mean ``y = 1/2``).
    """
    n = check_int(n, "n", 1)
    y = 1.0 - (np.arange(n) + 0.5) / n
    return _spiral(y)
