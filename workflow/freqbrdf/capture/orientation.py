"""Does a capture's environment map face the right way? A fit over azimuth rotations.

A real capture's environment map is only as useful as its orientation: a map
turned about the up axis lights the object from the wrong side, and every
estimate silently absorbs the mistake. The observations themselves say which
way the map faces. Under the reflection-as-convolution model (paper section 3.2,
Eq. 8) a texel's radiance is ``B_k = K_d E(p) + K_s F(theta_o) [S_alpha * L](w_r,k)``:
the diffuse term is the same in every view of the texel, so only the
view-dependent variation of ``B`` carries the orientation, and it must follow
the band-limited environment ``L'`` along the mirror directions ``w_r,k``.

For each candidate rotation the check fits, per patch of neighbouring texels,
``B = a E(n) + b L'(w_r)`` with non-negative ``a`` and ``b`` (a patch's
``K_d``, and its ``K_s F``, taken as constant) and scores the fraction of the
within-patch variance of ``B`` explained. Patches rather than single texels,
because a sparse capture sees most texels in one or two views only: across a
patch the normals differ, so the irradiance ``E(n)`` carries the orientation
as well as the mirror term. Rotations are cheap in the spherical-harmonic
domain (paper section 3.1): turning a map by ``delta`` about +Y mixes only the
``(l, m)`` and ``(l, -m)`` coefficients, by the angle ``m delta``, so the SH
basis is evaluated at the normals and mirror directions once for all rotations.
"""

from __future__ import annotations

import numpy as np

from freqbrdf.sphere.sh import real_sh, sh_degrees

# Rotations scored in the coarse pass (then refined to single map columns).
COARSE_STEPS = 72
# "Clearly worse": the given orientation explains this much less of the
# view-dependent variance than the best one, in absolute terms, and at least
# this fraction of the spread between the best and a typical (median) rotation,
# so neither noise on a near-uniform map nor a tiny gap on a strong one warns.
MIN_GAIN = 0.02
MIN_RELATIVE_GAIN = 0.25


def rotate_azimuth(coeffs: np.ndarray, angle: float | np.ndarray) -> np.ndarray:
    """SH coefficients of a map turned by ``angle`` about +Y (toward increasing azimuth).

    Turning by one column of a ``W``-column equirect map (``2 pi / W``) equals
    ``np.roll(map, 1, axis=1)``.

    Parameters
    ----------
    coeffs : ndarray, shape (n, ...)
        Real SH coefficients, ``n = (lmax + 1)^2``, in :mod:`freqbrdf.sphere.sh` order.
    angle : float or ndarray, shape (S,)
        Rotation in radians.

    Returns
    -------
    ndarray, shape (n, ...) or (S, n, ...)
    """
    coeffs = np.asarray(coeffs, dtype=np.float64)
    lmax = int(round(np.sqrt(len(coeffs)))) - 1
    angles = np.atleast_1d(np.asarray(angle, dtype=np.float64))
    out = np.repeat(coeffs[None], len(angles), axis=0)
    shape = (len(angles),) + (1,) * (coeffs.ndim - 1)
    for l in range(1, lmax + 1):
        for m in range(1, l + 1):
            cos_i, sin_i = l * l + l + m, l * l + l - m  # Y_lm ~ cos(m phi), Y_l,-m ~ sin(m phi)
            c, s = np.cos(m * angles).reshape(shape), np.sin(m * angles).reshape(shape)
            a, b = coeffs[cos_i], coeffs[sin_i]
            # f(phi - delta): a cos m(phi - d) + b sin m(phi - d), expanded
            out[:, cos_i] = a * c - b * s
            out[:, sin_i] = a * s + b * c
    return out if np.ndim(angle) else out[0]


def explained_variance(radiance: np.ndarray, irradiance: np.ndarray, light: np.ndarray,
                       group: np.ndarray) -> np.ndarray:
    """Fraction of the within-group variance of ``radiance`` a per-group fit ``a E + b L`` (a, b >= 0) explains.

    Parameters
    ----------
    radiance : ndarray, shape (P,)
        Observed radiance of P (texel, view) pairs.
    irradiance, light : ndarray, shape (P, S)
        Predicted irradiance at each pair's normal and light along its mirror
        direction, for S candidates.
    group : ndarray, shape (P,), int
        Patch of each pair, in ``0..G-1``.

    Returns
    -------
    ndarray, shape (S,)
        At most 1; below 0 where the fit is worse than a constant per group.
    """
    n = int(group.max()) + 1
    count = np.maximum(np.bincount(group, minlength=n), 1).astype(np.float64)
    centred = radiance - (np.bincount(group, radiance, n) / count)[group]
    total = float(centred @ centred)
    if total <= 0.0:
        return np.zeros(light.shape[1])
    s_bb = np.bincount(group, radiance * radiance, n)
    explained = np.empty(light.shape[1])
    for s in range(light.shape[1]):
        e, l = irradiance[:, s], light[:, s]
        s_ee, s_ll, s_el = (np.bincount(group, x * y, n) for x, y in ((e, e), (l, l), (e, l)))
        s_eb, s_lb = np.bincount(group, e * radiance, n), np.bincount(group, l * radiance, n)
        # Non-negative least squares in two unknowns: the best of the free fit
        # (when both come out >= 0) and each regressor alone.
        det = s_ee * s_ll - s_el**2
        safe = np.where(det > 1e-12 * np.maximum(s_ee * s_ll, 1e-300), det, np.inf)
        a, b = (s_ll * s_eb - s_el * s_lb) / safe, (s_ee * s_lb - s_el * s_eb) / safe
        both = np.where((a >= 0) & (b >= 0) & np.isfinite(safe), s_bb - a * s_eb - b * s_lb, np.inf)
        only_e = s_bb - np.maximum(s_eb, 0.0) ** 2 / np.maximum(s_ee, 1e-300)
        only_l = s_bb - np.maximum(s_lb, 0.0) ** 2 / np.maximum(s_ll, 1e-300)
        residual = np.minimum(np.minimum(both, only_e), np.minimum(only_l, s_bb))
        explained[s] = 1.0 - residual.sum() / total
    return explained


def irradiance_coeffs(coeffs: np.ndarray) -> np.ndarray:
    """Irradiance SH coefficients (degrees 0-2) from radiance ones: the clamped-cosine
    convolution, ``A_0 = pi``, ``A_1 = 2 pi / 3``, ``A_2 = pi / 4`` (Ramamoorthi and
    Hanrahan 2001, the ``E(p)`` of paper Eq. 8).

    Parameters
    ----------
    coeffs : ndarray, shape (n, ...), n >= 9

    Returns
    -------
    ndarray, shape (9, ...)
    """
    gain = np.repeat([np.pi, 2.0 * np.pi / 3.0, np.pi / 4.0], [1, 3, 5])
    return coeffs[:9] * gain.reshape((-1,) + (1,) * (np.ndim(coeffs) - 1))


def azimuth_scores(radiance: np.ndarray, normal: np.ndarray, mirror: np.ndarray, group: np.ndarray,
                   env_coeffs: np.ndarray, a_prime: float, shifts: np.ndarray, width: int) -> np.ndarray:
    """Explained variance for the map turned by each of ``shifts`` columns.

    Parameters
    ----------
    radiance : ndarray, shape (P,)
        Observed luminance of P (texel, view) pairs.
    normal, mirror : ndarray, shape (P, 3)
        World normals and mirror directions of the pairs (Y-up).
    group : ndarray, shape (P,), int
        Patch of each pair.
    env_coeffs : ndarray, shape (n,)
        SH coefficients of the map's luminance (``lmax >= 2``).
    a_prime : float
        Band limit of the mirror term (:func:`band_limited_coeffs`).
    shifts : ndarray, shape (S,), int
        Rotations as ``np.roll`` column shifts of a map ``width`` columns wide.
    width : int
        Map width W.

    Returns
    -------
    ndarray, shape (S,)
    """
    angles = 2.0 * np.pi * np.asarray(shifts, dtype=np.float64) / width
    rotated = rotate_azimuth(env_coeffs, angles)  # (S, n)
    light = real_sh(mirror, int(round(np.sqrt(len(env_coeffs)))) - 1) @ band_limited_coeffs(rotated.T, a_prime)
    irradiance = real_sh(normal, 2) @ irradiance_coeffs(rotated.T)
    return explained_variance(radiance, irradiance, light, group)


def best_azimuth(radiance: np.ndarray, normal: np.ndarray, mirror: np.ndarray, group: np.ndarray,
                 env_coeffs: np.ndarray, a_prime: float, width: int) -> dict:
    """The best column shift of the map, and whether the given orientation is clearly worse.

    A coarse pass scores :data:`COARSE_STEPS` rotations, then every column
    shift within one coarse step of the best is scored.

    Parameters
    ----------
    radiance, normal, mirror, group, env_coeffs, a_prime, width
        As in :func:`azimuth_scores`.

    Returns
    -------
    dict
        ``shift`` (int, columns, in ``0..W-1``; ``np.roll(map, shift, axis=1)``
        turns the map into its best orientation), ``degrees`` (the same as an
        angle), ``given`` and ``best`` (explained variance at shift 0 and at
        ``shift``), ``median`` (over the coarse rotations), ``clearly_worse``
        (bool), and ``scores``: ``(shift, explained)`` pairs of every rotation scored.
    """
    step = max(1, width // COARSE_STEPS)
    coarse = np.arange(0, width, step)
    coarse_scores = azimuth_scores(radiance, normal, mirror, group, env_coeffs, a_prime, coarse, width)
    centre = int(coarse[np.argmax(coarse_scores)])
    fine = np.array([(centre + d) % width for d in range(-step + 1, step) if d != 0], dtype=np.int64)
    fine_scores = azimuth_scores(radiance, normal, mirror, group, env_coeffs, a_prime, fine, width) if len(fine) else np.zeros(0)
    shifts = np.concatenate([coarse, fine])
    scores = np.concatenate([coarse_scores, fine_scores])
    best = int(np.argmax(scores))
    given, top, median = float(coarse_scores[0]), float(scores[best]), float(np.median(coarse_scores))
    gain = top - given
    shift = int(shifts[best])
    return {
        "shift": shift,
        "degrees": 360.0 * shift / width,
        "given": given,
        "best": top,
        "median": median,
        "clearly_worse": bool(gain > MIN_GAIN and gain > MIN_RELATIVE_GAIN * (top - median)),
        "scores": sorted(zip(shifts.tolist(), scores.tolist())),
    }


def band_limited_coeffs(coeffs: np.ndarray, a_prime: float) -> np.ndarray:
    """SH coefficients low-passed by the paper's filter ``exp(-(a' l)^2)`` (Eq. 9, section 4.2).

    Parameters
    ----------
    coeffs : ndarray, shape (n, ...)
    a_prime : float
        Band-limit width (> 0).
    """
    degrees = sh_degrees(int(round(np.sqrt(len(coeffs)))) - 1).astype(np.float64)
    gain = np.exp(-((a_prime * degrees) ** 2))
    return coeffs * gain.reshape((-1,) + (1,) * (np.ndim(coeffs) - 1))
