"""Real spherical harmonics: evaluation, projection of equirectangular maps, power spectra.

Conventions
-----------
Frame
    Directions are unit vectors ``d = (x, y, z)`` in a right-handed world
    frame whose polar axis is **+Y** (world Y-up).  The spherical angles are::

        theta = arccos(y)            in [0, pi]   (polar angle from +Y)
        phi   = atan2(x, -z)         in (-pi, pi] (azimuth, 0 towards -Z,
                                                   pi/2 towards +X)
        d     = (sin(theta) sin(phi), cos(theta), -sin(theta) cos(phi))

    `directions_to_angles` and `angles_to_directions` implement this mapping.

Real spherical harmonics
    ``Y_lm`` for ``l = 0..lmax`` and ``m = -l..l`` are real and orthonormal on
    the unit sphere (``int Y_i Y_j dOmega = delta_ij``).  They are stored
    l-major with flat index ``i = l*l + l + m``, i.e. ``(lmax + 1)**2``
    coefficients in the order (0,0), (1,-1), (1,0), (1,1), (2,-2), ...
    With ``N_l^m = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!)`` and ``P_l^m`` the
    associated Legendre function **without** the Condon-Shortley phase
    (``P_1^1(t) = +sqrt(1 - t^2)``)::

        m > 0 :  Y_lm = sqrt(2) N_l^m  P_l^m(cos theta) cos(m phi)
        m = 0 :  Y_l0 =         N_l^0  P_l(cos theta)
        m < 0 :  Y_lm = sqrt(2) N_l^|m| P_l^|m|(cos theta) sin(|m| phi)

    so that, e.g., ``Y_00 = 1/sqrt(4 pi)`` and, with ``k = sqrt(3/(4 pi))``,
    ``Y_1,-1 = k x``, ``Y_1,0 = k y``, ``Y_1,1 = -k z``.
    Relation to ``scipy.special.sph_harm_y(l, m, theta, phi)`` (which includes
    the Condon-Shortley phase ``(-1)^m``), for ``m > 0``::

        Y_l,m  = sqrt(2) (-1)^m Re sph_harm_y(l, m, theta, phi)
        Y_l,-m = sqrt(2) (-1)^m Im sph_harm_y(l, m, theta, phi)
        Y_l,0  =                Re sph_harm_y(l, 0, theta, phi)

Equirectangular maps
    The pixel grid and its quadrature weights are those of
    :mod:`freqbrdf.sphere.sampling` (Mitsuba 3's envmap layout).

Units
    Angles are in radians and solid angles in steradians.  Coefficients
    have the units of the projected function (e.g. radiance) times sr.

All functions are pure (no global mutable state) and return float64 arrays.
"""

from __future__ import annotations

from typing import Iterator

import numpy as np

from freqbrdf.sphere.sampling import check_grid, equirect_solid_angles, row_cos_sin
from freqbrdf.util.validation import check_int, lmax_of

__all__ = [
    "sh_index",
    "ring_factors",
    "eval_rings",
    "sh_degrees",
    "n_coeffs",
    "directions_to_angles",
    "angles_to_directions",
    "real_sh",
    "recurrence_tables",
    "eval_sh",
    "project_equirect",
    "equirect_factors",
    "filter_equirect",
    "power_spectrum",
]

_INV_SQRT_4PI = 1.0 / np.sqrt(4.0 * np.pi)
_SQRT2 = np.sqrt(2.0)
# Working-set target (number of float64 values) for one block of the
# (n_coeffs, n_block) evaluation buffer; keeps the recurrences in cache.
_BLOCK_VALUES = 1 << 18


# --------------------------------------------------------------------------
# validation helpers
# --------------------------------------------------------------------------
def _check_directions(directions: np.ndarray, name: str = "directions") -> np.ndarray:
    d = np.asarray(directions, dtype=np.float64)
    if d.ndim < 1 or d.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (..., 3), got shape {d.shape}")
    return d


# --------------------------------------------------------------------------
# indexing
# --------------------------------------------------------------------------
def sh_index(l: int, m: int) -> int:
    """Flat l-major index of ``Y_lm``.

    Parameters
    ----------
    l : int
        Degree, ``l >= 0``.
    m : int
        Order, ``-l <= m <= l``.

    Returns
    -------
    int
        ``l*l + l + m``.
    """
    l = check_int(l, "l", 0)
    if isinstance(m, (bool, np.bool_)) or not isinstance(m, (int, np.integer)):
        raise TypeError(f"m must be an int, got {type(m).__name__} {m!r}")
    m = int(m)
    if abs(m) > l:
        raise ValueError(f"order m={m} out of range for degree l={l} (need |m| <= l)")
    return l * l + l + m


def n_coeffs(lmax: int) -> int:
    """Number of coefficients ``(lmax + 1)**2`` up to degree ``lmax``."""
    lmax = check_int(lmax, "lmax", 0)
    return (lmax + 1) ** 2


def sh_degrees(lmax: int) -> np.ndarray:
    """Degree ``l`` of each flat index.

    Parameters
    ----------
    lmax : int
        Maximum degree, ``>= 0``.

    Returns
    -------
    numpy.ndarray
        Shape ``((lmax+1)**2,)``, int64; entry ``i`` is the degree of index ``i``.
    """
    lmax = check_int(lmax, "lmax", 0)
    return np.repeat(np.arange(lmax + 1, dtype=np.int64), 2 * np.arange(lmax + 1) + 1)


# --------------------------------------------------------------------------
# angles
# --------------------------------------------------------------------------
def directions_to_angles(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Spherical angles of direction vectors (Y-up convention).

    Parameters
    ----------
    d : numpy.ndarray
        Shape ``(..., 3)``; need not be normalised (the norm is divided out).

    Returns
    -------
    theta : numpy.ndarray
        Shape ``(...)``, polar angle from +Y in ``[0, pi]`` (rad).
    phi : numpy.ndarray
        Shape ``(...)``, azimuth ``atan2(x, -z)`` in ``(-pi, pi]`` (rad);
        0 exactly on the polar axis (``x == z == 0``).
    """
    d = _check_directions(d, "d")
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    r = np.sqrt(x * x + y * y + z * z)
    with np.errstate(invalid="ignore", divide="ignore"):
        theta = np.arccos(np.clip(y / r, -1.0, 1.0))
    phi = np.arctan2(x, -z)
    phi = np.where(phi <= -np.pi, np.pi, phi)
    phi = np.where((x == 0) & (z == 0), 0.0, phi)  # poles: define phi = 0
    return theta, phi


def angles_to_directions(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit vectors from spherical angles (Y-up convention).

    Parameters
    ----------
    theta, phi : numpy.ndarray
        Broadcastable arrays of polar angle and azimuth (rad).

    Returns
    -------
    numpy.ndarray
        Shape ``broadcast(theta, phi).shape + (3,)``:
        ``(sin theta sin phi, cos theta, -sin theta cos phi)``.
    """
    theta = np.asarray(theta, dtype=np.float64)
    phi = np.asarray(phi, dtype=np.float64)
    st = np.sin(theta)
    return np.stack(
        np.broadcast_arrays(st * np.sin(phi), np.cos(theta), -st * np.cos(phi)), axis=-1
    )


# --------------------------------------------------------------------------
# core evaluation
# --------------------------------------------------------------------------
def recurrence_tables(lmax: int) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients a_lm, b_lm of the normalised Legendre recurrence.

    ``q_l^m = a_lm (t q_{l-1}^m - b_lm q_{l-2}^m)`` for ``l >= m + 2``, where
    ``q_l^m = N_l^m P_l^m / sin^m(theta)`` is a polynomial in ``t = cos theta``.
    """
    a = np.zeros((lmax + 1, lmax + 1))
    b = np.zeros((lmax + 1, lmax + 1))
    for m in range(lmax + 1):
        for l in range(m + 2, lmax + 1):
            a[l, m] = np.sqrt((4.0 * l * l - 1.0) / (l * l - m * m))
            b[l, m] = np.sqrt(((l - 1.0) ** 2 - m * m) / (4.0 * (l - 1.0) ** 2 - 1.0))
    return a, b


def _sh_block(
    x: np.ndarray,
    y: np.ndarray,
    z: np.ndarray,
    lmax: int,
    a: np.ndarray,
    b: np.ndarray,
    out: np.ndarray,
) -> None:
    """Fill ``out`` (n_coeffs, n) with Y_i at unit vectors given by 1-D x, y, z.

    Uses ``sin^m(theta) e^{i m phi} = (u + i v)^m`` with ``u = -z``, ``v = x``
    (so no trigonometric functions are needed) and the stable three-term
    recurrence in l for the fully normalised Legendre polynomials
    ``q_l^m = N_l^m P_l^m / sin^m``.  The final value for ``m != 0`` is
    ``sqrt(2) q_l^m Re/Im[(u + i v)^m]``.
    """
    t = y
    u = np.negative(z)
    v = x
    tmp = np.empty_like(t)

    # m = 0 column (zonal harmonics)
    out[0].fill(_INV_SQRT_4PI)
    if lmax >= 1:
        np.multiply(t, np.sqrt(3.0) * _INV_SQRT_4PI, out=out[2])
    for l in range(2, lmax + 1):
        r = out[l * l + l]
        np.multiply(t, out[(l - 1) * (l - 1) + (l - 1)], out=r)
        np.multiply(out[(l - 2) * (l - 2) + (l - 2)], b[l, 0], out=tmp)
        r -= tmp
        r *= a[l, 0]
    if lmax == 0:
        return

    c_m = u.copy()  # Re (u + i v)^m
    s_m = v.copy()  # Im (u + i v)^m
    qmm = _INV_SQRT_4PI
    for m in range(1, lmax + 1):
        if m > 1:
            c_new = u * c_m
            np.multiply(v, s_m, out=tmp)
            c_new -= tmp
            s_m *= u
            np.multiply(v, c_m, out=tmp)
            s_m += tmp
            c_m = c_new
        # q_m^m (constant), including the sqrt(2) of the real form
        qmm = qmm * np.sqrt((2.0 * m + 1.0) / (2.0 * m))
        # Store sqrt(2) q_l^m in the +m slots, then split into cos / sin parts.
        out[m * m + 2 * m].fill(_SQRT2 * qmm)
        if m + 1 <= lmax:
            np.multiply(t, _SQRT2 * qmm * np.sqrt(2.0 * m + 3.0), out=out[(m + 1) ** 2 + (m + 1) + m])
        for l in range(m + 2, lmax + 1):
            r = out[l * l + l + m]
            np.multiply(t, out[(l - 1) * (l - 1) + (l - 1) + m], out=r)
            np.multiply(out[(l - 2) * (l - 2) + (l - 2) + m], b[l, m], out=tmp)
            r -= tmp
            r *= a[l, m]
        for l in range(m, lmax + 1):
            q = out[l * l + l + m]
            np.multiply(q, s_m, out=out[l * l + l - m])
            q *= c_m


def _sh_blocks(d_flat: np.ndarray, lmax: int) -> Iterator[tuple[int, int, np.ndarray]]:
    """Yield ``(start, stop, Y)`` with ``Y`` of shape (n_coeffs, stop - start).

    ``Y`` is a view of a buffer that is reused by the next iteration.
    Directions are normalised; zero-length vectors give NaN.
    """
    n = d_flat.shape[0]
    k = (lmax + 1) ** 2
    block = int(min(max(_BLOCK_VALUES // k, 256), 16384))
    block = min(block, max(n, 1))
    a, b = recurrence_tables(lmax)
    buf = np.empty((k, block))
    for start in range(0, n, block):
        stop = min(n, start + block)
        xyz = np.ascontiguousarray(d_flat[start:stop].T)  # (3, n_block)
        norm = np.sqrt(np.einsum("ij,ij->j", xyz, xyz))
        with np.errstate(invalid="ignore", divide="ignore"):
            xyz /= norm
        y_blk = buf[:, : stop - start]
        _sh_block(xyz[0], xyz[1], xyz[2], lmax, a, b, y_blk)
        yield start, stop, y_blk


def real_sh(directions: np.ndarray, lmax: int) -> np.ndarray:
    """Evaluate all real SH ``Y_i`` (``i < (lmax+1)**2``) at directions.

    Parameters
    ----------
    directions : numpy.ndarray
        Shape ``(..., 3)`` unit vectors (Y-up frame).  Inputs are normalised
        internally; zero-length vectors give NaN.
    lmax : int
        Maximum degree, ``>= 0``.

    Returns
    -------
    numpy.ndarray
        Shape ``(..., (lmax+1)**2)``, float64, C-contiguous; last axis is the
        l-major flat index ``l*l + l + m``.

    Raises
    ------
    ValueError
        If the last axis of ``directions`` is not 3 or ``lmax < 0``.
    TypeError
        If ``lmax`` is not an integer.
    """
    d = _check_directions(directions)
    lmax = check_int(lmax, "lmax", 0)
    batch = d.shape[:-1]
    d_flat = d.reshape(-1, 3)
    k = (lmax + 1) ** 2
    out = np.empty((d_flat.shape[0], k))
    for start, stop, y_blk in _sh_blocks(d_flat, lmax):
        out[start:stop] = y_blk.T
    return out.reshape(batch + (k,))


def eval_sh(coeffs: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Evaluate an SH expansion ``f(d) = sum_i c_i Y_i(d)``.

    Parameters
    ----------
    coeffs : numpy.ndarray
        Shape ``(n_coeffs,)`` or ``(n_coeffs, C)`` with ``n_coeffs = (lmax+1)**2``
        (coefficient axis FIRST, as returned by `project_equirect`).
    directions : numpy.ndarray
        Shape ``(..., 3)`` unit vectors.

    Returns
    -------
    numpy.ndarray
        Shape ``(...)`` or ``(..., C)``, float64.
    """
    c = np.asarray(coeffs, dtype=np.float64)
    if c.ndim not in (1, 2):
        raise ValueError(f"coeffs must have shape (n_coeffs,) or (n_coeffs, C), got shape {c.shape}")
    lmax = lmax_of(c.shape[0], f"coeffs of shape {c.shape}")
    d = _check_directions(directions)
    batch = d.shape[:-1]
    d_flat = d.reshape(-1, 3)
    out = np.empty((d_flat.shape[0],) + c.shape[1:])
    for start, stop, y_blk in _sh_blocks(d_flat, lmax):
        out[start:stop] = y_blk.T @ c
    return out.reshape(batch + c.shape[1:])


# --------------------------------------------------------------------------
# equirectangular projection
# --------------------------------------------------------------------------
def project_equirect(image: np.ndarray, lmax: int) -> np.ndarray:
    """Project an equirectangular map onto real SH by quadrature.

    ``c_i = sum_pixels Y_i(d_p) f(d_p) dOmega_p`` with the pixel directions of
    `freqbrdf.sphere.sampling.equirect_directions` and weights of
    `freqbrdf.sphere.sampling.equirect_solid_angles`, summed through `equirect_factors`
    (over each row's columns per order, then over rows per degree): O(H W lmax).

    Parameters
    ----------
    image : numpy.ndarray
        Shape ``(H, W)`` or ``(H, W, C)`` (e.g. radiance), ``H >= 2``.
    lmax : int
        Maximum degree, ``>= 0``.

    Returns
    -------
    numpy.ndarray
        Shape ``(n_coeffs,)`` or ``(n_coeffs, C)``, float64 (coefficient axis
        FIRST; transpose before `power_spectrum`).
    """
    img = np.asarray(image, dtype=np.float64)
    if img.ndim not in (2, 3):
        raise ValueError(f"image must have shape (H, W) or (H, W, C), got shape {img.shape}")
    lmax = check_int(lmax, "lmax", 0)
    height, width = img.shape[:2]
    if height < 2 or width < 1:
        raise ValueError(f"image must have H >= 2 and W >= 1, got shape {img.shape}")
    polar, azimuthal = equirect_factors(height, width, lmax)
    channels = img.reshape(height, width, -1)
    per_order = channels.transpose(0, 2, 1) @ azimuthal  # (H, C, M): sum over each row (O(H W lmax))
    weighted = polar * equirect_solid_angles(height, width)[:, None, None]
    by_order = np.einsum("hml,hcm->mlc", weighted, per_order)  # (M, L + 1, C), 0 where l < |m|
    acc = np.empty(((lmax + 1) ** 2, channels.shape[2]))
    for l in range(lmax + 1):  # flat indices l^2 .. l^2 + 2l are the orders m = -l .. l
        acc[l * l : (l + 1) * (l + 1)] = by_order[lmax - l : lmax + l + 1, l]
    return acc if img.ndim == 3 else acc[:, 0]


def equirect_factors(height: int, width: int, lmax: int) -> tuple[np.ndarray, np.ndarray]:
    """The real SH on an equirectangular grid as products of a polar and an azimuthal factor.

    Every pixel of a row shares its polar angle and every pixel of a column its
    azimuth, so ``Y_lm(theta_i, phi_j) = polar[i, m + lmax, l] * azimuthal[j, m + lmax]``
    on the grid of `freqbrdf.sphere.sampling.equirect_directions`.

    Parameters
    ----------
    height, width : int
        Map size ``H >= 2``, ``W >= 1``.
    lmax : int
        Maximum degree, ``>= 0``.

    Returns
    -------
    polar : numpy.ndarray
        Shape ``(H, 2 lmax + 1, lmax + 1)``: ``Y_l|m|`` at azimuth 0 (where the
        azimuthal factor of ``m >= 0`` is 1), 0 where ``l < |m|``.
    azimuthal : numpy.ndarray
        Shape ``(W, 2 lmax + 1)``: ``cos(m phi_j)`` for ``m > 0``, 1 for ``m = 0``
        and ``sin(|m| phi_j)`` for ``m < 0`` (the sign convention of `real_sh`).
    """
    height, width = check_grid(height, width)
    ct, st = row_cos_sin(height)
    return ring_factors(np.arctan2(st, ct), 2.0 * np.pi * (np.arange(width) + 0.5) / width, lmax)


def ring_factors(theta: np.ndarray, phi: np.ndarray, lmax: int) -> tuple[np.ndarray, np.ndarray]:
    """The real SH on a grid of rings (polar angles x azimuths) as a polar times an azimuthal factor.

    ``Y_lm(theta_i, phi_j) = polar[i, m + lmax, l] * azimuthal[j, m + lmax]`` (`equirect_factors`
    on any rings).

    Parameters
    ----------
    theta : numpy.ndarray
        Shape ``(n,)``, polar angles of the rings, radians.
    phi : numpy.ndarray
        Shape ``(k,)``, azimuths shared by every ring, radians.
    lmax : int
        Maximum degree, ``>= 0``.

    Returns
    -------
    polar : numpy.ndarray
        Shape ``(n, 2 lmax + 1, lmax + 1)``: ``Y_l|m|`` at azimuth 0, 0 where ``l < |m|``.
    azimuthal : numpy.ndarray
        Shape ``(k, 2 lmax + 1)``: ``cos(m phi)``, 1 or ``sin(|m| phi)``.
    """
    lmax = check_int(lmax, "lmax", 0)
    theta = np.asarray(theta, dtype=np.float64)
    # azimuth 0 is the direction (0, cos theta, -sin theta)
    y = real_sh(np.stack([np.zeros_like(theta), np.cos(theta), -np.sin(theta)], axis=-1), lmax)  # (n, n_coeffs)
    m = np.arange(-lmax, lmax + 1)
    polar = np.zeros((theta.shape[0], m.size, lmax + 1))
    for l in range(lmax + 1):
        polar[:, m[lmax - l : lmax + l + 1] + lmax, l] = y[:, l * l + l + np.abs(m[lmax - l : lmax + l + 1])]
    mphi = np.abs(m)[None, :] * np.asarray(phi, dtype=np.float64)[:, None]
    azimuthal = np.where(m > 0, np.cos(mphi), np.where(m < 0, np.sin(mphi), 1.0))
    return polar, azimuthal


def eval_rings(coeffs: np.ndarray, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """An SH expansion evaluated on a grid of rings, through `ring_factors`: O(n k lmax + n lmax^2).

    Parameters
    ----------
    coeffs : numpy.ndarray
        Shape ``((lmax + 1)**2, C)``.
    theta, phi : numpy.ndarray
        Shapes ``(n,)`` and ``(k,)``: the rings' polar angles and their azimuths, radians.

    Returns
    -------
    numpy.ndarray
        Shape ``(n, k, C)``, float64: ``eval_sh`` at ``angles_to_directions(theta_i, phi_j)``.
    """
    c = np.asarray(coeffs, dtype=np.float64)
    lmax = lmax_of(c.shape[0], "coeffs")
    polar, azimuthal = ring_factors(theta, phi, lmax)
    by_order = np.zeros((2 * lmax + 1, lmax + 1, c.shape[1]))
    for l in range(lmax + 1):
        by_order[lmax - l : lmax + l + 1, l] = c[l * l : (l + 1) * (l + 1)]
    rows = np.einsum("hml,mlc->hcm", polar, by_order)  # (n, C, M)
    return (rows @ azimuthal.T).transpose(0, 2, 1)


def filter_equirect(image: np.ndarray, gains: np.ndarray) -> np.ndarray:
    """An equirectangular map with each SH degree ``l`` scaled by ``gains[l]``.

    Equal to ``eval_sh(project_equirect(image, lmax) * gains[sh_degrees(lmax)][:, None],
    equirect_directions(H, W))`` with ``lmax = len(gains) - 1`` (to rounding), but
    computed through `equirect_factors`: a sum over columns per order ``m``, then
    over rows per degree, and back, which costs O(H W lmax) instead of
    O(H W lmax^2).

    Parameters
    ----------
    image : numpy.ndarray
        Shape ``(H, W, C)``, ``H >= 2``.
    gains : numpy.ndarray
        Shape ``(lmax + 1,)``: factor of each degree (e.g. a low-pass filter).

    Returns
    -------
    numpy.ndarray
        Shape ``(H, W, C)``, float64: the filtered map on the same grid.
    """
    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 3 or img.shape[0] < 2:
        raise ValueError(f"image must have shape (H, W, C) with H >= 2, got shape {img.shape}")
    gains = np.asarray(gains, dtype=np.float64)
    if gains.ndim != 1 or gains.size < 1:
        raise ValueError(f"gains must have shape (lmax + 1,), got shape {gains.shape}")
    height, width = img.shape[:2]
    polar, azimuthal = equirect_factors(height, width, gains.size - 1)
    per_order = img.transpose(0, 2, 1) @ azimuthal  # (H, C, M): sum over each row
    weighted = polar * equirect_solid_angles(height, width)[:, None, None]
    coeffs = np.einsum("hml,hcm->mlc", weighted, per_order) * gains[None, :, None]  # (M, L + 1, C)
    rows = np.einsum("hml,mlc->hcm", polar, coeffs)  # (H, C, M)
    return (rows @ azimuthal.T).transpose(0, 2, 1)


# --------------------------------------------------------------------------
# spectra
# --------------------------------------------------------------------------
def power_spectrum(coeffs: np.ndarray, lmax: int | None = None) -> np.ndarray:
    """Per-degree power ``S(l) = sum_m c_lm**2`` of each channel.

    Parameters
    ----------
    coeffs : numpy.ndarray
        Shape ``(..., n_coeffs, C)``: the library's one layout of SH
        coefficients (`project_equirect` returns ``(n_coeffs, C)``,
        :func:`freqbrdf.estimate.shfit.fit_sh` ``(T, n_coeffs, C)``).
    lmax : int, optional
        Degree up to which to compute.  Default: inferred from
        ``n_coeffs = (lmax+1)**2``.  If given, only the first
        ``(lmax+1)**2`` coefficients are used.

    Returns
    -------
    numpy.ndarray
        Shape ``(..., lmax + 1, C)``, float64.
    """
    c = np.asarray(coeffs, dtype=np.float64)
    if c.ndim < 2:
        raise ValueError(f"coeffs must have shape (..., n_coeffs, C), got shape {c.shape}")
    n = c.shape[-2]
    if lmax is None:
        lmax = lmax_of(n, f"coeffs of shape {c.shape} (axis -2)")
    else:
        lmax = check_int(lmax, "lmax", 0)
        if (lmax + 1) ** 2 > n:
            raise ValueError(
                f"lmax={lmax} needs {(lmax + 1) ** 2} coefficients on axis -2, got shape {c.shape}"
            )
    sq = c[..., : (lmax + 1) ** 2, :] ** 2
    return np.add.reduceat(sq, np.arange(lmax + 1) ** 2, axis=-2)
