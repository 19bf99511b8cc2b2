"""The specular lobe's zonal SH spectrum ``f_l(alpha)``, as the frequency-domain model applies it.

The paper (section 3.2, Eqs. 8-10) takes the Gaussian ``exp(-(alpha l)^2)`` of
Ramamoorthi and Hanrahan; `ggx_lobe_spectrum` is GGX's own, the lobe of the
principled BSDF that renders the captures. Kept apart from :mod:`freqbrdf.brdf`,
which nearly every rule imports, so that only the rules that fit the model depend on it.
"""

from __future__ import annotations

import functools

import numpy as np

from .brdf import ALPHA_MIN
from .validation import check_shape

__all__ = ["LOBES", "LOBE_NODES", "ggx_lobe_spectrum", "lobe_table"]

LOBES = ("gaussian", "ggx")
"""The paper's ``exp(-(alpha l)^2)``, or GGX's own spectrum (`ggx_lobe_spectrum`)."""
LOBE_NODES = 256  # nodes of `lobe_table` over log alpha in [log ALPHA_MIN, 0]


@functools.cache
def _unit_interval_nodes(nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on [0, 1] (numpy's eigenvalue solve takes 0.5 s at 2048: kept)."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    x, w = 0.5 * (x + 1.0), 0.5 * w
    x.flags.writeable = w.flags.writeable = False
    return x, w


def ggx_lobe_spectrum(alpha: np.ndarray, lmax: int, nodes: int = 2048) -> tuple[np.ndarray, np.ndarray]:
    """Zonal SH spectrum of the GGX reflection lobe, ``f_l(alpha)``, and its derivative in alpha.

    The paper (section 3.2, Eqs. 8-10) writes the specular lobe about the
    mirror direction as ``f_l = exp(-(alpha l)^2)``, Ramamoorthi and
    Hanrahan's Gaussian approximation of a Torrance-Sparrow lobe. For GGX
    (Mitsuba's principled BSDF) at normal view, ``f cos theta_i = D(h) / 4`` in
    the light direction, whose angle to the mirror direction is twice the
    half-vector's, ``theta = 2 theta_h``; as ``d omega_i = 4 cos theta_h d omega_h``
    the lobe's weight is ``D(h) cos theta_h d omega_h``, the measure GGX samples
    exactly: with ``xi`` uniform in [0, 1), ``cos^2 theta_h = (1 - xi) / (1 +
    (alpha^2 - 1) xi)``. So ``f_l = int_0^1 P_l(2 cos^2 theta_h - 1) d xi``
    (Funk-Hecke), ``f_0 = 1``. It falls faster than the Gaussian at low
    degrees (GGX's long tails: ``f_1`` 0.45 against 0.79 at alpha 0.49) and
    slower at high ones (its sharper peak).

    Parameters
    ----------
    alpha : numpy.ndarray
        Shape ``(A,)``: GGX widths in (0, 1].
    lmax : int
        Highest degree.
    nodes : int
        Gauss-Legendre nodes in ``xi``.

    Returns
    -------
    f, df_dalpha : numpy.ndarray
        Shape ``(A, lmax + 1)``, float64.
    """
    a = np.asarray(alpha, dtype=np.float64)
    check_shape(a, "alpha", (None,))
    if not np.all((a > 0) & (a <= 1)):
        raise ValueError(f"alpha must be in (0, 1], got {float(a[~((a > 0) & (a <= 1))][0])!r}")
    xi, w = _unit_interval_nodes(nodes)
    den = 1.0 + (a[:, None] ** 2 - 1.0) * xi
    t = 2.0 * (1.0 - xi) / den - 1.0  # cos theta, (A, n)
    dt = -4.0 * a[:, None] * xi * (1.0 - xi) / den**2  # dt / dalpha
    f = np.empty((a.size, lmax + 1))
    df = np.empty((a.size, lmax + 1))
    p_prev, p = np.ones_like(t), t  # P_0, P_1
    dp_prev, dp = np.zeros_like(t), np.ones_like(t)  # P_l' by P'_{l+1} = P'_{l-1} + (2l + 1) P_l
    f[:, 0], df[:, 0] = 1.0, 0.0
    for l in range(1, lmax + 1):
        f[:, l] = p @ w
        df[:, l] = (dp * dt) @ w
        p_prev, p, dp_prev, dp = p, ((2 * l + 1) * t * p - l * p_prev) / (l + 1), dp, dp_prev + (2 * l + 1) * p
    return f, df


def lobe_table(lobe: str, lmax: int) -> np.ndarray:
    """The lobe spectrum as the compiled model reads it (`freqbrdf.kernels`).

    Parameters
    ----------
    lobe : {"gaussian", "ggx"}
        See `LOBES`.
    lmax : int
        Highest degree.

    Returns
    -------
    numpy.ndarray
        Shape ``(0, 2, lmax + 1)`` for the Gaussian, which the kernels evaluate in closed form;
        for GGX ``(LOBE_NODES, 2, lmax + 1)``: ``f_l`` and ``df_l / d log alpha`` at ``log alpha``
        evenly spaced over ``[log ALPHA_MIN, 0]``, the nodes of a cubic Hermite interpolant.
    """
    if lobe not in LOBES:
        raise ValueError(f"lobe must be one of {LOBES}, got {lobe!r}")
    if lobe == "gaussian":
        return np.empty((0, 2, lmax + 1))
    alpha = np.exp(np.linspace(np.log(ALPHA_MIN), 0.0, LOBE_NODES))
    f, df = ggx_lobe_spectrum(alpha, lmax)
    return np.ascontiguousarray(np.stack([f, df * alpha[:, None]], axis=1))
