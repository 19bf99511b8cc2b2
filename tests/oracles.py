"""Independent reference implementations that only tests compare the library against.

They are deliberately written from the formulas (Ramamoorthi and Hanrahan
2001 for the clamped-cosine irradiance; the principled BSDF's lobes; Schlick's
Fresnel), not from the library's optimised code paths, so that a test
comparing the two can fail. Smith's G1 in the angle form and the brute-force
radiance of the principled BSDF, which the benches use too, are in the
library: `freqbrdf.sphere.reference`.
"""

from __future__ import annotations

import numpy as np

from freqbrdf.sphere.brdf import R0_DIELECTRIC
from freqbrdf.sphere.sh import real_sh, sh_degrees
from freqbrdf.util.validation import check_int, check_shape, lmax_of

LOCAL_NORMAL = (0.0, 0.0, 1.0)


def clamped_cosine_gains(lmax: int) -> np.ndarray:
    """``2 pi g_l`` with ``g_l = int_0^1 t P_l(t) dt`` for l = 0..lmax, shape (lmax+1,).

    Funk-Hecke: the clamped cosine about ``n`` has SH coefficients
    ``2 pi g_l Y_lm(n)`` (``g_0 = 1/2``, ``g_1 = 1/3``, 0 for odd ``l > 1``).
    ``t P_l(t)`` is a polynomial, so Gauss-Legendre quadrature is exact.
    """
    x, w = np.polynomial.legendre.leggauss(lmax // 2 + 2)  # exact up to degree lmax + 3
    t, w = 0.5 * (x + 1.0), 0.5 * w  # nodes on [0, 1]
    g = np.array([w @ (t * np.polynomial.legendre.Legendre.basis(l)(t)) for l in range(lmax + 1)])
    return 2.0 * np.pi * g


def check_normals(normal: np.ndarray, name: str) -> np.ndarray:
    n = np.asarray(normal, dtype=np.float64)
    if n.ndim not in (1, 2) or n.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (3,) or (T, 3), got shape {n.shape}")
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    if not (np.all(np.isfinite(norm)) and np.all(norm > 0)):
        raise ValueError(f"{name} must be non-zero finite vectors, got {n!r}")
    return n / norm


def clamped_cosine_sh(lmax: int, normal: np.ndarray = LOCAL_NORMAL) -> np.ndarray:
    """SH coefficients of ``max(n . w, 0)``, the irradiance kernel.

    Parameters
    ----------
    lmax : int
        Maximum degree.
    normal : numpy.ndarray
        Shape ``(3,)`` or ``(T, 3)``: kernel axis in the frame of the SH
        (default local +z, the texel normal).

    Returns
    -------
    numpy.ndarray
        Shape ``((lmax+1)**2,)`` or ``(T, (lmax+1)**2)``, float64:
        ``2 pi g_l Y_lm(n)``, ``g_l = int_0^1 t P_l(t) dt``.
    """
    lmax = check_int(lmax, "lmax", 0)
    n = check_normals(normal, "normal")
    return clamped_cosine_gains(lmax)[sh_degrees(lmax)] * real_sh(n, lmax)


def irradiance_from_coeffs(coeffs: np.ndarray, normal: np.ndarray = LOCAL_NORMAL) -> np.ndarray:
    """Irradiance ``E = int_{n.w>0} L(w) (n . w) dw`` of per-texel SH radiance.

    Parameters
    ----------
    coeffs : numpy.ndarray
        Shape ``(T, (lmax+1)**2, C)``: SH of the incoming radiance L, e.g. the
        fit of ``incoming`` at `mirror_directions` (texel frame).
    normal : numpy.ndarray
        Shape ``(3,)`` or ``(T, 3)``: the normal in that frame (default local +z).

    Returns
    -------
    numpy.ndarray
        Shape ``(T, C)``, float64, radiance times sr (``pi L`` for constant L).
    """
    c = np.asarray(coeffs, dtype=np.float64)
    check_shape(c, "coeffs", (None, None, None))
    lmax = lmax_of(c.shape[1], f"coeffs of shape {c.shape} (axis 1)")
    a = clamped_cosine_sh(lmax, normal)
    if a.ndim == 2:
        check_shape(a, "normal", (c.shape[0], None))
        return np.einsum("ti,tic->tc", a, c)
    return np.einsum("i,tic->tc", a, c)


def irradiance_at_normals(env_coeffs: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Irradiance of one distant environment at many surface normals.

    Unlike a per-texel fit of the mirror-direction samples (which only sees
    the light at K directions and misestimates E by a few percent with 24
    views), this uses the whole environment; like the paper's model it ignores
    occlusion by the object itself.

    Parameters
    ----------
    env_coeffs : numpy.ndarray
        Shape ``((lmax+1)**2, C)``: SH of the environment radiance in the frame
        of ``normals`` (e.g. :func:`freqbrdf.sphere.sh.project_equirect`, world frame).
    normals : numpy.ndarray
        Shape ``(T, 3)``, surface normals.

    Returns
    -------
    numpy.ndarray
        Shape ``(T, C)``, float64, radiance times sr.
    """
    c = np.asarray(env_coeffs, dtype=np.float64)
    check_shape(c, "env_coeffs", (None, None))
    lmax = lmax_of(c.shape[0], f"env_coeffs of shape {c.shape} (axis 0)")
    n = np.asarray(normals)
    check_shape(n, "normals", (None, 3))
    return clamped_cosine_sh(lmax, n) @ c


def lobes_from_principled(
    base: np.ndarray, roughness: np.ndarray, metallic: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Diffuse albedo, specular reflectance and lobe width of principled parameters.

    Parameters
    ----------
    base : numpy.ndarray
        Shape ``(T, 3)``, linear base colour in [0, 1].
    roughness, metallic : numpy.ndarray
        Shape ``(T,)``, in [0, 1].

    Returns
    -------
    tuple of numpy.ndarray
        ``kd`` (T, 3) ``= (1 - m) base``; ``ks`` (T, 3) ``= R0 = 0.04 (1 - m) + m base``;
        ``alpha`` (T,) ``= roughness^2``.
    """
    b = np.asarray(base, dtype=np.float64)
    check_shape(b, "base", (None, 3))
    r = np.asarray(roughness, dtype=np.float64)
    m = np.asarray(metallic, dtype=np.float64)
    check_shape(r, "roughness", (b.shape[0],))
    check_shape(m, "metallic", (b.shape[0],))
    m = m[:, None]
    return (1.0 - m) * b, R0_DIELECTRIC * (1.0 - m) + m * b, r**2


def schlick_fresnel(r0: np.ndarray, cos_theta: np.ndarray) -> np.ndarray:
    """Schlick's Fresnel ``R0 + (1 - R0)(1 - cos theta)^5``.

    Parameters
    ----------
    r0 : numpy.ndarray
        Reflectance at normal incidence (broadcastable with ``cos_theta``).
    cos_theta : numpy.ndarray
        Cosine of the angle to the normal, in [0, 1].

    Returns
    -------
    numpy.ndarray
        Reflectance, from ``R0`` at normal incidence to 1 at grazing.
    """
    s5 = (1.0 - np.asarray(cos_theta, dtype=np.float64)) ** 5
    return np.asarray(r0, dtype=np.float64) * (1.0 - s5) + s5
