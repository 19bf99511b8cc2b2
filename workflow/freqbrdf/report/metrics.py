"""Error metrics of recovered SVBRDFs: parameters and the BRDF they define against
ground-truth textures, the time to reach an error, and correlation of the uncertainty with the
error. Relit images against ground-truth renders: :mod:`freqbrdf.report.relight_metrics`."""

from __future__ import annotations

import warnings
from collections.abc import Mapping

import numpy as np

from freqbrdf.report.relight_metrics import psnr_l, ssim
from freqbrdf.sphere.brdf import R0_DIELECTRIC, TEXTURES, alpha_from_roughness, smith_g1, tan2_theta
from freqbrdf.util.validation import check_shape


def parameter_error_map(truth: dict[str, np.ndarray], estimate: dict[str, np.ndarray]) -> np.ndarray:
    """Per-texel squared parameter error: the texel-wise counterpart of ``parameter_mse``'s average.

    Each group's squared error (base colour averaged over its channels) is
    averaged over the three groups, so the mean of the map over a set of
    texels equals ``parameter_mse(...)["average"]`` (:func:`freqbrdf.sphere.brdf.parameter_mse`) over the same texels.

    Parameters
    ----------
    truth, estimate : dict
        ``base_color`` (R, R, 3), ``roughness`` (R, R), ``metallic`` (R, R).

    Returns
    -------
    ndarray, shape (R, R), float64
    """
    groups = []
    for name in TEXTURES:
        if truth[name].shape != estimate[name].shape:
            raise ValueError(f"parameter_error_map: {name} is {estimate[name].shape}, ground truth {truth[name].shape}")
        squared = (truth[name].astype(np.float64) - estimate[name].astype(np.float64)) ** 2
        groups.append(squared.mean(axis=2) if squared.ndim == 3 else squared)
    return np.mean(groups, axis=0)


# --------------------------------------------------------------------------
# BRDF space: the reflectance the parameters define, not the parameters
# --------------------------------------------------------------------------
# The full BRDF is composed here from brdf.py's parts rather than added to brdf.py:
# nearly every rule's script imports brdf.py, so editing it would rerun the whole benchmark.
def ggx_ndf(cos_h: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """GGX (Trowbridge-Reitz) microfacet distribution ``alpha^2 / (pi ((alpha^2 - 1) cos^2 theta_h + 1)^2)``.

    Parameters
    ----------
    cos_h : numpy.ndarray
        Cosine of the half vector's angle to the normal, in [0, 1], broadcastable with ``alpha``.
    alpha : numpy.ndarray
        GGX width (dimensionless, > 0).

    Returns
    -------
    numpy.ndarray
        Per steradian; ``1 / (pi alpha^2)`` at ``cos_h = 1``, ``1 / pi`` everywhere at ``alpha = 1``.
    """
    a2 = alpha * alpha
    q = (a2 - 1.0) * (cos_h * cos_h) + 1.0
    return a2 / (np.pi * q * q)


def principled_brdf(
    base_color: np.ndarray, roughness: np.ndarray, metallic: np.ndarray,
    cos_i: np.ndarray, cos_o: np.ndarray, cos_h: np.ndarray, cos_d: np.ndarray,
) -> np.ndarray:
    """The principled BRDF of the estimators, per texel and direction pair.

    ``f = (1 - m) base / pi + D(theta_h) G1(theta_i) G1(theta_o) F(theta_d) / (4 cos theta_i cos theta_o)``
    with GGX ``D`` (`ggx_ndf`) and Smith ``G1`` (`smith_g1`) of width
    `alpha_from_roughness`, and Schlick's ``F = R0 + (1 - R0)(1 - cos theta_d)^5``,
    ``R0 = 0.04 (1 - m) + m base``: the model whose spherical-harmonic form
    :mod:`freqbrdf.estimate.optimise` fits (it takes F at theta_o, which equals
    theta_d at the lobe's mirror peak). As there, the diffuse lobe is not
    reduced by the specular one's Fresnel.

    Parameters
    ----------
    base_color : numpy.ndarray
        Shape ``(T, 3)``, linear, in [0, 1].
    roughness, metallic : numpy.ndarray
        Shape ``(T,)``, in [0, 1].
    cos_i, cos_o : numpy.ndarray
        Shape ``(P,)``, cosines of the incoming and outgoing directions to the normal, in (0, 1].
    cos_h, cos_d : numpy.ndarray
        Shape ``(P,)``: of the half vector to the normal, and of the incoming direction to the half vector.

    Returns
    -------
    numpy.ndarray
        Shape ``(T, P, 3)`` (a view of a channels-first array), per steradian,
        in the float type of ``cos_i`` (float32 halves the time of the large arrays).
    """
    dtype = np.result_type(cos_i, np.float32)
    b = np.asarray(base_color).astype(dtype, copy=False)
    check_shape(b, "base_color", (None, 3))
    r, m = np.asarray(roughness), np.asarray(metallic).astype(dtype, copy=False)
    check_shape(r, "roughness", (b.shape[0],))
    check_shape(m, "metallic", (b.shape[0],))
    directions = [np.asarray(c).astype(dtype, copy=False) for c in (cos_i, cos_o, cos_h, cos_d)]
    for name, c in zip(("cos_i", "cos_o", "cos_h", "cos_d"), directions):
        check_shape(c, name, (directions[0].shape[0],))
    ci, co, ch, cd = directions
    for name, c in (("cos_i", ci), ("cos_o", co)):
        if not np.all(c > 0):
            raise ValueError(f"principled_brdf: {name} must be positive (above the surface), got {float(c[~(c > 0)][0])}")
    alpha = alpha_from_roughness(r)[0].astype(dtype)[:, None]
    specular = ggx_ndf(ch, alpha) * smith_g1(tan2_theta(ci), alpha) * smith_g1(tan2_theta(co), alpha) / (4 * ci * co)
    # channels first while computing: numpy's inner loops then run over the P pairs, not over 3 channels
    r0 = (R0_DIELECTRIC * (1 - m) + m * b.T)[:, :, None]
    s5 = (1 - cd) ** 5
    diffuse = ((1 - m) * b.T / dtype.type(np.pi))[:, :, None]
    return np.moveaxis(diffuse + specular * (r0 + (1 - r0) * s5), 0, -1)


BRDF_GRID = (12, 12, 6)
"""Sample counts of theta_h, theta_d and phi_d of `brdf_directions` (646 pairs above the surface)."""
_BRDF_CHUNK = 64  # texels per evaluation: its (64, P, 3) float32 arrays stay in cache (3x faster than 512)


def brdf_directions(grid: tuple[int, int, int] = BRDF_GRID) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The fixed direction pairs `brdf_log_rmse` compares BRDFs over, as cosines.

    A grid in Rusinkiewicz's half/difference angles, laid out as MERL's
    measured BRDFs are (the data 002 and NBRDF score on): midpoints
    ``theta_h = (pi / 2) ((j + 1/2) / n_h)^2`` (MERL's square-root spacing,
    dense at the specular peak: the first at 0.16 degrees, the width of the
    sharpest GGX lobe, alpha = 0.003), ``theta_d = (pi / 2) (k + 1/2) / n_d``
    and ``phi_d = pi (l + 1/2) / n_phi``; ``phi_h`` is irrelevant to an
    isotropic BRDF. Pairs with a direction at or below the horizon are
    dropped. ``phi_d -> pi - phi_d`` swaps the incoming and outgoing
    directions, so every pair's reverse is in the set too.

    Parameters
    ----------
    grid : tuple of int
        ``(n_h, n_d, n_phi)``, each at least 1.

    Returns
    -------
    cos_i, cos_o, cos_h, cos_d : ndarray, shape (P,), float64
        Cosines of the incoming and outgoing directions and of the half
        vector to the normal, and of the incoming direction to the half vector.
    """
    if len(grid) != 3 or any(int(n) != n or n < 1 for n in grid):
        raise ValueError(f"brdf_directions: grid must be three counts >= 1, got {grid}")
    n_h, n_d, n_phi = grid
    theta_h = 0.5 * np.pi * ((np.arange(n_h) + 0.5) / n_h) ** 2
    theta_d = 0.5 * np.pi * (np.arange(n_d) + 0.5) / n_d
    phi_d = np.pi * (np.arange(n_phi) + 0.5) / n_phi
    th, td, pd = (a.ravel() for a in np.meshgrid(theta_h, theta_d, phi_d, indexing="ij"))
    # the difference vector (theta_d, phi_d) about the half vector (theta_h, phi_h = 0), tilted to the normal frame
    along, across = np.cos(th) * np.cos(td), np.sin(th) * np.sin(td) * np.cos(pd)
    cos_i, cos_o = along - across, along + across
    above = (cos_i > 0) & (cos_o > 0)
    return cos_i[above], cos_o[above], np.cos(th)[above], np.cos(td)[above]


def _texel_parameters(textures: Mapping[str, np.ndarray], texels: np.ndarray) -> tuple[np.ndarray, ...]:
    """Base colour (N, 3), roughness (N,) and metallic (N,) of the selected texels."""
    n = np.shape(textures["roughness"])[0] * np.shape(textures["roughness"])[1]
    return (np.reshape(textures["base_color"], (n, 3))[texels], np.reshape(textures["roughness"], n)[texels],
            np.reshape(textures["metallic"], n)[texels])


# The columns of `texel_parameter_columns` each texture takes.
PARAMETER_COLUMNS = {"base_color": slice(0, 3), "roughness": slice(3, 4), "metallic": slice(4, 5)}


def texel_parameter_columns(textures: Mapping[str, np.ndarray], texels: np.ndarray) -> np.ndarray:
    """The five parameters of the selected texels side by side, as the optimiser orders them.

    Parameters
    ----------
    textures : mapping
        Atlases ``base_color`` (R, R, 3), ``roughness`` and ``metallic`` (R, R): an SVBRDF, or
        its posterior's standard deviations.
    texels : numpy.ndarray
        Shape ``(N,)``: flat atlas indices.

    Returns
    -------
    numpy.ndarray
        Shape ``(N, 5)``, float64: base R, G, B, roughness, metallic (`PARAMETER_COLUMNS`).
    """
    base, roughness, metallic = _texel_parameters(textures, texels)
    return np.column_stack([base, roughness, metallic]).astype(np.float64)


def brdf_log_rmse(truth: dict[str, np.ndarray], estimate: dict[str, np.ndarray], texels: np.ndarray,
                  grid: tuple[int, int, int] = BRDF_GRID) -> float:
    """RMS difference of ``log(1 + f cos theta_i)`` between the true and the estimated BRDF.

    ``f`` is the principled BRDF the textures define (:func:`principled_brdf`),
    evaluated per texel on the fixed pairs of :func:`brdf_directions`. The
    cosine weighting and the log keep the specular peak (up to 1e5 per
    steradian) from drowning the rest of the lobe; they are the transform
    with which neural BRDFs are fitted to MERL (NBRDF, Sztrajman et al. 2021,
    whose comparison 002 follows; 002's text states only MSE on the raw
    samples). The mean of the squares is over pairs and
    colour channels per texel, then over the texels (as ``parameter_mse``
    averages), and its square root is returned. A base-colour/metallic trade
    that parameter MSE punishes is visible here only as far as it changes
    the reflectance.

    Parameters
    ----------
    truth, estimate : dict
        ``base_color`` (R, R, 3), ``roughness`` (R, R), ``metallic`` (R, R) in [0, 1].
    texels : ndarray, shape (N,), int
        Flat indices ``i * R + j`` of the texels to score.
    grid : tuple of int
        Direction grid (:func:`brdf_directions`).

    Returns
    -------
    float
        Dimensionless (a log of reflected fraction); 0 for identical textures.
    """
    return float(np.sqrt(brdf_log_error(truth, estimate, texels, grid).mean()))


def brdf_log_error(truth: dict[str, np.ndarray], estimate: dict[str, np.ndarray], texels: np.ndarray,
                   grid: tuple[int, int, int] = BRDF_GRID) -> np.ndarray:
    """Per texel, the mean square of :func:`brdf_log_rmse`'s log difference (over pairs and channels).

    Returns
    -------
    ndarray, shape (N,), float64
        One value per entry of ``texels``.
    """
    texels = np.asarray(texels)
    if len(texels) == 0:
        raise ValueError("brdf_log_rmse: no texels to score")
    for name in TEXTURES:
        if truth[name].shape != estimate[name].shape:
            raise ValueError(f"brdf_log_rmse: {name} is {estimate[name].shape}, ground truth {truth[name].shape}")
    n = truth["roughness"].shape[0] * truth["roughness"].shape[1]
    if texels.min() < 0 or texels.max() >= n:
        raise ValueError(f"brdf_log_rmse: texel {texels[(texels < 0) | (texels >= n)][0]} outside the {n} texels")
    # float32: the texture-by-pairs arrays dominate the time; means stay float64
    cosines = tuple(c.astype(np.float32) for c in brdf_directions(grid))
    weight = cosines[0][None, :, None]
    params = _texel_parameters(truth, texels), _texel_parameters(estimate, texels)
    out = np.empty(len(texels))
    for start in range(0, len(texels), _BRDF_CHUNK):
        part = slice(start, start + _BRDF_CHUNK)
        logs = [np.log1p(principled_brdf(*(p[part] for p in side), *cosines) * weight) for side in params]
        out[part] = np.square(logs[1] - logs[0]).mean(axis=(1, 2), dtype=np.float64)
    return out


def base_color_si_scores(truth: np.ndarray, estimate: np.ndarray, texels: np.ndarray) -> dict[str, float]:
    """PSNR and SSIM of the base colour after a per-channel least-squares scale (Stanford-ORB's material track).

    The estimate is scaled per channel to the truth over the scored texels
    (:func:`freqbrdf.report.relight_metrics.channel_scale`, in linear values),
    both are clipped to [0, 1] and sRGB-encoded as base colour textures are
    stored and viewed, and compared as :func:`freqbrdf.report.relight_metrics.psnr_l`
    and :func:`freqbrdf.report.relight_metrics.ssim` compare relit images (peak 1;
    SSIM's window runs over the texture atlas, its mean over the scored texels).
    An albedo scale that light and reflectance cannot tell apart costs nothing.

    Parameters
    ----------
    truth, estimate : ndarray, shape (R, R, 3)
        Linear base colour in [0, 1].
    texels : ndarray, shape (N,), int
        Flat indices ``i * R + j`` of the texels to score.

    Returns
    -------
    dict
        ``psnr`` (dB, ``inf`` if equal after the scale) and ``ssim`` (at most 1).
    """
    t = np.asarray(truth)
    if t.ndim != 3 or t.shape[0] != t.shape[1]:
        raise ValueError(f"base_color_si_scores: ground truth is {t.shape}, expected (R, R, 3)")
    mask = np.zeros(t.shape[0] * t.shape[1], dtype=bool)
    mask[np.asarray(texels)] = True
    mask = mask.reshape(t.shape[:2])
    return {"psnr": psnr_l(estimate, t, mask), "ssim": ssim(estimate, t, mask)}


def time_to_reach(elapsed_s: np.ndarray, mse: np.ndarray, target: float) -> float:
    """First time at which a convergence curve reaches ``mse <= target``, linearly
    interpolated between its samples; NaN if it never does.

    Parameters
    ----------
    elapsed_s : ndarray, shape (N,)
        Increasing optimisation times (s) of the samples, the first usually 0 (the start).
    mse : ndarray, shape (N,)
        Parameter MSE at those times.
    target : float
        The MSE to reach (e.g. another method's).

    Returns
    -------
    float
        Seconds; 0 if the first sample already reaches it.
    """
    t, e = np.asarray(elapsed_s, dtype=np.float64), np.asarray(mse, dtype=np.float64)
    if t.ndim != 1 or t.shape != e.shape or t.size == 0:
        raise ValueError(f"time_to_reach: elapsed_s {t.shape} and mse {e.shape} must be the same non-empty 1-D shape")
    if np.any(np.diff(t) < 0):
        raise ValueError("time_to_reach: elapsed_s must not decrease")
    hit = np.nonzero(e <= target)[0]
    if hit.size == 0:
        return float("nan")
    i = int(hit[0])
    if i == 0:
        return float(t[0])
    # between sample i - 1 (above the target) and i (at or below it)
    return float(t[i - 1] + (t[i] - t[i - 1]) * (e[i - 1] - target) / (e[i - 1] - e[i]))


# A differentiable-rendering run counts as converged when its last epoch lowered the parameter
# MSE by less than this fraction (the criterion of the verdicts: a baseline at full strength).
CONVERGED_CHANGE = 0.01


def last_epoch_change(mse: np.ndarray) -> float:
    """Relative fall of a convergence curve over its last step: ``(mse[-2] - mse[-1]) / mse[-2]``.

    Parameters
    ----------
    mse : ndarray, shape (N,)
        Parameter MSE after each epoch, the first the start (N >= 2).

    Returns
    -------
    float
        Positive while the curve still falls; 0 or less once it stalls or rises.
    """
    e = np.asarray(mse, dtype=np.float64)
    if e.ndim != 1 or e.size < 2:
        raise ValueError(f"last_epoch_change: needs at least two epochs' MSE, got shape {e.shape}")
    if not e[-2] > 0:
        raise ValueError(f"last_epoch_change: the MSE before the last epoch must be positive, got {e[-2]}")
    return float((e[-2] - e[-1]) / e[-2])


def is_converged(mse: np.ndarray, lr_decay: str) -> bool:
    """Whether a differentiable-rendering run converged: its last epoch lowered the MSE by less
    than :data:`CONVERGED_CHANGE`, at a constant learning rate.

    A decaying rate (``lr_decay`` other than ``none``) makes the last epoch's steps small by
    construction, so its change says nothing of convergence: such a run never counts.

    Parameters
    ----------
    mse : ndarray, shape (N,)
        Parameter MSE after each epoch, the first the start.
    lr_decay : str
        Config ``mitsuba.lr_decay`` of the run.
    """
    return lr_decay == "none" and last_epoch_change(mse) < CONVERGED_CHANGE


def pearson(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson's r of two equally long samples (`scipy.stats.pearsonr`); NaN if either is constant."""
    # imported here: scipy.stats takes 0.9 s to import, and most users of this module never correlate
    from scipy.stats import ConstantInputWarning, pearsonr

    a, b = np.asarray(a, dtype=np.float64).ravel(), np.asarray(b, dtype=np.float64).ravel()
    if a.shape != b.shape:
        raise ValueError(f"samples differ in length: {a.size} and {b.size}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConstantInputWarning)
        return float(pearsonr(a, b).statistic)
