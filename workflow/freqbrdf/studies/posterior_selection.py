"""View selection by the fit's posterior (beyond the paper; issue 33).

The entropy-guided selection (:mod:`freqbrdf.studies.view_selection`) asks how well a view's
light would separate the lobe hypotheses of the spectrum search. This one asks what the fitted
model expects: with a pilot estimate ``x`` from a few views, each view ``v`` adds to texel ``t``'s
Laplace precision (`freqbrdf.estimate.optimise.posterior`) the information

    I_tv = sum over the pair (t, v)'s channels of  J^T J / s_t^2,

``J`` the Jacobian of the model radiance in the texel's five parameters at ``x``, ``s_t^2`` the
residual variance the pilot fit leaves at the texel. Neither needs the view's image: ``J`` comes
from the geometry, the light and ``x``. The greedy choice adds the view that most lowers the mean
over the texels of the expected squared parameter error, the average of the diagonal of
``(prior + sum of the chosen views' I)^-1`` as `freqbrdf.estimate.optimise.posterior.expected_error`
averages it (the calibration ``variance_scale`` multiplies every value alike, so it does not
change the order). The light terms are held at the pilot's roughness, as the posterior holds them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from freqbrdf.artefacts import Observations
from freqbrdf.estimate.light import LightQuadrature
from freqbrdf.estimate.light_table import ShadowedLightTable
from freqbrdf.estimate.optimise.model import ForwardModel
from freqbrdf.estimate.optimise.posterior import (PRIOR_PRECISION, expected_error, model_jacobian, pair_information,
                                                  pooled_residual_variance, residual_variance)
from freqbrdf.estimate.optimise.problem import build_problem, pack_params
from freqbrdf.estimate.optimise.settings import N_PARAMS, OptimiseSettings
from freqbrdf.util.validation import check_int, check_shape

__all__ = ["view_information", "mean_expected_error", "greedy_posterior_selection", "capture_information"]


def view_information(jacobian: np.ndarray, slot: np.ndarray, view: np.ndarray, s2: np.ndarray,
                     n_views: int) -> np.ndarray:
    """The information each view adds to each texel's precision.

    Parameters
    ----------
    jacobian : numpy.ndarray
        Shape ``(N, 3, 5)``: d radiance / d parameters of each (texel, view) pair, per channel.
    slot, view : numpy.ndarray
        Shape ``(N,)``, int: each pair's texel (0..T-1) and view (0..n_views-1).
    s2 : numpy.ndarray
        Shape ``(T,)``, > 0: each texel's residual variance.
    n_views : int
        Number of views.

    Returns
    -------
    numpy.ndarray
        Shape ``(T, n_views, 5, 5)``: ``sum_c J^T J / s2`` of the texel's pair with the view, 0 where
        the view does not see the texel.
    """
    check_shape(np.asarray(jacobian), "jacobian", (None, 3, N_PARAMS))
    slot, view = np.asarray(slot, dtype=np.int64), np.asarray(view, dtype=np.int64)
    s2 = np.asarray(s2, dtype=np.float64)
    n_views = check_int(n_views, "n_views", 1)
    check_shape(slot, "slot", (len(jacobian),))
    check_shape(view, "view", (len(jacobian),))
    bad = np.flatnonzero(~(s2 > 0))
    if bad.size:
        raise ValueError(f"view_information: residual variance {float(s2[bad[0]])!r} of texel {bad[0]}; each must be > 0")
    if slot.size and not (0 <= slot.min() and slot.max() < len(s2) and 0 <= view.min() and view.max() < n_views):
        raise ValueError(f"view_information: pairs name texels {slot.min()}..{slot.max()} of {len(s2)} and views "
                         f"{view.min()}..{view.max()} of {n_views}")
    out = np.zeros((len(s2) * n_views, N_PARAMS, N_PARAMS))
    np.add.at(out, slot * n_views + view, pair_information(jacobian) / s2[slot, None, None])
    return out.reshape(len(s2), n_views, N_PARAMS, N_PARAMS)


def mean_expected_error(precision: np.ndarray) -> np.ndarray:
    """The expected squared parameter error averaged over texels, of precisions ``(..., T, 5, 5)``: shape ``(...)``."""
    variance = np.diagonal(np.linalg.inv(precision), axis1=-2, axis2=-1)
    return expected_error(variance.reshape(-1, N_PARAMS)).reshape(variance.shape[:-1]).mean(axis=-1)


def greedy_posterior_selection(information: np.ndarray, k: int, chosen: Sequence[int] = ()
                               ) -> tuple[list[int], list[float]]:
    """Add, one at a time, the view that most lowers the mean expected error, until ``k`` views are chosen.

    Parameters
    ----------
    information : numpy.ndarray
        Shape ``(T, V, 5, 5)`` (`view_information`).
    k : int
        Views wanted in all, those in ``chosen`` included (at most V).
    chosen : sequence of int
        Views already taken (the pilot's).

    Returns
    -------
    picks : list of int
        The views added, in order (``k - len(chosen)`` of them).
    errors : list of float
        The mean expected error (variance scale 1) with ``chosen``, then after each pick.
    """
    information = np.asarray(information, dtype=np.float64)
    check_shape(information, "information", (None, None, N_PARAMS, N_PARAMS))
    n_views = information.shape[1]
    k = check_int(k, "k", 1)
    taken = [check_int(v, "chosen view", 0) for v in chosen]
    if k > n_views or len(set(taken)) != len(taken) or any(v >= n_views for v in taken) or len(taken) > k:
        raise ValueError(f"greedy_posterior_selection: k = {k} views of {n_views} with chosen {taken}")
    precision = PRIOR_PRECISION * np.eye(N_PARAMS) + information[:, taken].sum(axis=1)
    errors = [float(mean_expected_error(precision))]
    picks: list[int] = []
    while len(taken) + len(picks) < k:
        left = [v for v in range(n_views) if v not in taken and v not in picks]
        after = mean_expected_error(precision[None] + information[:, left].transpose(1, 0, 2, 3))
        best = int(np.argmin(after))  # ties go to the lowest view index
        picks.append(left[best])
        precision = precision + information[:, left[best]]
        errors.append(float(after[best]))
    return picks, errors


def capture_information(obs: Observations, pilot_views: Sequence[int], pilot: Mapping[str, np.ndarray],
                        light: LightQuadrature, irradiance: np.ndarray, settings: OptimiseSettings,
                        method: str = "freq", min_pilot_views: int = 2,
                        table: ShadowedLightTable | None = None) -> np.ndarray:
    """`view_information` of every view of a capture at a pilot estimate, from its pilot views' residuals.

    Parameters
    ----------
    obs : Observations
        T texels x V views (in practice a sample of the capture's texels): the geometry of
        every view; the radiance of the pilot views only is read (the others' is set to 0
        before anything is computed).
    pilot_views : sequence of int
        The views the pilot estimate was fitted on.
    pilot : mapping
        The pilot estimate of the T texels: ``base_color`` (T, 3), ``roughness`` and ``metallic`` (T,).
    light, irradiance, settings, method
        The light (`freqbrdf.estimate.optimise.model.estimate_light`), the texels' irradiance
        (T, 3), the settings and the method (of rule ``optimise_svbrdf``) the pilot was fitted with.
    min_pilot_views : int
        A texel that fewer pilot views see takes the residual variance pooled over every pilot
        pair (2: the fewest whose 6 residuals leave a degree of freedom to 5 parameters).
    table : ShadowedLightTable, optional
        ``light``'s shadowed light tabulated (`freqbrdf.estimate.optimise.model.ForwardModel.of`).

    Returns
    -------
    numpy.ndarray
        Shape ``(T, V, 5, 5)``; zero for texels no view sees.
    """
    n_texels, n_views = np.shape(obs.weight)
    pilot_views = np.asarray(pilot_views, dtype=np.int64)
    unread = np.setdiff1d(np.arange(n_views), pilot_views)
    radiance = np.array(obs.radiance)
    radiance[:, unread] = 0.0  # the views not taken: their images are not known yet
    obs = Observations(obs.texels, radiance, obs.weight, obs.wo_local, obs.incoming, obs.meta)
    problem = build_problem(obs, irradiance, settings.dtype)
    model = ForwardModel.of(problem, light, method, settings, table)
    xp = pack_params(pilot, n_texels)[problem.perm]  # checks the shapes
    xp[:, 3] = np.maximum(xp[:, 3], settings.min_roughness)
    roughness = np.empty(n_texels)
    roughness[problem.perm] = xp[:, 3]
    terms = model.light_terms(roughness, settings.workers)
    model_radiance, jacobian = model_jacobian(lambda z: model.radiance(z, terms), xp, problem.start)
    slot, view = problem.pair_slot, problem.pair_view
    known = np.isin(view, pilot_views)
    n_obs = len(problem.observed)
    residual = model_radiance[known] - problem.radiance[known]
    pairs = np.bincount(slot[known], minlength=n_obs)
    if not pairs.any():
        raise ValueError(f"capture_information: no texel is seen by the pilot views {pilot_views.tolist()}")
    s2 = np.where(pairs >= max(min_pilot_views, 1), residual_variance(residual, slot[known], n_obs),
                  pooled_residual_variance(residual, slot[known]))
    out = np.zeros((n_texels, n_views, N_PARAMS, N_PARAMS))
    out[problem.observed] = view_information(jacobian, slot, view, s2, n_views)
    return out
