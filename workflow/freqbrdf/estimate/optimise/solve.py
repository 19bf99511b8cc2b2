"""The gradient-descent estimator's solvers (paper section 4.3): Adam, as the authors' code, or
per-texel Levenberg-Marquardt, from the given start or the grid start, with the shadowed light
refitted as the roughness moves."""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from freqbrdf.artefacts import Observations
from freqbrdf.estimate.light import LightQuadrature
from freqbrdf.estimate.light_table import ShadowedLightTable, read_light_table
from freqbrdf.estimate.optimise.kernels import LmStep, adam_update, lm_sweep, texel_information
from freqbrdf.estimate.optimise.model import ForwardModel, estimate_light
from freqbrdf.estimate.optimise.posterior import posterior_variance, prior_variance
from freqbrdf.estimate.optimise.problem import build_problem, pack_params, unpack_params
from freqbrdf.estimate.optimise.settings import N_PARAMS, OptimiseSettings, method_terms
from freqbrdf.methods import get_method
from freqbrdf.util.threads import set_threads
from freqbrdf.util.validation import check_int

__all__ = ["Fit", "adam_step", "optimise", "estimate_capture"]

_LM_TRIES = 4  # damping increases per texel and LM sweep before its step is given up


@dataclass(frozen=True)
class Fit:
    """What `optimise` returns.

    Attributes
    ----------
    params : dict of numpy.ndarray
        ``base_color`` (T, 3), ``roughness`` (T,), ``metallic`` (T,), float64 in [0, 1].
    loss_curve : numpy.ndarray
        The objective at the start of each Adam iteration or LM sweep (`optimise`).
    std : dict of numpy.ndarray
        The same keys and shapes: each parameter's posterior standard deviation
        (:mod:`freqbrdf.estimate.optimise.posterior`); a texel without observations keeps the
        prior's (`freqbrdf.estimate.optimise.posterior.prior_variance`).
    """

    params: dict[str, np.ndarray]
    loss_curve: np.ndarray
    std: dict[str, np.ndarray]


def adam_step(
    x: np.ndarray,
    grad: np.ndarray,
    m1: np.ndarray,
    m2: np.ndarray,
    step: int,
    lr: float,
    betas: tuple[float, float] = (0.9, 0.999),
    eps: float = 1e-8,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One Adam update (Kingma and Ba 2015) followed by clamping to [0, 1].

    Parameters
    ----------
    x, grad, m1, m2 : numpy.ndarray
        Same shape: parameters, gradient, first and second moment estimates.
    step : int
        1-based step number (bias correction).
    lr : float
        Learning rate.
    betas : tuple of float
        Moment decay rates.
    eps : float
        Denominator offset.

    Returns
    -------
    tuple of numpy.ndarray
        New parameters (in [0, 1]), first and second moments.
    """
    step = check_int(step, "step", 1)
    b1, b2 = betas
    m1 = b1 * m1 + (1.0 - b1) * grad
    m2 = b2 * m2 + (1.0 - b2) * grad * grad
    update = lr * (m1 / (1.0 - b1**step)) / (np.sqrt(m2 / (1.0 - b2**step)) + eps)
    return np.clip(x - update, 0.0, 1.0), m1, m2


def optimise(
    obs: Observations,
    irradiance: np.ndarray,
    light: LightQuadrature,
    init: Mapping[str, np.ndarray] | None = None,
    method: str = "freq",
    *,
    settings: OptimiseSettings,
    table: ShadowedLightTable | None = None,
) -> Fit:
    """Per-texel principled parameters minimising the L1 + TV objective (Adam or LM: ``settings.solver``).

    Parameters
    ----------
    obs : Observations
        The capture's T texels x K views (:class:`freqbrdf.artefacts.Observations`);
        the atlas indices of its texels define the TV neighbours.
    irradiance : numpy.ndarray
        Shape ``(T, 3)``: E at the texel normals (:func:`freqbrdf.estimate.light.irradiance`).
    light : LightQuadrature
        The environment that lit the capture, at the model's degree l*
        (:func:`freqbrdf.estimate.light.light_quadrature`).
    init : mapping, optional
        ``base_color`` (T, 3), ``roughness`` (T,), ``metallic`` (T,) in [0, 1],
        e.g. the spectrum-only estimate; default 0.5 everywhere.
    method : str
        A method of rule ``optimise_svbrdf`` in :data:`freqbrdf.methods.METHODS`.
    settings : OptimiseSettings
        Solver and SH fit settings (keyword only, no default): the pipeline's
        from its config (`OptimiseSettings.from_config`), the paper's from
        `OptimiseSettings.paper`.
    table : ShadowedLightTable, optional
        ``light``'s shadowed light tabulated at ``settings.light_table`` (rule ``light_table``'s,
        `freqbrdf.estimate.light_table.read_light_table`); default: fitted here if the method
        and settings use one.

    Returns
    -------
    Fit
        ``params``: texels without observations move only through TV.
        ``loss_curve``: the objective at the start of each Adam iteration or LM sweep
        (after that iteration's refit, if any, so it may jump at refits);
        Adam's has one more, after its last step; where that ends above the
        first, Adam returns its iterate of lowest objective instead of the
        last; an LM run that meets ``sweep_tolerance`` early has fewer
        entries than ``sweeps``. ``std``: the posterior's standard deviations
        (:func:`freqbrdf.estimate.optimise.posterior.posterior_variance`, with the exact
        Jacobian of `freqbrdf.estimate.optimise.kernels.texel_information`) at the
        last light terms.
    """
    method_terms(method)  # a bad method is named before any work
    if not isinstance(settings, OptimiseSettings):
        raise TypeError(f"settings must be an OptimiseSettings, got {type(settings).__name__}")
    model = ForwardModel.of(build_problem(obs, irradiance, settings.dtype), light, method, settings, table)
    problem = model.problem
    xp = _start(model, init, settings)[problem.perm]  # internal order
    descend = _descend_lm if settings.solver == "lm" else _descend
    xp, curve, terms = descend(xp, model, settings)
    variance = np.full_like(xp, prior_variance(settings.variance_scale))  # what no view observes keeps the prior
    curvature, squares = texel_information(xp[: problem.n_observed], terms, problem.pair_data, model.kernel)
    variance[: problem.n_observed] = posterior_variance(curvature, squares, np.diff(problem.start),
                                                        settings.variance_scale)
    x, std = np.empty_like(xp), np.empty_like(xp)
    x[problem.perm], std[problem.perm] = xp, np.sqrt(variance)
    return Fit(unpack_params(x), curve, unpack_params(std))


def estimate_capture(
    obs: Observations,
    envmap: np.ndarray,
    method: str,
    config: Mapping[str, object],
    workers: int,
    init: Mapping[str, np.ndarray] | None = None,
    log: logging.Logger | None = None,
    light_table: str | os.PathLike | None = None,
) -> Fit:
    """One capture's estimate by ``method``, as rule ``optimise_svbrdf`` makes it: the method's
    light and the irradiance (`estimate_light`), then `optimise` with the settings of
    config ``optimise``, each step logged with its time.

    Parameters
    ----------
    obs : Observations
        The capture's observations.
    envmap : numpy.ndarray
        Shape ``(H, W, 3)``, the environment that lit it.
    method : str
        A method of rule ``optimise_svbrdf``.
    config : mapping
        Config ``optimise``.
    workers : int
        Threads.
    init : mapping, optional
        Start parameters (`optimise`'s ``init``).
    log : logging.Logger, optional
        Where the steps are logged (default: this module's logger).
    light_table : path, optional
        Rule ``light_table``'s table of this light (`freqbrdf.estimate.light_table.read_light_table`),
        for a method whose light is not pre-filtered; default: fitted here if the method uses one.

    Returns
    -------
    Fit
        As `optimise`.
    """
    log = log or logging.getLogger(__name__)
    settings = OptimiseSettings.from_config(config, workers=workers)
    log.info("roughness bounded below by %.3f (optimise.min_roughness: %s)", settings.min_roughness,
             config["min_roughness"])
    start = time.perf_counter()
    light, e = estimate_light(envmap, obs, method, config["lmax"], config["point_sources"])
    prefilter = "a' = %.3f" % obs.a_prime if get_method(method).prefiltered else "none"
    log.info("light at degree %d (pre-filter %s) from %d quadrature nodes, irradiance at %d normals in %.1f s",
             config["lmax"], prefilter, len(light.directions), len(obs.texels), time.perf_counter() - start)
    if light.sources is not None:
        points = light.sources.power.sum()
        log.info("%d point sources outside the SH light (optimise.point_sources: %s), %.1f%% of the map's power",
                 len(light.sources.power), config["point_sources"],
                 100.0 * points / (points + light.weighted_radiance.sum()))
    table = None
    if light_table is not None:
        table = read_light_table(light_table, light, settings.light_table)
        log.info("shadowed light from the table in %s (%d normals, rank %d)", light_table,
                 table.coefficients.shape[0], table.basis.rank)
    fit = optimise(obs, e, light, init=init, method=method, settings=settings, table=table)
    curve = fit.loss_curve
    if settings.solver == "adam":
        done = f"{settings.iterations} Adam steps, loss {curve[0]:.4g} -> {curve[-1]:.4g}"
        if curve[-1] > curve[0]:  # it ended above its start: the iterate of lowest loss is kept
            done += f", above the start: kept {curve.min():.4g} (after {int(np.argmin(curve))} steps)"
    else:
        done = f"{len(curve)} LM sweeps, loss {curve[0]:.4g} -> {curve[-1]:.4g} (at the last sweep's start)"
    log.info("%s: %s in %.1f s", method, done, time.perf_counter() - start)
    return fit


def _start(model: ForwardModel, init: Mapping[str, np.ndarray] | None, settings: OptimiseSettings) -> np.ndarray:
    """Packed start parameters (T, 5): ``init``, else the grid start or 0.5 everywhere."""
    n_texels = model.problem.n_texels
    if init is not None:
        return pack_params(init, n_texels)
    if settings.grid_start:
        # shadowed at a middle roughness: with the unshadowed light (no horizon) 1 of the 64
        # texels of the noise-free test in tests/test_light.py starts in another basin
        terms = model.light_terms(np.full(n_texels, 0.5), settings.workers)
        return model.grid_start(terms, np.linspace(0.0, 1.0, settings.grid_roughness),
                                np.linspace(0.0, 1.0, settings.grid_metallic), settings.workers)
    return np.full((n_texels, N_PARAMS), 0.5)


class _RefittedTerms:
    """The light terms of the observations, refitted for the texels whose roughness moved."""

    def __init__(self, xp: np.ndarray, model: ForwardModel, settings: OptimiseSettings):
        self.model, self.settings = model, settings
        problem = model.problem
        self.roughness = np.empty(problem.n_texels)
        self.roughness[problem.perm] = xp[:, 3]
        self.terms = model.light_terms(self.roughness, settings.workers)
        self.lane = model.lane_terms(self.terms)  # the same terms as the objective's vectorised kernel reads them
        self.fitted = self.roughness[problem.observed]  # roughness each texel's light was fitted at

    def refit(self, xp: np.ndarray) -> int:
        """Refit the texels that moved by more than ``refit_tolerance`` since their last fit (most
        stay near their start); returns how many. Without shadowing the fitted light does not
        depend on alpha: the first fit is exact."""
        if not self.model.shadowing:
            return 0
        problem = self.model.problem
        self.roughness[problem.perm] = xp[:, 3]
        now = self.roughness[problem.observed]
        slots = np.nonzero(np.abs(now - self.fitted) > self.settings.refit_tolerance)[0]
        if slots.size:
            self.model.refit(self.terms, self.roughness, slots, self.settings.workers)
            self.model.lane_terms(self.terms, self.lane)
            self.fitted[slots] = now[slots]
        return int(slots.size)


def _descend_lm(xp: np.ndarray, model: ForwardModel, settings: OptimiseSettings) -> tuple[np.ndarray, ...]:
    """Levenberg-Marquardt sweeps from ``xp`` (internal order; `freqbrdf.estimate.optimise.kernels.lm_sweep`), refitting
    the shadowed light every ``sweep_refit_every`` sweeps; returns the parameters, the objective
    at the start of each sweep and the last light terms.

    Each sweep updates the texels of one checkerboard colour with the other's held fixed, then the
    other colour: block coordinate descent, so the objective does not rise between refits. The
    objective is the one Adam minimises (`loss_and_gradient`), L1 data term and TV alike.
    """
    xp = xp.copy()
    xp[:, 3] = np.maximum(xp[:, 3], settings.min_roughness)
    set_threads(settings.workers)
    problem = model.problem
    light = _RefittedTerms(xp, model, settings)
    if not settings.sweeps:
        return xp, np.empty(0), light.terms
    step = LmStep(
        data_scale=1.0 / (3.0 * problem.n_pairs), tv_scale=settings.tv_weight / max(problem.tv_edges.shape[0], 1),
        lower=np.array([0.0, 0.0, 0.0, settings.min_roughness, 0.0]), upper=np.ones(N_PARAMS),
        irls_floor=settings.irls_floor, tv_floor=settings.tv_floor, tries=_LM_TRIES,
    )
    lam = np.full(problem.n_texels, settings.damping)
    curve: list[float] = []
    last_refit = 0
    for sweep in range(settings.sweeps):
        if sweep and sweep % settings.sweep_refit_every == 0 and light.refit(xp):
            last_refit = sweep
        loss = model.objective(xp, light.terms, settings.tv_weight, light.lane)[0]
        if sweep > last_refit and curve[-1] - loss < settings.sweep_tolerance * curve[-1]:
            break
        curve.append(loss)
        for texels in problem.colours:
            lm_sweep(xp, texels, light.terms, problem.pair_data, model.kernel, (problem.nb_start, problem.nb), step, lam)
    return xp, np.asarray(curve), light.terms


def _descend(xp: np.ndarray, model: ForwardModel, settings: OptimiseSettings) -> tuple[np.ndarray, ...]:
    """Adam from ``xp`` (internal order), refitting the shadowed light every ``refit_every`` steps;
    returns the last iterate (or, if its objective ended above the start's, the iterate of lowest
    objective), the objective at the start of each iteration and after the last
    (``iterations + 1`` values) and the last light terms.

    Adam moves every parameter by about ``lr`` a step however small its gradient, so from a start
    already near the optimum (the grid start on a small capture) its iterates can wander above
    where they began; the fallback bounds the result by the start. It is only a guard: near its
    end the objective is flat while the parameters still move, and its lowest point is no better
    an estimate than the last iterate (docs/estimator.md measures it).
    """
    xp = xp.copy()
    xp[:, 3] = np.maximum(xp[:, 3], settings.min_roughness)
    set_threads(settings.workers)
    light = _RefittedTerms(xp, model, settings)
    if not settings.iterations:
        return xp, np.empty(0), light.terms
    m1 = np.zeros_like(xp)
    m2 = np.zeros_like(xp)
    floor = np.zeros(N_PARAMS)
    floor[3] = settings.min_roughness
    curve = np.empty(settings.iterations + 1)
    best, best_loss = xp.copy(), np.inf
    for it in range(settings.iterations):
        if it and it % settings.refit_every == 0:
            light.refit(xp)
        curve[it], grad = model.objective(xp, light.terms, settings.tv_weight, light.lane)
        if curve[it] < best_loss:
            best[:], best_loss = xp, curve[it]
        # `adam_step` in place, in one pass (the update the loop's own time goes to besides the objective)
        adam_update(xp, grad, m1, m2, it + 1, settings.lr, settings.betas, settings.eps, floor)
    curve[-1] = model.objective(xp, light.terms, settings.tv_weight, light.lane)[0]
    return (xp if curve[-1] <= curve[0] else best), curve, light.terms
