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

The best of many rotations always beats the given one by something, so a gain
only counts when the capture's own patches agree on it: the patches are the
check's independent replicates (each has its own fit), and the best rotation
must fit better than the given one in significantly more patches than it fits
worse (a one-sided sign test, :func:`sign_test`). Where texture varies inside
the patches (the model holds ``K_d`` and ``K_s`` constant over a patch) and the
views are few, no rotation explains much of the variance and the best one is
chance: with 8 x 8-texel patches, ``config/tiny.yaml``'s re-imported sphere
capture (4 views of 32 pixels, a 32-texel atlas, 11 patches) explained 0.017 of
the within-patch variance as given and 0.099 turned by 151.9 degrees, the
turned map better in 6 patches and worse in 4 (p = 0.38), and it warned. The
patches are now a :data:`PATCH_GRID` x :data:`PATCH_GRID` grid over the atlas
whatever its resolution (:func:`patch_index`), so a small atlas has as many
replicates as a large one.
"""

from __future__ import annotations

import math

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
# ... and significantly so over the patches: the one-sided sign-test p-value of
# "the best rotation fits better in more patches than it fits worse" is below this.
MAX_P_VALUE = 0.01
# Patches per side of the atlas: PATCH_GRID x PATCH_GRID patches whatever its resolution.
PATCH_GRID = 8


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


def patch_residuals(radiance: np.ndarray, irradiance: np.ndarray, light: np.ndarray,
                    group: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Residual of the per-patch fit ``a E + b L`` (a, b >= 0) for each candidate, and each patch's variance.

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
    residual : ndarray, shape (G, S)
        Sum of squared residuals of each patch's fit.
    total : ndarray, shape (G,)
        Sum of squares of each patch's radiance about its mean.
    """
    n = int(group.max()) + 1
    count = np.maximum(np.bincount(group, minlength=n), 1).astype(np.float64)
    centred = radiance - (np.bincount(group, radiance, n) / count)[group]
    total = np.bincount(group, centred * centred, n)
    s_bb = np.bincount(group, radiance * radiance, n)
    residual = np.empty((n, light.shape[1]))
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
        residual[:, s] = np.minimum(np.minimum(both, only_e), np.minimum(only_l, s_bb))
    return residual, total


def explained_variance(radiance: np.ndarray, irradiance: np.ndarray, light: np.ndarray,
                       group: np.ndarray) -> np.ndarray:
    """Fraction of the within-group variance of ``radiance`` a per-group fit ``a E + b L`` (a, b >= 0) explains.

    Parameters
    ----------
    radiance, irradiance, light, group
        As in :func:`patch_residuals`.

    Returns
    -------
    ndarray, shape (S,)
        At most 1; below 0 where the fit is worse than a constant per group.
    """
    residual, total = patch_residuals(radiance, irradiance, light, group)
    if total.sum() <= 0.0:
        return np.zeros(light.shape[1])
    return 1.0 - residual.sum(axis=0) / total.sum()


def sign_test(better: int, worse: int) -> float:
    """One-sided sign-test p-value: the chance of ``better`` or more successes in
    ``better + worse`` fair coin tosses (1 when there are none)."""
    n = better + worse
    return math.fsum(math.comb(n, k) for k in range(better, n + 1)) / 2.0**n if n else 1.0


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


def _rotated_predictions(normal: np.ndarray, mirror: np.ndarray, env_coeffs: np.ndarray, a_prime: float,
                         shifts: np.ndarray, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Irradiance at the normals and band-limited light along the mirror directions, (P, S) each,
    for the map turned by each of ``shifts`` columns."""
    angles = 2.0 * np.pi * np.asarray(shifts, dtype=np.float64) / width
    rotated = rotate_azimuth(env_coeffs, angles)  # (S, n)
    light = real_sh(mirror, int(round(np.sqrt(len(env_coeffs)))) - 1) @ band_limited_coeffs(rotated.T, a_prime)
    irradiance = real_sh(normal, 2) @ irradiance_coeffs(rotated.T)
    return irradiance, light


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
    irradiance, light = _rotated_predictions(normal, mirror, env_coeffs, a_prime, shifts, width)
    return explained_variance(radiance, irradiance, light, group)


def best_azimuth(radiance: np.ndarray, normal: np.ndarray, mirror: np.ndarray, group: np.ndarray,
                 env_coeffs: np.ndarray, a_prime: float, width: int) -> dict:
    """The best column shift of the map, and whether the given orientation is clearly worse.

    A coarse pass scores :data:`COARSE_STEPS` rotations, then every column
    shift within one coarse step of the best is scored. The given orientation
    is clearly worse when the best explains :data:`MIN_GAIN` more of the
    variance, at least :data:`MIN_RELATIVE_GAIN` of the spread between the
    best and the median rotation, and the patches agree: the best fits better
    in significantly more of them than it fits worse (:func:`sign_test` below
    :data:`MAX_P_VALUE`; patches that fit both alike are left out).

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
        ``shift``), ``median`` (over the coarse rotations), ``patches_better``
        and ``patches_worse`` (patches the best rotation fits better and worse
        than the given one), ``p_value`` (their sign test), ``significant``
        (``p_value`` below :data:`MAX_P_VALUE`), ``clearly_worse`` (bool), and
        ``scores``: ``(shift, explained)`` pairs of every rotation scored.
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
    # Per patch, the best rotation's residual against the given one's.
    residual, _ = patch_residuals(radiance, *_rotated_predictions(normal, mirror, env_coeffs, a_prime,
                                                                  np.array([0, shift]), width), group)
    # Ties (the same fit, to rounding of the patch's sum of squares) count neither way.
    margin = 1e-9 * np.bincount(group, radiance * radiance, len(residual))
    better = int((residual[:, 1] < residual[:, 0] - margin).sum())
    worse = int((residual[:, 1] > residual[:, 0] + margin).sum())
    p_value = sign_test(better, worse)
    significant = bool(p_value < MAX_P_VALUE)
    return {
        "shift": shift,
        "degrees": 360.0 * shift / width,
        "given": given,
        "best": top,
        "median": median,
        "patches_better": better,
        "patches_worse": worse,
        "p_value": p_value,
        "significant": significant,
        "clearly_worse": bool(gain > MIN_GAIN and gain > MIN_RELATIVE_GAIN * (top - median) and significant),
        "scores": sorted(zip(shifts.tolist(), scores.tolist())),
    }


def summary(result: dict, pairs: int) -> str:
    """What :func:`best_azimuth` found, in words: the best rotation, the scores and the patches' verdict."""
    return (f"turned by {result['degrees']:.1f} degrees about the up axis it explains {result['best']:.3f} "
            f"of the within-patch variance, as given {result['given']:.3f} ({pairs} pairs); it fits better in "
            f"{result['patches_better']} patches and worse in {result['patches_worse']} "
            f"(sign test p = {result['p_value']:.2g}{'' if result['significant'] else ', not significant'})")


def patch_index(texel: np.ndarray, resolution: int) -> np.ndarray:
    """Patch of each texel (flat ``i * R + j``): a :data:`PATCH_GRID` x :data:`PATCH_GRID` grid over the atlas."""
    size = max(1, -(-resolution // PATCH_GRID))
    row, column = np.divmod(np.asarray(texel), resolution)
    return (row // size) * (-(-resolution // size)) + column // size


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
