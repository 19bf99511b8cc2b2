"""The principled BSDF's parameters as the frequency-domain model sees them.

Mitsuba's principled BSDF (Burley 2012) is parametrised by base colour,
roughness and metallic; the frequency-domain model (Wiersma et al. 2024,
sections 3.2 and 4.1, Eqs. 8-11) by a diffuse albedo K_d, a specular
reflectance K_s at normal incidence and a GGX width alpha. This module maps
between the two (the paper's Eqs. 26-30), holds the constants both sides share,
and measures parameters against a reference (`parameter_mse`: the error the Mitsuba baseline
logs after every epoch and the metrics score, defined once below both).
"""

from __future__ import annotations

import numpy as np

from freqbrdf.util.colour import LUMINANCE
from freqbrdf.util.validation import check_shape

TEXTURES = ("base_color", "roughness", "metallic")
"""The principled parameters as textures, in the order of every table and figure."""

__all__ = ["TEXTURES", "R0_DIELECTRIC", "ALPHA_MIN", "alpha_from_roughness", "tan2_theta", "smith_g1", "principled_from_lobes",
           "parameter_mse"]

R0_DIELECTRIC = 0.04  # Disney/Mitsuba principled: specular reflectance at normal incidence of a dielectric
ALPHA_MIN = 1e-3  # Mitsuba's principled BSDF clamps alpha here


def alpha_from_roughness(roughness: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """GGX width ``alpha = max(r^2, ALPHA_MIN)`` and the derivative the optimiser uses.

    Below ``r_min = sqrt(ALPHA_MIN)`` alpha is constant, so the true
    derivative is 0 there and a texel whose roughness overshoots below
    ``r_min`` (Adam moves every parameter by about ``lr`` per step, whatever
    the gradient's size) would never move again; with 0.5 initial values this
    trapped 1-2 of the 200 texels of a noise-free synthetic test at
    ``r ~ 0.01`` although their true roughness was 0.3-0.37. So the derivative is
    passed straight through the clamp: ``2 max(r, r_min)``, exact wherever
    the clamp is inactive.

    Parameters
    ----------
    roughness : numpy.ndarray
        Shape ``(T,)``, in [0, 1].

    Returns
    -------
    alpha, dalpha_dr : numpy.ndarray
        Shape ``(T,)``, float64.
    """
    r = np.asarray(roughness, dtype=np.float64)
    r_min = np.sqrt(ALPHA_MIN)
    return np.maximum(r * r, ALPHA_MIN), 2.0 * np.maximum(r, r_min)


def tan2_theta(cos_theta: np.ndarray) -> np.ndarray:
    """``tan^2 theta`` of ``cos theta`` in (0, 1] (the form in which Smith's G1 depends on theta)."""
    c2 = cos_theta * cos_theta
    return (1.0 - c2) / c2


def smith_g1(tan2: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """GGX Smith masking of one direction, ``2 / (1 + sqrt(1 + alpha^2 tan^2 theta))`` (the G_alpha of paper Eq. 11).

    Parameters
    ----------
    tan2 : numpy.ndarray
        ``tan^2`` of the angle to the normal (`tan2_theta`), >= 0, broadcastable with ``alpha``.
    alpha : numpy.ndarray
        GGX width (dimensionless, >= 0).

    Returns
    -------
    numpy.ndarray
        In (0, 1]; 1 at normal incidence, falling toward grazing angles and with alpha.
    """
    return 2.0 / (1.0 + np.sqrt(1.0 + alpha * alpha * tan2))


def principled_from_lobes(
    kd: np.ndarray, ks: np.ndarray, alpha: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Principled (base colour, roughness, metallic) from (K_d, K_s, alpha).

    Approximations: K_s is taken as the normal-incidence reflectance R0 (the
    spectrum-only K_s also absorbs the Fresnel rise at grazing angles, so it
    overestimates R0 and hence metallic); the Torrance-Sparrow lobe width
    alpha is taken as the GGX alpha, ``roughness = sqrt(alpha)``. Metallic m
    solves the luminance (Rec. 709) relations ``Y(kd) = (1 - m) Y(base)`` and
    ``Y(ks) = 0.04 (1 - m) + m Y(base)``, i.e. with ``u = 1 - m``
    ``0.04 u^2 - (Y(ks) + Y(kd)) u + Y(kd) = 0``: the smaller root, which lies
    in [0, 1) whenever ``Y(ks) > 0.04``; m = 0 if there is no real root or
    the root exceeds 1 (K_s at or below a dielectric's 0.04). For a base
    colour darker than 0.04 the relations have a second exact solution; the
    more metallic one is returned. The base
    colour is then the per-channel least-squares solution of
    ``(1 - m) base = kd`` and ``m base = ks - 0.04 (1 - m)``, so it comes from
    the diffuse lobe for dielectrics and from the specular lobe for metals
    (grey for metals if ``ks`` is a scalar). Everything is clipped to [0, 1].

    Parameters
    ----------
    kd : numpy.ndarray
        Shape ``(T, 3)``, diffuse albedo.
    ks : numpy.ndarray
        Shape ``(T,)`` (luminance) or ``(T, 3)``, specular reflectance.
    alpha : numpy.ndarray
        Shape ``(T,)``, lobe width.

    Returns
    -------
    tuple of numpy.ndarray
        ``base`` (T, 3), ``roughness`` (T,), ``metallic`` (T,), float64 in [0, 1].
    """
    d = np.asarray(kd, dtype=np.float64)
    check_shape(d, "kd", (None, 3))
    k = np.asarray(ks, dtype=np.float64)
    if k.ndim == 1:
        check_shape(k, "ks", (d.shape[0],))
        k = k[:, None]
    else:
        check_shape(k, "ks", (d.shape[0], 3))
    a = np.asarray(alpha, dtype=np.float64)
    check_shape(a, "alpha", (d.shape[0],))
    for name, v in (("kd", d), ("ks", k), ("alpha", a)):
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{name} must be finite, got {v[~np.isfinite(v)][0]!r}")
    d = np.clip(d, 0.0, 1.0)
    k = np.clip(k, 0.0, 1.0)
    y_d = d @ LUMINANCE
    y_s = k[:, 0] if k.shape[1] == 1 else k @ LUMINANCE
    s = y_s + y_d
    disc2 = s * s - 4.0 * R0_DIELECTRIC * y_d
    real = (disc2 >= 0.0) & (s > 0.0)
    # smaller root u = 2 y_d / (s + sqrt(disc2)), free of cancellation; no real
    # root (K_s below a dielectric's, diffuse too bright) or black -> dielectric
    u = np.where(real, 2.0 * y_d / np.where(real, s + np.sqrt(np.maximum(disc2, 0.0)), 1.0), 1.0)
    m = np.clip(1.0 - u, 0.0, 1.0)
    mm = m[:, None]
    base = ((1.0 - mm) * d + mm * (k - R0_DIELECTRIC * (1.0 - mm))) / ((1.0 - mm) ** 2 + mm**2)
    roughness = np.sqrt(np.clip(a, 0.0, 1.0))
    return np.clip(base, 0.0, 1.0), roughness, m


def parameter_mse(truth: dict[str, np.ndarray], estimate: dict[str, np.ndarray], texels: np.ndarray) -> dict[str, float]:
    """Mean squared error per parameter group over selected texels, and their average.

    Parameters
    ----------
    truth, estimate : dict
        ``base_color`` (R, R, 3), ``roughness`` (R, R), ``metallic`` (R, R) in [0, 1].
    texels : ndarray, shape (N,), int
        Flat indices ``i * R + j`` of the texels to score (e.g. the observed ones).

    Returns
    -------
    dict
        ``base_color``, ``roughness``, ``metallic`` (base colour averaged over
        its channels) and ``average`` (mean of the three, as in the paper's Table 2).
    """
    if len(texels) == 0:
        raise ValueError("parameter_mse: no texels to score")
    out = {}
    for name in TEXTURES:
        if truth[name].shape != estimate[name].shape:
            raise ValueError(f"parameter_mse: {name} is {estimate[name].shape}, ground truth {truth[name].shape}")
        n = truth[name].shape[0] * truth[name].shape[1]
        t = truth[name].reshape(n, -1)[texels].astype(np.float64)
        e = estimate[name].reshape(n, -1)[texels].astype(np.float64)
        out[name] = float(np.mean((t - e) ** 2))
    out["average"] = float(np.mean([out[name] for name in TEXTURES]))
    return out
