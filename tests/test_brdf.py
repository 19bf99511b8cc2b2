"""Tests for freqbrdf.brdf (principled parameters <-> the model's lobes)."""

from __future__ import annotations

import numpy as np
import pytest

import oracles
from freqbrdf import brdf
# principled parameters
# --------------------------------------------------------------------------
def test_principled_round_trip() -> None:
    rng = np.random.default_rng(10)
    n = 200
    base = rng.uniform(0.04, 1.0, (n, 3))  # darker bases have two exact inverses
    roughness = rng.uniform(0, 1, n)
    metallic = np.concatenate([np.zeros(50), np.ones(50), rng.uniform(0, 1, 100)])
    kd, ks, alpha = oracles.lobes_from_principled(base, roughness, metallic)
    np.testing.assert_allclose(kd, (1 - metallic[:, None]) * base)
    np.testing.assert_allclose(ks, 0.04 * (1 - metallic[:, None]) + metallic[:, None] * base)
    np.testing.assert_allclose(alpha, roughness**2)
    b2, r2, m2 = brdf.principled_from_lobes(kd, ks, alpha)  # K_s per channel: exact for any material
    np.testing.assert_allclose(r2, roughness, atol=1e-12)
    np.testing.assert_allclose(m2, metallic, atol=1e-9)
    np.testing.assert_allclose(b2, base, atol=1e-9)
    # K_s as a scalar (luminance R0): dielectrics and grey metals round-trip exactly
    grey = np.repeat(base[:, :1], 3, axis=1)
    for b, m in ((base[:50], metallic[:50]), (grey[50:100], metallic[50:100]), (grey[100:], metallic[100:])):
        kd, ks, alpha = oracles.lobes_from_principled(b, roughness[: len(b)], m)
        b3, r3, m3 = brdf.principled_from_lobes(kd, ks @ np.array([0.2126, 0.7152, 0.0722]), alpha)
        np.testing.assert_allclose(m3, m, atol=1e-9)
        np.testing.assert_allclose(b3, b, atol=1e-9)
    # outside the model: everything stays in [0, 1] and finite
    b4, r4, m4 = brdf.principled_from_lobes(
        np.array([[0.0, 0.0, 0.0], [2.0, -1.0, 0.5], [0.3, 0.3, 0.3]]),
        np.array([0.0, 1.5, 0.01]),
        np.array([-0.1, 2.0, 0.5]),
    )
    for v in (b4, r4, m4):
        assert np.all((v >= 0) & (v <= 1))
    assert m4[2] == 0.0  # K_s below a dielectric's 0.04 -> dielectric


# --------------------------------------------------------------------------


def test_smith_g1_is_one_at_normal_incidence_and_falls_toward_grazing() -> None:
    alpha = np.array([1e-3, 0.1, 0.5, 1.0])[:, None]
    cos = np.linspace(1.0, 0.01, 50)[None, :]
    g1 = brdf.smith_g1(brdf.tan2_theta(cos), alpha)
    np.testing.assert_allclose(g1[:, 0], 1.0, rtol=0, atol=1e-15)
    assert np.all(np.diff(g1, axis=1) < 0)  # toward grazing
    assert np.all(np.diff(g1, axis=0)[:, 1:] < 0)  # rougher
    assert g1[-1, -1] < 0.03  # alpha 1 at 89.4 degrees
    # textbook value: alpha = 1, theta = 60 degrees -> tan^2 = 3, G1 = 2 / (1 + 2)
    assert brdf.smith_g1(brdf.tan2_theta(0.5), 1.0) == pytest.approx(2.0 / 3.0, rel=1e-14)
    np.testing.assert_allclose(brdf.smith_g1(brdf.tan2_theta(cos), alpha), oracles.smith_g1(cos, alpha), rtol=1e-13)


def test_alpha_is_clamped_with_a_straight_through_derivative() -> None:
    alpha, d = brdf.alpha_from_roughness(np.array([0.0, 0.01, 0.5, 1.0]))
    np.testing.assert_allclose(alpha, [brdf.ALPHA_MIN, brdf.ALPHA_MIN, 0.25, 1.0])
    np.testing.assert_allclose(d, [2 * np.sqrt(brdf.ALPHA_MIN), 2 * np.sqrt(brdf.ALPHA_MIN), 1.0, 2.0])


def test_schlick_fresnel_oracle_limits() -> None:
    r0 = np.array([0.04, 0.5, 0.9])
    np.testing.assert_allclose(oracles.schlick_fresnel(r0, 1.0), r0, rtol=1e-15)
    np.testing.assert_allclose(oracles.schlick_fresnel(r0, 0.0), 1.0, rtol=1e-15)
    assert oracles.schlick_fresnel(0.04, 0.5) == pytest.approx(0.04 + 0.96 / 32)




# --------------------------------------------------------------------------
# the BRDF itself (scored by freqbrdf.metrics.brdf_log_rmse)
# --------------------------------------------------------------------------
def test_ggx_ndf_is_normalised_over_projected_half_vectors() -> None:
    # int D(h) cos(theta_h) d(omega_h) = 1 for every width: a wrong exponent or factor breaks it
    theta = np.linspace(0.0, np.pi / 2, 400_001)
    for alpha in (0.03, 0.2, 0.7, 1.0):
        integrand = brdf.ggx_ndf(np.cos(theta), alpha) * np.cos(theta) * np.sin(theta) * 2 * np.pi
        assert np.trapezoid(integrand, theta) == pytest.approx(1.0, abs=2e-4)
    assert brdf.ggx_ndf(1.0, 0.1) == pytest.approx(1 / (np.pi * 0.01), rel=1e-14)


def test_principled_brdf_matches_an_evaluation_from_direction_vectors() -> None:
    rng = np.random.default_rng(3)
    n_texels, n_pairs = 5, 40
    base = rng.uniform(0, 1, (n_texels, 3))
    roughness = rng.uniform(0.1, 1, n_texels)  # above the alpha clamp, which the oracle lacks
    metallic = np.array([0.0, 1.0, *rng.uniform(0, 1, n_texels - 2)])
    wi, wo = rng.normal(size=(2, n_pairs, 3))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]) + 0.05, np.abs(wo[:, 2]) + 0.05  # above the surface
    wi, wo = wi / np.linalg.norm(wi, axis=1, keepdims=True), wo / np.linalg.norm(wo, axis=1, keepdims=True)
    h = (wi + wo) / np.linalg.norm(wi + wo, axis=1, keepdims=True)
    cos_d = np.sum(wi * h, axis=1)
    f = brdf.principled_brdf(base, roughness, metallic, wi[:, 2], wo[:, 2], h[:, 2], cos_d)
    assert f.shape == (n_texels, n_pairs, 3)
    kd, ks, alpha = oracles.lobes_from_principled(base, roughness, metallic)
    a = alpha[:, None]
    # D from the half vector's slope: alpha^2 / (pi cos^4 (alpha^2 + tan^2)^2)
    tan2_h = (h[:, 0] ** 2 + h[:, 1] ** 2) / h[:, 2] ** 2
    d = a**2 / (np.pi * h[:, 2] ** 4 * (a**2 + tan2_h) ** 2)
    g = oracles.smith_g1(wi[:, 2], a) * oracles.smith_g1(wo[:, 2], a)
    fresnel = oracles.schlick_fresnel(ks[:, None, :], cos_d[None, :, None])
    expected = kd[:, None, :] / np.pi + (d * g / (4 * wi[:, 2] * wo[:, 2]))[..., None] * fresnel
    np.testing.assert_allclose(f, expected, rtol=1e-10)
    # reciprocal: swapping the directions keeps the half vector and the angle to it
    np.testing.assert_allclose(brdf.principled_brdf(base, roughness, metallic, wo[:, 2], wi[:, 2], h[:, 2], cos_d), f)
    # the float type follows the cosines'
    assert brdf.principled_brdf(base, roughness, metallic, *(c.astype(np.float32) for c in
                                (wi[:, 2], wo[:, 2], h[:, 2], cos_d))).dtype == np.float32


def test_principled_brdf_refuses_directions_below_the_surface() -> None:
    ones = np.ones(2)
    with pytest.raises(ValueError, match=r"cos_o must be positive \(above the surface\), got -0.5"):
        brdf.principled_brdf(np.full((1, 3), 0.5), [0.5], [0.0], ones, np.array([1.0, -0.5]), ones, ones)
    with pytest.raises(ValueError, match=r"base_color must have shape \(\*, 3\)"):
        brdf.principled_brdf(np.full((1, 4), 0.5), [0.5], [0.0], ones, ones, ones, ones)
