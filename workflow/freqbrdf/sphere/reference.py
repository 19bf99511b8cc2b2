"""Brute-force reference radiance of the principled BSDF, an independent oracle for tests and benches.

Written from the formulas (GGX distribution, Smith's G1 in the angle form,
Schlick's Fresnel at the half vector, Burley's diffuse lobe), summed over
every pixel of an equirectangular environment map: no spherical harmonics,
no lobe tables, nothing of the estimator (`freqbrdf.estimate`) or of
`freqbrdf.sphere.brdf`'s and `freqbrdf.sphere.lobes`' code paths, so that
comparing the model with it can fail. It imports only numpy, the dielectric
reflectance constant and the map's pixel grid (`freqbrdf.sphere.sampling`:
the convention the map is stored in, not part of any model).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from freqbrdf.sphere.brdf import R0_DIELECTRIC
from freqbrdf.sphere.sampling import equirect_directions, equirect_solid_angles

__all__ = ["smith_g1", "ggx_radiance"]


def smith_g1(cos_theta: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """GGX Smith masking of one direction, ``2 / (1 + sqrt(1 + alpha^2 tan^2 theta))`` (paper Eq. 8).

    Parameters
    ----------
    cos_theta : numpy.ndarray
        Cosine of the angle to the normal, in (0, 1] (broadcastable with ``alpha``).
    alpha : numpy.ndarray
        GGX width (dimensionless, >= 0).

    Returns
    -------
    numpy.ndarray
        In (0, 1]; 1 at normal incidence, falling toward grazing angles and with alpha.
    """
    c2 = np.square(np.asarray(cos_theta, dtype=np.float64))
    a = np.asarray(alpha, dtype=np.float64)
    return 2.0 / (1.0 + np.sqrt(1.0 + a * a * (1.0 - c2) / c2))


def ggx_radiance(env: np.ndarray, capture: Mapping[str, np.ndarray],
                 truth: Mapping[str, np.ndarray]) -> np.ndarray:
    """Outgoing radiance of every observation by quadrature over the map's pixels above each texel's horizon.

    The BRDF is Mitsuba's principled BSDF without its extras: GGX distribution, separable Smith
    masking-shadowing, Schlick's Fresnel at the half vector (``R0 = 0.04 (1 - m) + m base``) and
    its diffuse lobe ``(1 - m) base / pi [(1 - F_i / 2)(1 - F_o / 2) + R (F_o + F_i + F_o F_i (R - 1))]``,
    ``F = (1 - cos theta)^5``, ``R = 2 r (h.o)^2`` (Burley 2015). The object does not shadow
    itself.

    Parameters
    ----------
    env : numpy.ndarray
        Shape ``(H, W, 3)``: equirectangular environment radiance (`freqbrdf.sphere.sampling`).
    capture : mapping
        ``frame`` (T, 3, 3): rows tangent, bitangent, normal (world); ``wo_local`` (T, K, 3):
        unit directions to the cameras in the texel frames; ``weight`` (T, K): > 0 where observed.
    truth : mapping
        ``base_color`` (T, 3) linear; ``roughness`` and ``metallic`` (T,), in [0, 1].

    Returns
    -------
    numpy.ndarray
        Shape ``(T, K, 3)``, float64, radiance in the map's units; 0 where ``weight`` is 0.
    """
    frame, wo, weight = capture["frame"], capture["wo_local"], capture["weight"]
    h, w = env.shape[:2]
    directions = equirect_directions(h, w).reshape(-1, 3)
    power = (env * equirect_solid_angles(h, w)[:, None, None]).reshape(-1, 3)
    radiance = np.zeros(wo.shape[:2] + (3,))
    for t in range(frame.shape[0]):
        wi = directions @ frame[t].T  # local directions: the frame's rows are tangent, bitangent, normal
        above = wi[:, 2] > 0
        wi, pw = wi[above], power[above]
        alpha, m, base = truth["roughness"][t] ** 2, truth["metallic"][t], truth["base_color"][t]
        r0 = R0_DIELECTRIC * (1 - m) + m * base
        f_i = (1 - wi[:, 2]) ** 5
        for k in np.nonzero(weight[t] > 0)[0]:
            o = wo[t, k]
            half = wi + o
            half /= np.linalg.norm(half, axis=1, keepdims=True)
            f_o, retro = (1 - o[2]) ** 5, 2 * truth["roughness"][t] * (half @ o) ** 2
            shape = (1 - f_i / 2) * (1 - f_o / 2) + retro * (f_o + f_i + f_o * f_i * (retro - 1))
            diffuse = (1 - m) * base[None, :] / np.pi * (shape * wi[:, 2])[:, None]
            d = alpha**2 / (np.pi * (half[:, 2] ** 2 * (alpha**2 - 1) + 1) ** 2)
            g = smith_g1(wi[:, 2], alpha) * smith_g1(np.array([o[2]]), alpha)
            fresnel = r0 + (1 - r0) * ((1 - np.clip(half @ o, 0, 1)) ** 5)[:, None]
            specular = (d * g / (4 * o[2]))[:, None] * fresnel  # f cos theta_i: cos theta_i cancels
            radiance[t, k] = ((specular + diffuse) * pw).sum(axis=0)
    return radiance
