"""Environment maps: frequency content, normalisation and the ground model."""

import functools

import numpy as np
import pytest

from freqbrdf.scene import envmaps
from freqbrdf.scene.render import sunsky
from freqbrdf.sphere.sampling import equirect_directions

HEIGHT = 128


@pytest.fixture(scope="module")
def maps(mi):
    return {
        "studio": envmaps.normalise(envmaps.studio(HEIGHT, seed=1), 1.0),
        "museum": envmaps.normalise(envmaps.museum(HEIGHT, seed=2), 1.0),
        "sunny": envmaps.normalise(envmaps.sunny(HEIGHT, sky=functools.partial(sunsky, mi)), 1.0),
        "overcast": envmaps.normalise(envmaps.overcast(HEIGHT), 1.0),
    }


def test_overcast_has_far_less_high_frequency_power_than_sunny(maps):
    frac = {name: envmaps.high_frequency_fraction(envmaps.sh_spectrum(m, 12)[:, 3], 4) for name, m in maps.items()}
    assert frac["overcast"] < 0.01
    assert frac["sunny"] > 0.5
    assert frac["overcast"] < frac["sunny"] / 50
    # small lamps carry more high frequencies than large soft lights
    assert frac["museum"] > 2 * frac["studio"] > 2 * frac["overcast"]


def test_maps_are_normalised_finite_and_positive(maps):
    for env in maps.values():
        assert env.shape == (HEIGHT, 2 * HEIGHT, 3) and env.dtype == np.float32
        assert np.isfinite(env).all() and env.min() >= 0.0
        assert float(envmaps.mean_radiance(env) @ envmaps.LUMINANCE) == pytest.approx(1.0, rel=1e-5)




def test_ground_radiance_is_albedo_times_sky_irradiance_over_pi():
    # Under a unit sky the horizontal irradiance is pi, so the ground shows the albedo.
    env = envmaps.add_ground(np.ones((128, 256, 3)), albedo=0.3, horizon_blur_deg=4.0)
    dirs = equirect_directions(128, 256)
    np.testing.assert_allclose(env[dirs[..., 1] < -0.2], 0.3, rtol=2e-3)
    np.testing.assert_allclose(env[dirs[..., 1] > 0.2], 1.0, rtol=1e-12)
    assert envmaps.horizontal_irradiance(np.ones((256, 512, 3)))[0] == pytest.approx(np.pi, rel=1e-3)


def test_cie_overcast_profile():
    env = envmaps.overcast(128, ground_albedo=0.2, horizon_blur_deg=1.0)
    dirs = equirect_directions(128, 256)
    zenith, mid = env[0, 0, 1], env[np.argmin(np.abs(dirs[:, 0, 1] - 0.5)), 0, 1]
    # L(theta) proportional to (1 + 2 cos theta): zenith / (cos = 0.5) = 3 / 2
    assert zenith / mid == pytest.approx(1.5, rel=0.02)


def test_soft_disc_is_one_inside_zero_outside():
    centre = np.array([0.0, 1.0, 0.0])
    dirs = np.array([[0.0, 1.0, 0.0], envmaps.direction_from_angles(90 - 5, 0.0), envmaps.direction_from_angles(90 - 20, 0.0)])
    values = envmaps.soft_disc(dirs, centre, radius_deg=10.0, edge=0.2)
    np.testing.assert_allclose(values, [1.0, 1.0, 0.0])
