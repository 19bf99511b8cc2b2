"""The environment-orientation check: SH azimuth rotation and the fit over rotations."""

import numpy as np
import pytest

from freqbrdf.envmaps import studio
from freqbrdf.orientation import band_limited_coeffs, best_azimuth, explained_variance, rotate_azimuth
from freqbrdf.sh import eval_sh, fibonacci_sphere, project_equirect

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
    group = np.repeat(np.arange(10), 5)
    light = np.random.default_rng(0).uniform(size=50)
    radiance = 0.3 + 2.0 * light
    np.testing.assert_allclose(explained_variance(radiance, np.stack([light, -light], 1), group), [1.0, 0.0])


def _observations(env, true_shift, rng, n_texels=300, views=8, noise=0.02):
    """Pairs of a glossy object lit by the map turned by ``true_shift`` columns."""
    lum = env @ np.array([0.2126, 0.7152, 0.0722])
    coeffs = band_limited_coeffs(project_equirect(np.roll(lum, true_shift, axis=1), 8), 0.3)
    mirror = fibonacci_sphere(n_texels * views)[rng.permutation(n_texels * views)]
    group = np.repeat(np.arange(n_texels), views)
    kd, ks = rng.uniform(0.1, 0.8, n_texels), rng.uniform(0.05, 0.5, n_texels)
    radiance = kd[group] * 2.0 + ks[group] * eval_sh(coeffs, mirror)
    return radiance + noise * rng.standard_normal(len(radiance)), mirror, group


def test_a_turned_map_is_found_and_reported(env):
    rng = np.random.default_rng(1)
    lum = env @ np.array([0.2126, 0.7152, 0.0722])
    given = band_limited_coeffs(project_equirect(lum, 8), 0.3)
    radiance, mirror, group = _observations(env, W // 4, rng)  # the scene's light is turned by 90 degrees
    result = best_azimuth(radiance, mirror, group, given, W)
    assert result["shift"] == W // 4 and result["degrees"] == 90.0
    assert result["clearly_worse"] and result["best"] > 0.9 > result["given"]
    radiance, mirror, group = _observations(env, 0, rng)
    result = best_azimuth(radiance, mirror, group, given, W)
    assert result["shift"] == 0 and not result["clearly_worse"]
