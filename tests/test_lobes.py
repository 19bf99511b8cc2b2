"""Tests for freqbrdf.sphere.lobes: GGX's zonal SH spectrum, its weight per view, and the tables the compiled model reads."""

from __future__ import annotations

import numpy as np
import pytest
from test_light import ENVS

from freqbrdf.estimate.optimise import kernels
from freqbrdf.estimate import light as lt
from freqbrdf.estimate.optimise.kernels import KernelModel, PairData
from freqbrdf.estimate.optimise.model import forward, light_terms
from freqbrdf.estimate.optimise.problem import build_problem, pack_params
from freqbrdf.estimate.optimise.settings import OptimiseSettings
from freqbrdf.sphere.brdf import ALPHA_MIN
from freqbrdf.sphere.reference import ggx_radiance, smith_g1
from freqbrdf.studies.recovery_capture import capture_observations, oracle_capture
from freqbrdf.sphere.lobes import (
    DIFFUSE_LOBES,
    LOBE_NODES,
    VIEW_NODES,
    VIEW_WEIGHTS,
    ggx_lobe_spectrum,
    ggx_specular_albedo,
    lobe_table,
    principled_diffuse_albedo,
    uniform_response,
    view_table,
)


def ggx_spectrum_by_angles(alpha: float, lmax: int, n: int = 200_000) -> np.ndarray:
    """Independent oracle: Funk-Hecke integral of the normal-view GGX lobe ``D(h) / 4`` over the
    light direction's angle theta to the mirror direction (``theta_h = theta / 2``), midpoint rule."""
    theta = (np.arange(n) + 0.5) * np.pi / n
    ch = np.cos(theta / 2)
    d = alpha**2 / (np.pi * (ch**2 * (alpha**2 - 1) + 1) ** 2)
    weight = 2 * np.pi * d / 4 * np.sin(theta) * np.pi / n
    return np.array([weight @ np.polynomial.legendre.Legendre.basis(l)(np.cos(theta)) for l in range(lmax + 1)])


@pytest.mark.parametrize("alpha", [0.05, 0.3, 0.8])
def test_ggx_spectrum_matches_the_integral_over_angles(alpha: float) -> None:
    f, _ = ggx_lobe_spectrum(np.array([alpha]), 12)
    np.testing.assert_allclose(f[0], ggx_spectrum_by_angles(alpha, 12), atol=2e-5)
    assert f[0, 0] == 1.0  # the lobe conserves the light's power


def test_ggx_spectrum_derivative_and_limits() -> None:
    alpha = np.array([0.02, 0.2, 0.6])
    f, df = ggx_lobe_spectrum(alpha, 10)
    h = 1e-6
    fd = (ggx_lobe_spectrum(alpha + h, 10)[0] - ggx_lobe_spectrum(alpha - h, 10)[0]) / (2 * h)
    np.testing.assert_allclose(df, fd, atol=1e-6)
    # a narrow lobe passes every degree; GGX's long tails take more of the low degrees than the Gaussian
    assert ggx_lobe_spectrum(np.array([1e-3]), 10)[0].min() > 0.99
    assert f[2, 1] < np.exp(-(0.6**2)) - 0.3
    with pytest.raises(ValueError, match="alpha must be in \\(0, 1\\], got 0.0"):
        ggx_lobe_spectrum(np.array([0.3, 0.0]), 4)


def test_kernels_interpolate_the_table_between_its_nodes() -> None:
    """The model's f_l and df/dalpha at alphas between the nodes (the Hermite interpolant of
    `lobe_table`) against the spectrum computed there, through the model's radiance and gradient:
    one pair per texel, its light a single degree so that B = F sum_l f_l light_l picks f_l out."""
    lmax = 8
    table = lobe_table("ggx", lmax)
    assert table.shape == (LOBE_NODES, 2, lmax + 1)
    alpha = np.exp(np.random.default_rng(0).uniform(np.log(ALPHA_MIN), 0.0, 40))
    n = alpha.size * (lmax + 1)
    x = np.zeros((n, 5))
    x[:, 3] = np.sqrt(np.repeat(alpha, lmax + 1))
    light = np.zeros((n, lmax + 1, 3))
    light[np.arange(n), np.tile(np.arange(lmax + 1), alpha.size), :] = 1.0
    model = np.empty((n, 3))
    _, grad = kernels.l1_loss_gradient(x, light, PairData(np.arange(n + 1), np.full((n, 3), -1.0), np.zeros(n), np.zeros(n), np.zeros((n, 3))), KernelModel(False, lobe=table, r0_dielectric=1.0), model)
    f, df = ggx_lobe_spectrum(alpha, lmax)
    np.testing.assert_allclose(model[:, 0], f.ravel(), atol=1e-6)  # F = 1 (r0 1), no diffuse
    # dL/dr = 3 sign(B - B_obs) df/dalpha 2 r, all signs +1
    np.testing.assert_allclose(grad[:, 3] / (6.0 * x[:, 3]), df.ravel(), atol=1e-4, rtol=1e-3)


def test_gaussian_table_is_the_closed_form_and_bad_names_are_named() -> None:
    assert lobe_table("gaussian", 6).shape == (0, 2, 7)
    with pytest.raises(ValueError, match="lobe must be one of \\('gaussian', 'ggx'\\), got 'phong'"):
        lobe_table("phong", 6)
    with pytest.raises(ValueError, match="lobe must be a lobe_table of degree >= 8, got shape \\(256, 2, 5\\)"):
        kernels.l1_loss_gradient(np.zeros((1, 5)), np.zeros((1, 9, 3)), PairData(np.array([0, 1]), np.zeros((1, 3)), np.zeros(1), np.zeros(1), np.zeros((1, 3))), KernelModel(False, lobe=lobe_table("ggx", 4), r0_dielectric=0.04))


def specular_albedo_by_angles(alpha: float, mu: float, n: int = 1500) -> tuple[float, float]:
    """Independent oracle: ``int f_s cos theta_i d omega_i`` of the GGX microfacet BRDF over light
    directions (midpoint rule in theta_i, phi_i), split by Schlick's Fresnel into ``R0 A + B``."""
    theta = (np.arange(n) + 0.5) * (np.pi / 2) / n
    phi = (np.arange(2 * n) + 0.5) * np.pi / n
    t, p = np.meshgrid(theta, phi, indexing="ij")
    wi = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)
    wo = np.array([np.sqrt(1 - mu**2), 0.0, mu])
    half = wi + wo
    half /= np.linalg.norm(half, axis=-1, keepdims=True)
    d = alpha**2 / (np.pi * (half[..., 2] ** 2 * (alpha**2 - 1) + 1) ** 2)
    g = smith_g1(wi[..., 2], alpha) * smith_g1(mu, alpha)
    c5 = (1 - np.clip(half @ wo, 0, 1)) ** 5
    measure = d * g / (4 * mu) * np.sin(t) * (np.pi / 2 / n) * (np.pi / n)  # f_s cos theta_i d omega_i
    return float((measure * (1 - c5)).sum()), float((measure * c5).sum())


@pytest.mark.parametrize("alpha, mu", [(0.1, 0.9), (0.25, 0.3), (0.49, 0.6), (0.81, 0.1), (1.0, 0.5)])
def test_specular_albedo_matches_the_integral_over_light_directions(alpha: float, mu: float) -> None:
    a, b = ggx_specular_albedo(np.array([alpha]), np.array([mu]))
    np.testing.assert_allclose([a[0, 0], b[0, 0]], specular_albedo_by_angles(alpha, mu), atol=3e-3)


@pytest.mark.parametrize("roughness, mu", [(0.0, 0.9), (0.3, 0.2), (0.7, 0.55), (1.0, 0.05), (1.0, 1.0)])
def test_principled_diffuse_albedo_matches_the_integral_over_light_directions(roughness: float, mu: float) -> None:
    # Burley's diffuse shape times cos theta_i / pi, summed over a midpoint grid of the hemisphere
    n = 400
    t, p = np.meshgrid((np.arange(n) + 0.5) * np.pi / 2 / n, (np.arange(2 * n) + 0.5) * np.pi / n, indexing="ij")
    cos_io = np.cos(t) * mu + np.sin(t) * np.sqrt(1 - mu**2) * np.cos(p)
    f_i, f_o, retro = (1 - np.cos(t)) ** 5, (1 - mu) ** 5, roughness * (1 + cos_io)
    shape = (1 - f_i / 2) * (1 - f_o / 2) + retro * (f_o + f_i + f_o * f_i * (retro - 1))
    expected = (shape * np.cos(t) * np.sin(t)).sum() * (np.pi / 2 / n) * (np.pi / n) / np.pi
    both = principled_diffuse_albedo(np.array([roughness, 0.0]), np.array([mu]))
    np.testing.assert_allclose(both[0, 0], expected, rtol=1e-5)
    assert both[1, 0] <= 1.0  # smooth: never brighter than Lambert


def test_uniform_response_is_the_models_specular_term_under_a_uniform_light() -> None:
    """Under a constant unit environment, with R0 = 1 and the paper's weight without masking, the
    model's radiance is its filtered shadowed light alone: `uniform_response` at each view, which
    is computed from Legendre coefficients, not through the SH fit and shadowing of the light (whose
    quadrature of the horizon accounts for the few largest differences, at grazing views)."""
    env = np.ones((64, 128, 3))
    capture, truth = oracle_capture(env, seed=1)
    problem = build_problem(capture_observations(capture), lt.irradiance(env, capture["frame"][:, 2]), "float64")
    truth = truth | {"metallic": np.ones(truth["roughness"].size), "base_color": np.ones((truth["roughness"].size, 3))}
    for lobe in ("gaussian", "ggx"):
        light = light_terms(truth["roughness"], problem, True, lt.light_quadrature(env, 12))
        model = forward(pack_params(truth, problem.n_texels), problem, light, KernelModel(False, lobe_table(lobe, 12)))
        seen = capture["weight"] > 0
        expected = np.concatenate([uniform_response(np.array([r**2]), capture["wo_local"][t, seen[t], 2], lobe, 12)[0]
                                   for t, r in enumerate(truth["roughness"])])
        error = np.abs(model[seen][:, 0] / expected - 1)  # measured: median 1e-4, 95% 1.3e-3, max 0.021
        assert np.median(error) < 5e-4 and np.percentile(error, 95) < 3e-3 and error.max() < 0.03, lobe


def test_kernels_interpolate_the_view_table() -> None:
    """a and b as the model reads them (Hermite in log alpha, linear in cos theta_o) against
    `ggx_specular_albedo` / `uniform_response` at random points: a single degree-0 light of 1 makes
    the specular term ``R0 a + b``, so R0 = 1 (base 1, metallic 1) gives a + b and R0 = 0 gives b.
    Within 1.4% (the worst at roughness 0.17 near normal view, where the truncated lobe rings);
    the diffuse factor d within 0.2%; the derivative in alpha is that of the interpolant: central
    differences of the model."""
    rng = np.random.default_rng(3)
    n = 200
    roughness, mu = rng.uniform(0.1, 1.0, n), rng.uniform(0.05, 1.0, n)
    tan2 = (1 - mu**2) / mu**2
    view = view_table("albedo", "principled", "gaussian", 20)
    assert view.shape == (VIEW_NODES[0], 2, 3, VIEW_NODES[1] + 1)
    assert view_table("paper", "principled", "ggx", 20).shape == (VIEW_NODES[0], 2, 1, VIEW_NODES[1] + 1)
    assert view_table("paper", "lambert", "ggx", 20).size == 0  # the kernels' closed form

    def model(r: np.ndarray) -> np.ndarray:
        x = np.zeros((n, 5))
        x[:, 0], x[:, 3], x[:, 4] = 1.0, r, 1.0  # channel 0: R0 = 1; channels 1, 2: R0 = 0
        out = np.empty((n, 3))
        kernels.l1_loss_gradient(x, np.ones((n, 1, 3)), PairData(np.arange(n + 1), np.full((n, 3), -1.0), np.zeros(n), tan2, np.zeros((n, 3))), KernelModel(True, view=view), out)
        return out

    out = model(roughness)
    a = np.array([ggx_specular_albedo(np.array([r**2]), np.array([m]))[0][0, 0] for r, m in zip(roughness, mu)])
    b = np.array([ggx_specular_albedo(np.array([r**2]), np.array([m]))[1][0, 0] for r, m in zip(roughness, mu)])
    s = np.array([uniform_response(np.array([r**2]), np.array([m]), "gaussian", 20)[0, 0]
                  for r, m in zip(roughness, mu)])
    np.testing.assert_allclose(out[:, 0], (a + b) / s, rtol=0.015)
    np.testing.assert_allclose(out[:, 1], b / s, atol=4e-3)
    # the diffuse factor: no light, a white dielectric under E / pi = 1
    x = np.zeros((n, 5))
    x[:, :3], x[:, 3] = 1.0, roughness
    diffuse = np.empty((n, 3))
    kernels.l1_loss_gradient(x, np.zeros((n, 1, 3)), PairData(np.arange(n + 1), np.zeros((n, 3)), np.zeros(n), tan2, np.ones((n, 3))), KernelModel(True, view=view), diffuse)
    expected = np.array([principled_diffuse_albedo(np.array([r]), np.array([m]))[0, 0] for r, m in zip(roughness, mu)])
    np.testing.assert_allclose(diffuse[:, 0], expected, rtol=2e-3)
    x = np.zeros((n, 5))
    x[:, 0], x[:, 3], x[:, 4] = 1.0, roughness, 1.0
    _, grad = kernels.l1_loss_gradient(x, np.ones((n, 1, 3)), PairData(np.arange(n + 1), np.full((n, 3), -1.0), np.zeros(n), tan2, np.zeros((n, 3))), KernelModel(True, view=view))
    h = 1e-6
    fd = (model(roughness + h) - model(roughness - h)).sum(axis=1) / (2 * h)  # all signs +1
    np.testing.assert_allclose(grad[:, 3], fd, rtol=1e-5, atol=1e-8)


def test_albedo_weight_matches_ggx_under_a_uniform_light() -> None:
    """The split sum is exact under a uniform light: the model with the albedo weight and the
    principled diffuse term at the true parameters gives the brute-force radiance of the principled
    BSDF (`freqbrdf.sphere.reference.ggx_radiance`) for every observation within 2% (interpolation and truncation),
    where the paper's weights miss rough metals at grazing views by a factor of 2-5."""
    env = np.ones((64, 128, 3))
    capture, truth = oracle_capture(env, seed=0)
    ggx = ggx_radiance(env, capture, truth).sum(-1)
    problem = build_problem(capture_observations(capture), lt.irradiance(env, capture["frame"][:, 2]), "float64")
    light = light_terms(truth["roughness"], problem, True, lt.light_quadrature(env, 20))
    seen = capture["weight"] > 0
    ratio = {}
    for weight, diffuse in zip(VIEW_WEIGHTS, DIFFUSE_LOBES):
        model = forward(pack_params(truth, problem.n_texels), problem, light, KernelModel(True, lobe_table("ggx", 20), view_table(weight, diffuse, "ggx", 20)))
        ratio[weight] = model.sum(-1)[seen] / ggx[seen]
    assert np.abs(ratio["albedo"] - 1).max() < 0.02, np.abs(ratio["albedo"] - 1).max()
    metal = np.broadcast_to((truth["metallic"] == 1)[:, None] & (truth["roughness"] >= 0.7)[:, None], seen.shape)[seen]
    grazing = capture["wo_local"][..., 2][seen] < 0.3
    assert np.median(ratio["paper"][metal & grazing]) < 0.5


def test_view_weight_names_are_checked() -> None:
    with pytest.raises(ValueError, match="view_weight must be one of \\('paper', 'albedo'\\), got 'split'"):
        view_table("split", "lambert", "ggx", 20)
    with pytest.raises(ValueError, match="diffuse must be one of \\('lambert', 'principled'\\), got 'oren'"):
        view_table("paper", "oren", "ggx", 20)
    with pytest.raises(ValueError, match="view must be a view_table, got shape \\(3, 2, 2\\)"):
        kernels.l1_loss_gradient(np.zeros((1, 5)), np.zeros((1, 9, 3)), PairData(np.array([0, 1]), np.zeros((1, 3)), np.zeros(1), np.zeros(1), np.zeros((1, 3))), KernelModel(False, view=np.zeros((3, 2, 2)), r0_dielectric=0.04))
    with pytest.raises(ValueError, match="view_weight must be one of"):
        OptimiseSettings.paper(view_weight="albedos")
    with pytest.raises(ValueError, match="diffuse must be one of"):
        OptimiseSettings.paper(diffuse="oren")


@pytest.mark.parametrize("masking", [True, False])
def test_the_principled_diffuse_term_scales_the_papers_model(masking: bool) -> None:
    """With the principled diffuse term alone the table holds ``d`` only and the kernels keep the
    paper's specular weight ``F G1m`` (with or without masking): the model equals the closed-form
    one (empty table) with ``E / pi`` scaled by `principled_diffuse_albedo` at each texel's
    roughness and view, within the interpolation."""
    env = ENVS["studio"]()
    env = lt.downsample_equirect(env, 64)
    capture, truth = oracle_capture(env, seed=2)
    problem = build_problem(capture_observations(capture), lt.irradiance(env, capture["frame"][:, 2]), "float64")
    light = light_terms(truth["roughness"], problem, True, lt.light_quadrature(env, 12))
    x, lobe = pack_params(truth, problem.n_texels), lobe_table("ggx", 12)
    closed = forward(x, problem, light, KernelModel(masking, lobe))
    tabled = forward(x, problem, light, KernelModel(masking, lobe, view_table("paper", "principled", "ggx", 12)))
    diffuse = forward(x, problem, np.zeros_like(light), KernelModel(masking, lobe))  # no light: the diffuse term alone
    seen = capture["weight"] > 0
    factor = np.zeros(seen.shape)
    for t, r in enumerate(truth["roughness"]):
        factor[t, seen[t]] = principled_diffuse_albedo(np.array([r]), capture["wo_local"][t, seen[t], 2])[0]
    expected = closed + diffuse * (factor[..., None] - 1.0)
    np.testing.assert_allclose(tabled, expected, rtol=5e-3, atol=1e-5 * np.abs(expected).max())
    assert np.abs(tabled - closed).max() > 0.02 * np.abs(closed).max()  # the factor matters


def test_albedo_inputs_are_checked() -> None:
    with pytest.raises(ValueError, match="mu must be in \\(0, 1\\], got 0.0"):
        ggx_specular_albedo(np.array([0.3]), np.array([0.5, 0.0]))
    with pytest.raises(ValueError, match="roughness must be in \\[0, 1\\], got 1.5"):
        principled_diffuse_albedo(np.array([1.5]), np.array([0.5]))
    # a Lambertian-like limit: at normal view and roughness 0, 1 - 1/42 (the (1 - F_i / 2) factor alone)
    np.testing.assert_allclose(principled_diffuse_albedo(np.array([0.0]), np.array([1.0])), 1 - 1 / 42, rtol=1e-12)


@pytest.mark.parametrize("n", [1, 2, 3, 64, 2048])
def test_gauss_legendre_rule_integrates_polynomials_to_degree_2n_minus_1(n: int) -> None:
    from scipy.special import roots_legendre

    from freqbrdf.sphere.lobes import _gauss_legendre

    x, w = _gauss_legendre(n)
    np.testing.assert_allclose(x, roots_legendre(n)[0], rtol=0, atol=4e-16)
    for k in sorted({0, min(1, n - 1), n // 2, n - 1}):  # x^(2k) up to degree 2n - 2, exact: 2 / (2k + 1)
        assert (w * x ** (2 * k)).sum() == pytest.approx(2.0 / (2 * k + 1), rel=1e-12)
    if n == 2:
        np.testing.assert_allclose(x, [-1 / np.sqrt(3), 1 / np.sqrt(3)], rtol=1e-15)
        np.testing.assert_allclose(w, [1.0, 1.0], rtol=1e-15)
