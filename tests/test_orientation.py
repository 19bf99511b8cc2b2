"""The environment-orientation check: SH azimuth rotation and the fit over rotations."""

import numpy as np
import pytest

from freqbrdf.scene.envmaps import studio
from freqbrdf.capture.orientation import (
    band_limited_coeffs,
    best_azimuth,
    explained_variance,
    irradiance_coeffs,
    rotate_azimuth,
)
from freqbrdf.sphere.sh import eval_sh, project_equirect
from freqbrdf.sphere.sampling import fibonacci_sphere

W = 64


@pytest.fixture(scope="module")
def env():
    return studio(W // 2, seed=3)


def test_rotating_the_coefficients_equals_rolling_the_map(env):
    lmax = 6
    for shift in (1, 5, 16, 37):
        rolled = project_equirect(np.roll(env, shift, axis=1), lmax)
        np.testing.assert_allclose(rotate_azimuth(project_equirect(env, lmax), 2 * np.pi * shift / W), rolled,
                                   atol=1e-9 * np.abs(rolled).max())
    many = rotate_azimuth(project_equirect(env, lmax), np.array([0.0, 2 * np.pi * 5 / W]))
    np.testing.assert_allclose(many[1], project_equirect(np.roll(env, 5, axis=1), lmax), atol=1e-9)


def test_explained_variance_of_a_perfect_and_an_anticorrelated_fit():
    rng = np.random.default_rng(0)
    group = np.repeat(np.arange(10), 5)
    irradiance, light = rng.uniform(1, 2, size=50), rng.uniform(size=50)
    radiance = 0.3 * irradiance + 2.0 * light
    both = explained_variance(radiance, np.stack([irradiance, irradiance], 1), np.stack([light, -light], 1), group)
    assert both[0] == pytest.approx(1.0) and both[1] < 0.9


def test_irradiance_of_a_constant_sky_is_pi_times_its_radiance():
    coeffs = project_equirect(np.ones((32, 64)), 4)
    e = eval_sh(irradiance_coeffs(coeffs), fibonacci_sphere(20))
    np.testing.assert_allclose(e, np.pi, rtol=1e-3)


def _observations(env, true_shift, rng, patches=40, texels=8, views=2, noise=0.02):
    """Pairs of a glossy object lit by the map turned by ``true_shift`` columns: few views per texel."""
    lum = env @ np.array([0.2126, 0.7152, 0.0722])
    coeffs = project_equirect(np.roll(lum, true_shift, axis=1), 8)
    n_tex = patches * texels
    normal = np.repeat(fibonacci_sphere(n_tex)[rng.permutation(n_tex)], views, axis=0)
    mirror = fibonacci_sphere(n_tex * views)[rng.permutation(n_tex * views)]
    group = np.repeat(np.arange(patches), texels * views)
    kd, ks = rng.uniform(0.1, 0.8, patches), rng.uniform(0.05, 0.5, patches)
    radiance = kd[group] * eval_sh(irradiance_coeffs(coeffs), normal) / np.pi
    radiance += ks[group] * eval_sh(band_limited_coeffs(coeffs, 0.3), mirror)
    return radiance * (1 + noise * rng.standard_normal(len(radiance))), normal, mirror, group


def test_a_turned_map_is_found_and_reported(env):
    rng = np.random.default_rng(1)
    given = project_equirect(env @ np.array([0.2126, 0.7152, 0.0722]), 8)
    radiance, normal, mirror, group = _observations(env, W // 4, rng)  # the scene's light is turned by 90 degrees
    result = best_azimuth(radiance, normal, mirror, group, given, 0.3, W)
    assert result["shift"] == W // 4 and result["degrees"] == 90.0
    assert result["clearly_worse"] and result["best"] > 0.9 > result["given"]
    radiance, normal, mirror, group = _observations(env, 0, rng)
    result = best_azimuth(radiance, normal, mirror, group, given, 0.3, W)
    assert result["shift"] == 0 and not result["clearly_worse"]
