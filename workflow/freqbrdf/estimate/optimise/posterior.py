"""A per-texel posterior of the fitted parameters: the Laplace (Gauss-Newton) approximation.

The entropy of the spectrum search (paper section 5, Eq. 23) scores how well the light
constrains a texel's lobe before anything is fitted; it cannot see whether the fitted model
explains the texel's observations. This posterior uses what the fit shows. Around the
estimate ``x`` (5 parameters), with ``J`` the Jacobian of the texel's model radiance over its
observed pairs and channels and ``r`` its residuals,

    precision = J^T J / s^2 + prior I,     s^2 = |r|^2 / (3 n - 5),

``n`` the texel's observed views: the curvature of its least-squares misfit scaled by the
residual variance it leaves (a texel the model fits badly is less sure), plus a prior as wide
as a uniform on [0, 1] (precision 12), so that an unconstrained direction (a rough metal against
a diffuse dielectric under soft light) stays bounded. Its diagonal, scaled by ``variance_scale``
(a calibration of the interval's coverage, fitted on the tuning set), gives each parameter's
variance. The light terms are held fixed, as in the fit (the shadowing follows roughness only
at refits).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from freqbrdf.estimate.optimise.settings import N_PARAMS
from freqbrdf.sphere.brdf import TEXTURES

__all__ = ["PRIOR_PRECISION", "prior_variance", "model_jacobian", "pair_information", "residual_variance",
           "pooled_residual_variance", "laplace_variance", "posterior_variance", "expected_error", "expected_error_atlas"]

PRIOR_PRECISION = 12.0  # 1 / variance of a uniform on [0, 1]
_STEP = 1e-4  # finite-difference step of the Jacobian (parameters in [0, 1])


def prior_variance(variance_scale: float = 1.0) -> float:
    """The variance of a texel no view observes: the prior's, scaled as every variance is."""
    return variance_scale / PRIOR_PRECISION


def model_jacobian(radiance, xp: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The model radiance of every pair and its Jacobian in the texel's parameters, by finite differences.

    Parameters
    ----------
    radiance : callable
        ``radiance(xp) -> (N, 3)``: the model radiance of the N pairs at internal-order
        parameters ``xp`` (`freqbrdf.estimate.optimise.model.ForwardModel.radiance`).
    xp : numpy.ndarray
        Shape ``(T, 5)``, parameters in internal order (observed texels first).
    start : numpy.ndarray
        Shape ``(T_obs + 1,)``: first pair of each observed texel.

    Returns
    -------
    model : numpy.ndarray
        Shape ``(N, 3)``.
    jacobian : numpy.ndarray
        Shape ``(N, 3, 5)``: d radiance / d (base R, G, B, roughness, metallic) of the pair's texel.
    """
    slot = np.repeat(np.arange(start.shape[0] - 1), np.diff(start))
    model = radiance(xp)
    jacobian = np.empty(model.shape + (N_PARAMS,))
    for q in range(N_PARAMS):
        moved = xp.copy()
        step = np.where(moved[:, q] > 0.5, -_STEP, _STEP)  # inwards, so the step stays in [0, 1]
        moved[:, q] += step
        jacobian[..., q] = (radiance(moved) - model) / step[slot][:, None]
    return model, jacobian


def pair_information(jacobian: np.ndarray) -> np.ndarray:
    """Each pair's ``J^T J`` summed over its channels, the curvature it adds to its texel's misfit.

    Parameters
    ----------
    jacobian : numpy.ndarray
        Shape ``(N, 3, 5)`` (`model_jacobian`).

    Returns
    -------
    numpy.ndarray
        Shape ``(N, 5, 5)``, float64.
    """
    jacobian = np.asarray(jacobian, dtype=np.float64)
    return np.einsum("ncq,ncr->nqr", jacobian, jacobian)


def _texel_information(jacobian: np.ndarray, start: np.ndarray, block: int = 4096) -> np.ndarray:
    """`pair_information` summed over each observed texel's pairs (``start``, (T_obs + 1,)):
    shape ``(T_obs, 5, 5)``. ``block`` texels at a time, so that the (pairs, 5, 5) products
    stay in cache instead of a whole capture's (hundreds of MB) being written and read once."""
    n_obs = start.shape[0] - 1
    out = np.empty((n_obs, N_PARAMS, N_PARAMS))
    for a in range(0, n_obs, block):
        b = min(n_obs, a + block)
        out[a:b] = np.add.reduceat(pair_information(jacobian[start[a] : start[b]]), start[a:b] - start[a])
    return out


def _degrees_of_freedom(pairs: np.ndarray) -> np.ndarray:
    """``3 n - 5`` of texels with n pairs each (3 channels, 5 parameters); negative below 2 pairs."""
    return 3 * pairs - N_PARAMS


def residual_variance(residual: np.ndarray, slot: np.ndarray, n_slots: int) -> np.ndarray:
    """Per texel, the variance its fit leaves: ``|r|^2 / (3 n - 5)`` over its n pairs.

    Parameters
    ----------
    residual : numpy.ndarray
        Shape ``(N, 3)``: model minus observed radiance of each pair.
    slot : numpy.ndarray
        Shape ``(N,)``, int: each pair's texel, in ``[0, n_slots)``.
    n_slots : int
        Number of texels.

    Returns
    -------
    numpy.ndarray
        Shape ``(n_slots,)``: at least 1 degree of freedom is assumed, and the variance is at least 1e-12.
    """
    squares = np.bincount(slot, (np.asarray(residual, dtype=np.float64) ** 2).sum(axis=1), minlength=n_slots)
    return _variance_left(squares, np.bincount(slot, minlength=n_slots))


def _variance_left(squares: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """``squares / (3 n - 5)`` per texel of n ``pairs``, at least 1 degree of freedom and at least 1e-12."""
    return np.maximum(squares / np.maximum(_degrees_of_freedom(pairs), 1), 1e-12)


def pooled_residual_variance(residual: np.ndarray, slot: np.ndarray) -> float:
    """The variance the fit leaves over every texel at once: ``sum |r|^2 / sum (3 n_t - 5)``.

    For texels with too few pairs to have a variance of their own; ``residual`` and ``slot``
    as for `residual_variance` (every texel that has a pair spends 5 degrees of freedom).
    At least 1e-12; raises if there is no pair.
    """
    slot = np.asarray(slot, dtype=np.int64)
    if slot.size == 0:
        raise ValueError("pooled_residual_variance: no pair")
    pairs = np.bincount(slot)
    dof = max(int(_degrees_of_freedom(pairs[pairs > 0]).sum()), 1)
    return max(float((np.asarray(residual, dtype=np.float64) ** 2).sum() / dof), 1e-12)


def laplace_variance(radiance, xp: np.ndarray, observed: np.ndarray, start: np.ndarray,
                     variance_scale: float = 1.0) -> np.ndarray:
    """Posterior variance of every parameter of the observed texels (module docstring).

    Parameters
    ----------
    radiance, xp, start
        As for `model_jacobian`; ``radiance`` over the observed pairs.
    observed : numpy.ndarray
        Shape ``(N, 3)``: the observed radiance of the pairs.
    variance_scale : float
        Factor on every variance (> 0).

    Returns
    -------
    numpy.ndarray
        Shape ``(T_obs, 5)``, float64: variances of base R, G, B, roughness, metallic.
    """
    model, jacobian = model_jacobian(radiance, xp, start)
    n_obs = start.shape[0] - 1
    squares = np.bincount(np.repeat(np.arange(n_obs), np.diff(start)),
                          ((model - np.asarray(observed, dtype=np.float64)) ** 2).sum(axis=1), minlength=n_obs)
    return posterior_variance(_texel_information(jacobian, start), squares, np.diff(start), variance_scale)


def posterior_variance(curvature: np.ndarray, squares: np.ndarray, pairs: np.ndarray,
                       variance_scale: float = 1.0) -> np.ndarray:
    """The Laplace posterior's variances (module docstring) from each texel's misfit.

    Parameters
    ----------
    curvature : numpy.ndarray
        Shape ``(T, 5, 5)``: ``J^T J`` of each texel's model radiance over its pairs and channels
        (`freqbrdf.estimate.optimise.kernels.texel_information`, or `pair_information` summed).
    squares : numpy.ndarray
        Shape ``(T,)``: each texel's squared residual summed over its pairs and channels.
    pairs : numpy.ndarray
        Shape ``(T,)``, int: each texel's observed pairs.
    variance_scale : float
        Factor on every variance (> 0).

    Returns
    -------
    numpy.ndarray
        Shape ``(T, 5)``, float64: variances of base R, G, B, roughness, metallic.
    """
    _check_scale(variance_scale)
    s2 = _variance_left(np.asarray(squares, dtype=np.float64), np.asarray(pairs))
    precision = np.asarray(curvature, dtype=np.float64) / s2[:, None, None] + PRIOR_PRECISION * np.eye(N_PARAMS)
    return variance_scale * np.diagonal(np.linalg.inv(precision), axis1=1, axis2=2).copy()


def _check_scale(variance_scale: float) -> None:
    if not (np.isfinite(variance_scale) and variance_scale > 0):
        raise ValueError(f"variance_scale must be a finite number > 0, got {variance_scale!r}")


def expected_error(variance: np.ndarray) -> np.ndarray:
    """The expected squared parameter error of texels with these posterior variances (T, 5): the
    mean over base colour (its channels averaged), roughness and metallic, as
    `freqbrdf.report.metrics.parameter_error_map` averages the squared errors."""
    v = np.asarray(variance, dtype=np.float64)
    return (v[:, :3].mean(axis=1) + v[:, 3] + v[:, 4]) / 3.0


def expected_error_atlas(std: Mapping[str, np.ndarray]) -> np.ndarray:
    """`expected_error` of every texel of an estimate's posterior deviation atlases.

    Parameters
    ----------
    std : mapping
        Posterior standard deviations as `freqbrdf.artefacts.read_posterior_std` returns
        them: ``base_color`` (R, R, 3), ``roughness`` and ``metallic`` (R, R); the prior's
        where no view observes the texel, so those texels score worst.

    Returns
    -------
    ndarray, shape (R, R), float64
    """
    shape = np.shape(std["roughness"])
    variance = np.column_stack([np.asarray(std[g], np.float64).reshape(shape[0] * shape[1], -1) ** 2
                                for g in TEXTURES])
    return expected_error(variance).reshape(shape)
