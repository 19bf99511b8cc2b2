"""The lobes of the frequency-domain model: the specular zonal SH spectrum ``f_l(alpha)``, and the weights per view.

The paper (section 3.2, Eqs. 8-10) takes the Gaussian ``exp(-(alpha l)^2)`` of
Ramamoorthi and Hanrahan; `ggx_lobe_spectrum` is GGX's own, the lobe of the
principled BSDF that renders the captures. The paper weights the filtered
light by Fresnel and masking at the view, ``F(theta_o) G1(theta_o)``;
`view_table` offers GGX's directional albedo instead (`ggx_specular_albedo`),
and the view dependence of the principled BSDF's diffuse lobe, which the paper
takes as Lambertian (`principled_diffuse_albedo`).
Kept apart from :mod:`freqbrdf.sphere.brdf`, which nearly every rule imports, so
that only the rules that fit the model depend on it.
"""

from __future__ import annotations

import functools

import numba
import numpy as np

from freqbrdf.sphere.brdf import ALPHA_MIN, smith_g1, tan2_theta
from freqbrdf.util.validation import check_choice, check_shape

__all__ = ["LOBES", "LOBE_NODES", "VIEW_WEIGHTS", "DIFFUSE_LOBES", "VIEW_NODES", "ggx_lobe_spectrum", "lobe_table",
           "ggx_specular_albedo", "principled_diffuse_albedo", "uniform_response", "view_table"]

LOBES = ("gaussian", "ggx")
"""The paper's ``exp(-(alpha l)^2)``, or GGX's own spectrum (`ggx_lobe_spectrum`)."""
LOBE_NODES = 256  # nodes of `lobe_table` over log alpha in [log ALPHA_MIN, 0]
VIEW_WEIGHTS = ("paper", "albedo")
"""The paper's ``F(theta_o) G1(theta_o)``, or GGX's directional albedo over the model's own (`view_table`)."""
DIFFUSE_LOBES = ("lambert", "principled")
"""The paper's Lambertian diffuse term, or the principled BSDF's view dependence (`principled_diffuse_albedo`)."""
VIEW_NODES = (64, 64)  # nodes of `view_table`: log alpha over [log ALPHA_MIN, 0], cos theta_o over (0, 1]


@numba.njit(cache=True)
def _legendre(n, z):  # pragma: no cover - compiled
    """``P_n(z)`` and ``P_n'(z)`` by the three-term recurrence (``|z| < 1``)."""
    p0, p1 = 1.0, z
    for k in range(2, n + 1):
        p0, p1 = p1, ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k
    return p1, n * (z * p1 - p0) / ((z - 1.0) * (z + 1.0))


@numba.njit(cache=True)
def _gauss_legendre(n):  # pragma: no cover - compiled
    """Gauss-Legendre nodes (ascending) and weights on [-1, 1]: Newton's iteration on ``P_n`` by its
    three-term recurrence from the asymptotic guess, as scipy's ``roots_legendre``, whose import
    (SciPy's special functions) a job would otherwise pay for these alone."""
    x = np.empty(n)
    w = np.empty(n)
    for i in range((n + 1) // 2):
        z = np.cos(np.pi * (i + 0.75) / (n + 0.5))
        for it in range(100):
            p1, slope = _legendre(n, z)
            step = p1 / slope
            z -= step
            if abs(step) <= 1e-16 * abs(z) and it:
                break
        slope = _legendre(n, z)[1]  # at the root itself: the weight needs it exact
        x[i], x[n - 1 - i] = -z, z
        w[i] = w[n - 1 - i] = 2.0 / ((1.0 - z) * (1.0 + z) * slope * slope)
    return x, w


@functools.cache
def _unit_interval_nodes(nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on [0, 1] (`_gauss_legendre`)."""
    x, w = _gauss_legendre(nodes)
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
    _check_unit_interval(a, "alpha", open_below=True)
    xi, w = _unit_interval_nodes(nodes)
    den = 1.0 + (a[:, None] ** 2 - 1.0) * xi
    t = 2.0 * (1.0 - xi) / den - 1.0  # cos theta, (A, n)
    dt_w = (-4.0 * w * xi * (1.0 - xi)) * a[:, None] / den**2  # dt / dalpha times the quadrature weights
    f = np.empty((a.size, lmax + 1))
    df = np.empty((a.size, lmax + 1))
    p_prev, p = np.ones_like(t), t.copy()  # P_0, P_1
    dp_prev, dp = np.zeros_like(t), np.ones_like(t)  # P_l' by P'_{l+1} = P'_{l-1} + (2l + 1) P_l
    scratch = np.empty_like(t)
    f[:, 0], df[:, 0] = 1.0, 0.0
    for l in range(1, lmax + 1):
        f[:, l] = p @ w
        df[:, l] = np.einsum("an,an->a", dp, dt_w)
        # the recurrences in place, each into the buffer of degree l - 1 (every job builds this
        # table: (A, n) temporaries per degree took twice as long)
        np.multiply(t, p, out=scratch)
        scratch *= (2 * l + 1) / (l + 1)
        p_prev *= -l / (l + 1)
        p_prev += scratch
        np.multiply(p, 2 * l + 1, out=scratch)
        dp_prev += scratch
        p_prev, p, dp_prev, dp = p, p_prev, dp, dp_prev
    return f, df


def lobe_table(lobe: str, lmax: int) -> np.ndarray:
    """The lobe spectrum as the compiled model reads it (`freqbrdf.estimate.optimise.kernels`).

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
    if check_choice(lobe, "lobe", LOBES) == "gaussian":
        return np.empty((0, 2, lmax + 1))
    alpha = np.exp(np.linspace(np.log(ALPHA_MIN), 0.0, LOBE_NODES))
    f, df = ggx_lobe_spectrum(alpha, lmax)
    return np.ascontiguousarray(np.stack([f, df * alpha[:, None]], axis=1))


def _check_unit_interval(values: np.ndarray, name: str, open_below: bool) -> None:
    """Raise naming the first of ``values`` outside [0, 1] (or (0, 1] if ``open_below``)."""
    bad = ~(((values > 0) if open_below else (values >= 0)) & (values <= 1))
    if np.any(bad):
        interval = "(0, 1]" if open_below else "[0, 1]"
        raise ValueError(f"{name} must be in {interval}, got {float(values[bad].flat[0])!r}")


def _shadowing(cos_theta: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Smith ``G1`` (`freqbrdf.sphere.brdf.smith_g1`) above the horizon, 0 at and below it."""
    return np.where(cos_theta > 0, smith_g1(tan2_theta(np.clip(cos_theta, 1e-12, 1.0)), alpha), 0.0)


def ggx_specular_albedo(alpha: np.ndarray, mu: np.ndarray, nodes: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """GGX's specular directional albedo under a uniform unit light, split as ``R0 A + B``.

    ``int f_s cos theta_i d omega_i`` of the microfacet BRDF that renders the
    captures (GGX, separable Smith masking-shadowing, Schlick's Fresnel at
    the half vector ``F = R0 + (1 - R0)(1 - o.h)^5``) is ``R0 A + B``, the
    split-sum factors of Karis (2013). Sampling half vectors from GGX's
    distribution of visible normals (Heitz 2018), whose density is
    ``G1(o) (o.h) D(h) / cos theta_o``, leaves ``G1(i)`` and the Fresnel factor as
    the integrand: ``A = E[G1(i) (1 - (1 - o.h)^5)]``, ``B = E[G1(i) (1 - o.h)^5]``,
    ``G1(i) = 0`` below the horizon. A product Gauss-Legendre rule in the
    sampler's two uniform variables evaluates them (within 3e-3 at 32 nodes).

    Parameters
    ----------
    alpha : numpy.ndarray
        Shape ``(A,)``: GGX widths in (0, 1].
    mu : numpy.ndarray
        Shape ``(M,)``: ``cos theta_o`` in (0, 1].
    nodes : int
        Gauss-Legendre nodes per variable.

    Returns
    -------
    A, B : numpy.ndarray
        Shape ``(A, M)``, float64, dimensionless.
    """
    a = np.asarray(alpha, dtype=np.float64)[:, None, None]
    m = np.asarray(mu, dtype=np.float64)[None, :, None]
    _check_unit_interval(a, "alpha", open_below=True)
    _check_unit_interval(m, "mu", open_below=True)
    u, w = _unit_interval_nodes(nodes)
    u1, u2 = (g.ravel() for g in np.meshgrid(u, u, indexing="ij"))
    weight = np.outer(w, w).ravel()
    # the view in the xz plane; the stretched view v, and the disc sample warped towards it
    ox = np.sqrt(1.0 - m * m)
    norm = np.sqrt((a * ox) ** 2 + m * m)
    vx, vz = a * ox / norm, m / norm
    t1 = np.sqrt(u1) * np.cos(2 * np.pi * u2)
    s = 0.5 * (1.0 + vz)
    t2 = (1.0 - s) * np.sqrt(1.0 - t1 * t1) + s * np.sqrt(u1) * np.sin(2 * np.pi * u2)
    up = np.sqrt(np.maximum(0.0, 1.0 - t1 * t1 - t2 * t2))
    # the hemisphere point in the frame (t1 along y, t2 along v x y, up along v), unstretched
    hx, hy, hz = a * (up * vx - t2 * vz), a * t1, np.maximum(up * vz + t2 * vx, 0.0)
    norm = np.sqrt(hx * hx + hy * hy + hz * hz)
    oh = np.clip((hx * ox + hz * m) / norm, 0.0, 1.0)
    g1_i = _shadowing(2.0 * oh * hz / norm - m, a)
    c5 = (1.0 - oh) ** 5
    return (g1_i * (1.0 - c5)) @ weight, (g1_i * c5) @ weight


def principled_diffuse_albedo(roughness: np.ndarray, mu: np.ndarray, nodes: int = 32) -> np.ndarray:
    """Directional albedo of the principled BSDF's diffuse lobe over a Lambertian's, under a uniform light.

    Mitsuba's ``principled`` (after Burley 2015) scales ``base / pi`` by
    ``(1 - F_i / 2)(1 - F_o / 2) + R (F_o + F_i + F_o F_i (R - 1))`` with the
    Schlick weights ``F = (1 - cos theta)^5`` and the retro-reflection
    ``R = 2 r cos^2 theta_d``, ``cos^2 theta_d = (1 + i.o) / 2``: darker than Lambert at
    grazing views when smooth, brighter when rough. The albedo ``(1 / pi) int (...) cos theta_i
    d omega_i`` is a quadratic in r, so only its three coefficients are integrated, per view, by
    a product Gauss-Legendre rule in ``cos theta_i`` and the azimuth (the integrand is a
    polynomial in ``cos theta_i``, its sine and ``cos phi``).

    Parameters
    ----------
    roughness : numpy.ndarray
        Shape ``(A,)``: principled roughness r in [0, 1].
    mu : numpy.ndarray
        Shape ``(M,)``: ``cos theta_o`` in (0, 1].

    Returns
    -------
    numpy.ndarray
        Shape ``(A, M)``, float64: 1 for a Lambertian lobe.
    """
    r = np.asarray(roughness, dtype=np.float64)[:, None]
    m = np.asarray(mu, dtype=np.float64)[:, None]
    _check_unit_interval(r, "roughness", open_below=False)
    _check_unit_interval(m, "mu", open_below=True)
    u, w = _unit_interval_nodes(nodes)
    cos_i, phi = (g.ravel() for g in np.meshgrid(u, np.pi * u, indexing="ij"))  # phi in [0, pi]: symmetric
    weight = 2.0 * np.outer(w, w).ravel() * cos_i  # cos theta_i d omega / pi, phi = pi u over [0, pi], twice
    d = 1 + cos_i * m + np.sqrt(1 - cos_i**2) * np.sqrt(1 - m * m) * np.cos(phi)  # (M, nodes^2): R = r d
    f_i, f_o = (1 - cos_i) ** 5, (1 - m) ** 5
    # shape = (1 - f_i / 2)(1 - f_o / 2) + r d (f_o + f_i - f_o f_i) + r^2 d^2 f_o f_i
    c0 = (1 - f_o[:, 0] / 2) * ((1 - f_i / 2) @ weight)
    c1 = (d * (f_o + f_i - f_o * f_i)) @ weight
    c2 = f_o[:, 0] * ((d * d * f_i) @ weight)
    return c0 + r * (c1 + r * c2)


def uniform_response(alpha: np.ndarray, mu: np.ndarray, lobe: str, lmax: int, nodes: int = 512) -> np.ndarray:
    """The model's filtered shadowed light ``Spec`` under a uniform unit environment, at view ``mu``.

    The shadowed light is then zonal about the normal, ``G1(cos theta; alpha)`` above the
    horizon and 0 below, with Legendre coefficients ``(2l + 1) / 2 c_l``,
    ``c_l = int_0^1 G1(x) P_l(x) dx``; the model filters them by ``f_l`` up to l* and
    reads them at the mirror direction, whose angle to the normal is the view's:
    ``S = sum_l f_l (2l + 1) / 2 c_l P_l(mu)``.

    Parameters
    ----------
    alpha : numpy.ndarray
        Shape ``(A,)``: GGX widths in (0, 1].
    mu : numpy.ndarray
        Shape ``(M,)``: ``cos theta_o`` in (0, 1].
    lobe : {"gaussian", "ggx"}
        See `LOBES`.
    lmax : int
        The model's degree l*.
    nodes : int
        Gauss-Legendre nodes for ``c_l``.

    Returns
    -------
    numpy.ndarray
        Shape ``(A, M)``, float64.
    """
    a = np.asarray(alpha, dtype=np.float64)
    check_choice(lobe, "lobe", LOBES)
    x, w = _unit_interval_nodes(nodes)
    f = np.exp(-((a[:, None] * np.arange(lmax + 1)) ** 2)) if lobe == "gaussian" else ggx_lobe_spectrum(a, lmax)[0]
    legendre = np.polynomial.legendre.legvander
    c = (_shadowing(x[None, :], a[:, None]) * w) @ legendre(x, lmax)  # (A, L)
    degree = (2 * np.arange(lmax + 1) + 1) / 2
    return (f * c * degree) @ legendre(np.asarray(mu, dtype=np.float64), lmax).T


@functools.cache
def _view_table(view_weight: str, diffuse: str, lobe: str, lmax: int) -> np.ndarray:
    n_alpha, n_mu = VIEW_NODES
    log_alpha = np.linspace(np.log(ALPHA_MIN), 0.0, n_alpha)
    alpha, mu = np.exp(log_alpha), np.linspace(0.0, 1.0, n_mu + 1)[1:]
    factor = principled_diffuse_albedo(np.sqrt(alpha), mu) if diffuse == "principled" else np.ones((n_alpha, n_mu))
    components = [factor]
    if view_weight == "albedo":
        rise, offset = ggx_specular_albedo(alpha, mu)
        response = uniform_response(alpha, mu, lobe, lmax)
        components = [rise / response, offset / response, factor]
    table = np.empty((n_alpha, 2, len(components), n_mu + 1))
    for k, value in enumerate(components):
        value = np.concatenate([value[:, :1], value], axis=1)  # mu = 0 holds mu = 1/64's (G1 and S vanish at 0)
        table[:, 0, k] = value
        table[:, 1, k] = np.gradient(value, log_alpha, axis=0, edge_order=2)
    table.flags.writeable = False
    return table


def view_table(view_weight: str, diffuse: str, lobe: str, lmax: int) -> np.ndarray:
    """The model's weights per view, as the compiled model reads them (`freqbrdf.estimate.optimise.kernels`).

    The paper (section 4.2) writes ``B = (1 - m) base E / pi + F(theta_o) G1(theta_o) Spec``:
    a Lambertian diffuse term, and the filtered light at the mirror direction weighted by
    Schlick's ``F = R0 + (1 - R0)(1 - cos theta_o)^5`` and masking. Both are options here.

    ``view_weight="paper"`` keeps that specular weight (the kernels' masking flag applies). It weights
    every view by the lobe's value at the mirror direction, while an oblique GGX lobe gathers more
    light (the projected area of its microfacets grows as ``1 / G1(theta_o)``) and leans towards
    the normal, where the horizon cuts it: at grazing views the model under-predicts rough metals
    by a factor of 2-5. ``"albedo"``: ``(R0 a + b) Spec`` with ``a = A / S`` and ``b = B / S``,
    GGX's directional albedo (`ggx_specular_albedo`) over the model's own response to a uniform
    light (`uniform_response`): the split-sum approximation (Karis 2013), exact under a uniform
    light, which keeps the light's frequency content at the mirror direction and takes the lobe's
    mass, masking and Fresnel from GGX.

    ``diffuse="lambert"`` is the paper's; ``"principled"`` scales ``E / pi`` by
    `principled_diffuse_albedo` (``d``), the view dependence of the diffuse lobe of Mitsuba's
    principled BSDF (darker than Lambert at grazing views when smooth, brighter when rough),
    exact under a uniform light.

    Parameters
    ----------
    view_weight : {"paper", "albedo"}
        See `VIEW_WEIGHTS`.
    diffuse : {"lambert", "principled"}
        See `DIFFUSE_LOBES`.
    lobe : {"gaussian", "ggx"}
        The model's lobe (`LOBES`).
    lmax : int
        The model's degree l*.

    Returns
    -------
    numpy.ndarray
        Shape ``(0, 2, 3, 0)`` for the paper's weights and diffuse, which the kernels
        evaluate in closed form; ``(VIEW_NODES[0], 2, 1, VIEW_NODES[1] + 1)`` for the paper's
        specular weight (closed form too) and the principled diffuse term ``d``; for the
        albedo ``(VIEW_NODES[0], 2, 3, VIEW_NODES[1] + 1)``, ``a``, ``b`` and ``d``.
        ``[i, 0, k, j]`` is the value and ``[i, 1, k, j]`` the derivative in ``log alpha`` of
        component k at ``log alpha`` evenly spaced over
        ``[log ALPHA_MIN, 0]`` and ``cos theta_o = j / VIEW_NODES[1]``: cubic Hermite in
        ``log alpha``, linear in ``cos theta_o``. Read-only (cached).
    """
    check_choice(view_weight, "view_weight", VIEW_WEIGHTS)
    check_choice(diffuse, "diffuse", DIFFUSE_LOBES)
    check_choice(lobe, "lobe", LOBES)
    if view_weight == "paper" and diffuse == "lambert":
        return np.empty((0, 2, 3, 0))
    return _view_table(view_weight, diffuse, lobe, int(lmax))
