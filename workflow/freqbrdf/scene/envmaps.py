"""Procedural environment maps with deliberately different frequency content.

Maps are equirectangular, shape (H, 2H, 3), linear radiance, on the grid of
:func:`freqbrdf.sphere.sampling.equirect_directions` (row 0 at the +Y pole, the last row at
-Y, which is how Mitsuba's ``envmap`` emitter reads a bitmap). Each kind:

- ``studio``: indoor; a dim room and a few large soft lights (low frequencies).
- ``museum``: indoor; dim walls and many small bright lamps (high frequencies).
- ``sunny``: Mitsuba's ``sunsky`` (Hosek-Wilkie sky and sun) baked by
  :func:`freqbrdf.scene.render.bake_emitter`, over a diffuse ground (very high
  frequencies: the sun is smaller than a pixel).
- ``overcast``: CIE standard overcast sky over a diffuse ground with a hazy
  horizon (almost only low frequencies).

Every map is scaled so its mean radiance over the sphere equals
``mean_radiance``, so captures under different environments are similarly exposed.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from freqbrdf.util.colour import LUMINANCE
from freqbrdf.sphere.sh import angles_to_directions, filter_equirect, power_spectrum, project_equirect
from freqbrdf.sphere.sampling import equirect_directions, equirect_solid_angles

ENV_KINDS = ("studio", "museum", "sunny", "overcast")


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def direction_from_angles(elevation_deg: float | np.ndarray, azimuth_deg: float | np.ndarray) -> np.ndarray:
    """World direction from elevation above the horizon and azimuth about +Y.

    Azimuth 0 points to -Z and 90 degrees to +X, matching the equirect
    parametrisation (column ``j`` at azimuth ``360 (j + 0.5) / W`` degrees).

    Returns
    -------
    ndarray, shape (..., 3)
    """
    return angles_to_directions(np.radians(90.0 - np.asarray(elevation_deg, dtype=np.float64)), np.radians(azimuth_deg))


def soft_disc(dirs: np.ndarray, centre: np.ndarray, radius_deg: float, edge: float = 0.3) -> np.ndarray:
    """Smooth indicator of a spherical cap (a round light).

    Parameters
    ----------
    dirs : ndarray, shape (..., 3)
        Unit directions.
    centre : ndarray, shape (3,)
        Unit direction of the cap's centre.
    radius_deg : float
        Angular radius of the cap in degrees.
    edge : float
        Width of the fall-off as a fraction of the radius.

    Returns
    -------
    ndarray, shape (...)
        1 inside the cap, 0 outside, smoothstep in between.
    """
    angle = np.degrees(np.arccos(np.clip(dirs @ centre, -1.0, 1.0)))
    inner = radius_deg * (1.0 - edge / 2.0)
    outer = radius_deg * (1.0 + edge / 2.0)
    t = np.clip((outer - angle) / max(outer - inner, 1e-9), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def mean_radiance(envmap: np.ndarray) -> np.ndarray:
    """Solid-angle weighted mean radiance per channel, shape (C,)."""
    h, w = envmap.shape[:2]
    weights = np.repeat(equirect_solid_angles(h, w)[:, None], w, axis=1)
    return np.einsum("hw,hwc->c", weights, envmap) / (4.0 * np.pi)


def horizontal_irradiance(envmap: np.ndarray) -> np.ndarray:
    """Irradiance on an upward-facing plane, per channel, shape (C,)."""
    h, w = envmap.shape[:2]
    dirs = equirect_directions(h, w)
    weights = np.repeat(equirect_solid_angles(h, w)[:, None], w, axis=1) * np.maximum(dirs[..., 1], 0.0)
    return np.einsum("hw,hwc->c", weights, envmap)


def add_ground(sky: np.ndarray, albedo: float, horizon_blur_deg: float) -> np.ndarray:
    """Replace the lower hemisphere by a Lambertian ground lit by the sky.

    The ground radiance is ``albedo * E / pi`` with ``E`` the horizontal
    irradiance of the upper hemisphere; sky and ground are blended across the
    horizon over ``horizon_blur_deg`` (haze), which also bounds the frequency
    content of the horizon edge.

    Parameters
    ----------
    sky : ndarray, shape (H, W, 3)
        Radiance; values below the horizon are ignored.
    albedo : float
        Ground reflectance in [0, 1].
    horizon_blur_deg : float
        Full width of the horizon blend in degrees (> 0).

    Returns
    -------
    ndarray, shape (H, W, 3)
    """
    h, w = sky.shape[:2]
    elevation = np.degrees(np.arcsin(np.clip(equirect_directions(h, w)[..., 1], -1.0, 1.0)))
    upper = np.where(elevation[..., None] > 0.0, sky, 0.0)
    ground = albedo * horizontal_irradiance(upper) / np.pi
    # The sky just above the horizon continues into the haze band, so blending
    # never dims the sky with its own (absent) values below the horizon.
    horizon_row = int(np.nonzero(elevation[:, 0] > 0.0)[0].max())
    sky_at_horizon = np.where(elevation[..., None] > 0.0, sky, sky[horizon_row][None])
    t = np.clip(0.5 + elevation / max(horizon_blur_deg, 1e-6), 0.0, 1.0)[..., None]
    t = t * t * (3.0 - 2.0 * t)
    return t * sky_at_horizon + (1.0 - t) * ground[None, None, :]


def studio(height: int, seed: int, lights: int = 3, light_radius_deg: float = 22.0, light_radiance: float = 8.0,
           light_elevation_deg: tuple[float, float] = (15.0, 60.0)) -> np.ndarray:
    """Indoor studio: a dim room lit by a few large soft lights.

    Parameters
    ----------
    height : int
        Map height H (width 2H).
    seed : int
        Seed of the light placement and tints.
    lights : int
        Number of area lights (key, fill, rim, ...).
    light_radius_deg : float
        Mean angular radius of a light in degrees (each varies by +-30%).
    light_radiance : float
        Radiance of a light relative to the room (before normalisation).
    light_elevation_deg : (float, float)
        Range the lights' elevations are drawn from, degrees above the horizon
        (negative: below it, lighting the object from underneath).

    Returns
    -------
    ndarray, shape (H, 2H, 3), float64
    """
    rng = np.random.default_rng(seed)
    dirs = equirect_directions(height, 2 * height)
    y = dirs[..., 1]
    # Brighter ceiling than floor, warm walls: a typical photo studio.
    room = (0.12 + 0.08 * y)[..., None] * np.array([1.0, 0.95, 0.88])
    env = room.copy()
    azimuths = rng.uniform(0.0, 360.0) + np.arange(lights) * 360.0 / lights + rng.uniform(-25.0, 25.0, lights)
    for az in azimuths:
        centre = direction_from_angles(rng.uniform(*light_elevation_deg), az)
        radius = light_radius_deg * rng.uniform(0.7, 1.3)
        tint = 1.0 + rng.uniform(-0.08, 0.08, 3)
        env += light_radiance * rng.uniform(0.5, 1.0) * soft_disc(dirs, centre, radius, edge=0.6)[..., None] * tint
    return env


def museum(height: int, seed: int, lamps: int = 9, lamp_radius_deg: float = 2.5, lamp_radiance: float = 400.0) -> np.ndarray:
    """Indoor museum: dim panelled walls and many small bright ceiling lamps.

    Parameters
    ----------
    height : int
        Map height H (width 2H).
    seed : int
        Seed of the lamp placement and the wall pattern.
    lamps : int
        Number of lamps.
    lamp_radius_deg : float
        Angular radius of a lamp in degrees.
    lamp_radiance : float
        Radiance of a lamp relative to the walls (before normalisation).

    Returns
    -------
    ndarray, shape (H, 2H, 3), float64
    """
    rng = np.random.default_rng(seed)
    dirs = equirect_directions(height, 2 * height)
    y = dirs[..., 1]
    azimuth = np.degrees(np.arctan2(dirs[..., 0], -dirs[..., 2]))
    # Framed paintings: bright and dark panels around the horizon.
    panel_count = int(rng.integers(6, 10))
    panel = (np.cos(np.radians(azimuth) * panel_count + rng.uniform(0, 2 * np.pi)) > 0.3) & (np.abs(y) < 0.35)
    walls = (0.08 + 0.04 * (y > 0)) * np.ones_like(y) + 0.06 * panel
    env = walls[..., None] * np.array([1.0, 0.9, 0.75])
    for _ in range(lamps):
        centre = direction_from_angles(rng.uniform(25.0, 80.0), rng.uniform(0.0, 360.0))
        tint = np.array([1.0, 0.93, 0.8]) * rng.uniform(0.6, 1.0)
        env += lamp_radiance * soft_disc(dirs, centre, lamp_radius_deg * rng.uniform(0.8, 1.2), edge=0.2)[..., None] * tint
    return env


def sunny(
    height: int,
    sky: Callable[[int, np.ndarray, float], np.ndarray],
    sun_elevation_deg: float = 40.0,
    sun_azimuth_deg: float = 60.0,
    turbidity: float = 3.0,
    ground_albedo: float = 0.25,
    horizon_blur_deg: float = 2.0,
) -> np.ndarray:
    """Clear sky with a sun over a diffuse ground.

    Parameters
    ----------
    height : int
        Map height H (width 2H).
    sky : callable
        ``sky(height, sun_direction, turbidity) -> (H, 2H, 3)`` radiance of the
        sky and sun, e.g. :func:`freqbrdf.scene.render.sunsky` bound to Mitsuba.
    sun_elevation_deg, sun_azimuth_deg : float
        Sun position (azimuth 0 toward -Z, 90 toward +X).
    turbidity : float
        Atmospheric turbidity.
    ground_albedo, horizon_blur_deg : float
        See :func:`add_ground`.

    Returns
    -------
    ndarray, shape (H, 2H, 3), float64
    """
    sun = direction_from_angles(sun_elevation_deg, sun_azimuth_deg)
    return add_ground(sky(height, sun, turbidity), ground_albedo, horizon_blur_deg)


def overcast(height: int, ground_albedo: float = 0.25, horizon_blur_deg: float = 12.0) -> np.ndarray:
    """CIE standard overcast sky, ``L(theta) = L_z (1 + 2 cos theta) / 3``, over a diffuse ground.

    Parameters
    ----------
    height : int
        Map height H (width 2H).
    ground_albedo : float
        Ground reflectance.
    horizon_blur_deg : float
        Width of the hazy horizon blend in degrees.

    Returns
    -------
    ndarray, shape (H, 2H, 3), float64
    """
    dirs = equirect_directions(height, 2 * height)
    sky = ((1.0 + 2.0 * np.maximum(dirs[..., 1], 0.0)) / 3.0)[..., None] * np.array([0.95, 0.98, 1.0])
    return add_ground(sky, ground_albedo, horizon_blur_deg)


def blur(envmap: np.ndarray, width: float) -> np.ndarray:
    """The map convolved with a zonal kernel whose SH degree ``l`` has gain ``exp(-(width l)^2)``.

    It is the low-pass filter by which a GGX lobe of ``alpha = width`` acts on the
    light in the paper's model (section 3.2): a surface of roughness alpha_1 under
    the blurred map reflects, to that model, what one of alpha_2 = sqrt(alpha_1^2
    + width^2) reflects under the sharp map (the light/material ambiguity).

    Parameters
    ----------
    envmap : ndarray, shape (H, 2H, 3)
        Equirectangular radiance.
    width : float
        Width of the kernel in the units of alpha (>= 0; 0 returns the map).

    Returns
    -------
    ndarray, shape (H, 2H, 3), float64
        Non-negative (the truncated kernel's small negative lobes are clipped).
    """
    if not width >= 0.0:
        raise ValueError(f"blur width must be >= 0, got {width}")
    if width == 0.0:
        return np.asarray(envmap, dtype=np.float64)
    # Degrees past 4 / width have gains below exp(-16): truncating there is exact to float32.
    lmax = min(int(np.ceil(4.0 / width)), envmap.shape[0] // 2)
    gains = np.exp(-((width * np.arange(lmax + 1)) ** 2))
    return np.maximum(filter_equirect(envmap, gains), 0.0)


def turn_envmap(envmap: np.ndarray, degrees: float) -> np.ndarray:
    """An equirect map turned about the up axis by whole columns (lossless).

    Parameters
    ----------
    envmap : ndarray, shape (H, W, C)
    degrees : float
        Rotation toward increasing azimuth; rounded to a whole column.

    Returns
    -------
    ndarray, shape (H, W, C)
    """
    return np.roll(envmap, int(round(degrees / 360.0 * envmap.shape[1])), axis=1)


def normalise(envmap: np.ndarray, target_mean: float) -> np.ndarray:
    """Scale ``envmap`` so its luminance-weighted mean radiance is ``target_mean``.

    Parameters
    ----------
    envmap : ndarray, shape (H, W, 3)
    target_mean : float
        Desired mean radiance over the sphere (> 0).

    Returns
    -------
    ndarray, shape (H, W, 3), float32
    """
    mean = float(mean_radiance(envmap) @ LUMINANCE)
    if not mean > 0.0:
        raise ValueError("environment map has no positive radiance")
    return (envmap * (target_mean / mean)).astype(np.float32)


def sh_spectrum(envmap: np.ndarray, lmax: int) -> np.ndarray:
    """Spherical-harmonics power spectrum of an environment map.

    Parameters
    ----------
    envmap : ndarray, shape (H, W, 3)
        Equirectangular radiance.
    lmax : int
        Highest degree.

    Returns
    -------
    ndarray, shape (lmax + 1, 4)
        Power ``S(l) = sum_m c_lm^2`` of the R, G, B channels and of luminance,
        in squared radiance units.
    """
    rgb = np.asarray(envmap, dtype=np.float64)
    channels = np.concatenate([rgb, (rgb @ LUMINANCE)[..., None]], axis=-1)
    return power_spectrum(project_equirect(channels, lmax))


def high_frequency_fraction(spectrum: np.ndarray, above: int) -> float:
    """Fraction of the power (degrees 0..lmax) that lies at degrees > ``above``.

    Parameters
    ----------
    spectrum : ndarray, shape (lmax + 1,)
        Power per degree of one channel.
    above : int
        Degrees strictly greater than this count as high frequency.
    """
    spectrum = np.asarray(spectrum, dtype=np.float64)
    return float(spectrum[above + 1 :].sum() / spectrum.sum())
