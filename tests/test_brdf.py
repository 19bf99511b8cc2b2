"""Tests for freqbrdf.sphere.brdf (principled parameters <-> the model's lobes)."""

from __future__ import annotations

import numpy as np
import pytest

import oracles
from freqbrdf.sphere import brdf, reference
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
    np.testing.assert_allclose(brdf.smith_g1(brdf.tan2_theta(cos), alpha), reference.smith_g1(cos, alpha), rtol=1e-13)


def test_alpha_is_clamped_with_a_straight_through_derivative() -> None:
    alpha, d = brdf.alpha_from_roughness(np.array([0.0, 0.01, 0.5, 1.0]))
    np.testing.assert_allclose(alpha, [brdf.ALPHA_MIN, brdf.ALPHA_MIN, 0.25, 1.0])
    np.testing.assert_allclose(d, [2 * np.sqrt(brdf.ALPHA_MIN), 2 * np.sqrt(brdf.ALPHA_MIN), 1.0, 2.0])


def test_schlick_fresnel_oracle_limits() -> None:
    r0 = np.array([0.04, 0.5, 0.9])
    np.testing.assert_allclose(oracles.schlick_fresnel(r0, 1.0), r0, rtol=1e-15)
    np.testing.assert_allclose(oracles.schlick_fresnel(r0, 0.0), 1.0, rtol=1e-15)
    assert oracles.schlick_fresnel(0.04, 0.5) == pytest.approx(0.04 + 0.96 / 32)


