"""The model of the gradient-descent estimator (paper sections 4.1-4.3, Eqs. 11 and 13): the
light it sees, its per-degree light terms, the radiance it predicts, and its objective."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from freqbrdf.artefacts import Observations
from freqbrdf.estimate.light import LightQuadrature, PointSources, extract_point_sources, irradiance, light_quadrature, shadowed_light
from freqbrdf.estimate.light_table import ShadowedLightTable, shadowed_light_table
from freqbrdf.estimate.optimise import lanes
from freqbrdf.estimate.optimise.kernels import (KernelModel, degree_sums, grid_search, l1_loss_gradient,
                                                source_geometry, table_sums)
from freqbrdf.estimate.optimise.problem import Problem, check_params
from freqbrdf.estimate.optimise.settings import N_PARAMS, OptimiseSettings, method_terms
from freqbrdf.methods import get_method
from freqbrdf.sphere.brdf import alpha_from_roughness, tan2_theta
from freqbrdf.sphere.lobes import lobe_table, view_table
from freqbrdf.sphere.sh import recurrence_tables
from freqbrdf.util.threads import set_threads
from freqbrdf.util.validation import check_finite, check_int, check_shape

__all__ = ["ForwardModel", "estimate_light", "model_light", "map_light", "point_terms", "pair_source_geometry", "model_tables",
           "light_terms", "refit_light", "forward", "loss_and_gradient", "grid_start"]


def estimate_light(
    envmap: np.ndarray, obs: Observations, method: str, lmax: int, point_sources: Mapping[str, float] | None = None,
) -> tuple[LightQuadrature, np.ndarray]:
    """The light of a method's model at degree ``lmax`` and the irradiance at the texel normals:
    the map as it is, or low-passed by the views' band limit a' for a ``prefiltered`` method
    (``freq_paper``: paper section 4.2). With ``point_sources`` (``max_radius_deg``,
    ``min_radiance``: `freqbrdf.estimate.light.extract_point_sources`), for a method that is not
    pre-filtered, the map's compact bright sources leave the SH light and ride along as ``LightQuadrature.sources``;
    the irradiance is always the whole map's."""
    return model_light(envmap, obs, method, lmax, point_sources), irradiance(envmap, obs.texels.normal)


def model_light(
    envmap: np.ndarray, obs: Observations, method: str, lmax: int, point_sources: Mapping[str, float] | None = None,
) -> LightQuadrature:
    """The light of `estimate_light` without the irradiance."""
    if get_method(method).prefiltered:
        return light_quadrature(envmap, lmax, prefilter=obs.a_prime)
    return map_light(envmap, lmax, point_sources)


def map_light(envmap: np.ndarray, lmax: int, point_sources: Mapping[str, float] | None = None) -> LightQuadrature:
    """The light of every method that is not pre-filtered: it depends on the map alone, not on the
    capture (`model_light`; rule ``light_table`` fits its shadowed light once per map)."""
    if not point_sources or not point_sources["max_radius_deg"]:
        return light_quadrature(envmap, lmax)
    residual, sources = extract_point_sources(envmap, point_sources["max_radius_deg"], point_sources["min_radiance"])
    return dataclasses.replace(light_quadrature(residual, lmax), sources=sources)


def point_terms(
    problem: Problem, sources: PointSources | None, shadowing: bool,
) -> tuple[np.ndarray, np.ndarray] | None:
    """The point sources of `freqbrdf.estimate.optimise.kernels.KernelModel` for ``sources``.

    Per pair and source, the geometry of its half vector, which no parameter changes
    (`pair_source_geometry`); per observed texel (internal order) and source, ``tan^2 theta_i``
    (0 without ``shadowing``: G1 = 1) and its power.
    None if there are no sources."""
    if sources is None or not len(sources.power):
        return None
    local = np.einsum("tij,sj->tsi", problem.frame[problem.observed], sources.directions)  # (T_obs, S, 3)
    cos_i = local[..., 2]
    tan2_i = tan2_theta(np.clip(cos_i, 1e-6, 1.0)) if shadowing else np.zeros_like(cos_i)
    power = np.broadcast_to(sources.power[None], cos_i.shape + (3,))
    return (pair_source_geometry(problem.wo_local, local, problem.pair_slot, problem.dtype),
            np.concatenate([tan2_i[..., None], power], axis=2))


def pair_source_geometry(wo: np.ndarray, incoming: np.ndarray, slot: np.ndarray, dtype="float32") -> np.ndarray:
    """What the microfacet term of each pair and point source needs of the half vector ``h``.

    Parameters
    ----------
    wo : numpy.ndarray
        Shape ``(N, 3)``: each pair's view direction in its texel's frame (unit).
    incoming : numpy.ndarray
        Shape ``(T, S, 3)``: each source's direction in each texel's frame (unit).
    slot : numpy.ndarray
        Shape ``(N,)``, int: each pair's texel.
    dtype : {"float32", "float64"}
        Of the result (the problem's: the kernels read it at every evaluation).

    Returns
    -------
    numpy.ndarray
        Shape ``(N, S, 3)``: ``sin^2 theta_h`` (kept instead of ``cos^2``, whose
        ``1 - cos^2`` would cancel for a sharp lobe), Schlick's ``(1 - h.wo)^5`` and
        ``1 / (4 cos theta_o)``; the last is 0 where the source or the view is below the
        horizon, which drops the term.
    """
    wo = np.ascontiguousarray(wo, dtype=np.float64)
    incoming = np.ascontiguousarray(incoming, dtype=np.float64)
    slot = np.ascontiguousarray(slot, dtype=np.int64)
    if wo.ndim != 2 or wo.shape[1] != 3 or incoming.ndim != 3 or incoming.shape[2] != 3 or slot.shape != wo.shape[:1]:
        raise ValueError(f"pair_source_geometry needs wo (N, 3), incoming (T, S, 3) and slot (N,), got shapes "
                         f"{wo.shape}, {incoming.shape} and {slot.shape}")
    if slot.size and (slot.min() < 0 or slot.max() >= incoming.shape[0]):
        raise ValueError(f"slot must index the {incoming.shape[0]} texels of incoming, got {slot.min()}..{slot.max()}")
    out = np.empty((wo.shape[0], incoming.shape[1], 3), dtype=dtype)
    source_geometry(wo, incoming, slot, out)
    return out


# --------------------------------------------------------------------------
# BRDF terms
# --------------------------------------------------------------------------


def model_tables(settings: OptimiseSettings, method: str, lmax: int) -> tuple[np.ndarray, np.ndarray]:
    """The lobe (`freqbrdf.sphere.lobes.lobe_table`) and view (`freqbrdf.sphere.lobes.view_table`) tables of
    ``method``'s model at degree ``lmax``: ``settings.view_weight`` applies to the methods with
    shadowing and masking, the others ablate the paper's terms and keep its specular weight."""
    shadowing, masking = method_terms(method)
    view_weight = settings.view_weight if shadowing and masking else "paper"
    return lobe_table(settings.lobe, lmax), view_table(view_weight, settings.diffuse, settings.lobe, lmax)


def light_terms(
    roughness: np.ndarray,
    problem: Problem,
    shadowing: bool,
    light: LightQuadrature,
    workers: int = 1,
    table: ShadowedLightTable | None = None,
) -> np.ndarray:
    """Per-degree contributions of the (shadowed) environment light at each observation.

    With shadowing, ``Lg`` is the SH fit (degree ``light.lmax``) of
    ``G1(theta_i, alpha) L`` over each texel's upper hemisphere by dense
    quadrature of the known environment (paper section 4.2, Fig. 2:
    :func:`freqbrdf.estimate.light.shadowed_light`), or interpolated from ``table``
    (:class:`freqbrdf.estimate.light_table.ShadowedLightTable`); without it, ``Lg`` is the
    environment's own SH, as in Ramamoorthi and Hanrahan (2001). Then
    ``P[n, l, c] = sum_m Lg_lm,c Y_lm(w_r,n)`` at the world mirror direction.

    Parameters
    ----------
    roughness : numpy.ndarray
        Shape ``(T,)``: the roughness whose alpha shadows the light (unused
        without shadowing).
    problem : Problem
        Observations (`build_problem`).
    shadowing : bool
        Apply ``G1(theta_i)`` and the texel's horizon.
    light : LightQuadrature
        The environment (:func:`freqbrdf.estimate.light.light_quadrature`).
    workers : int
        Threads of the evaluation.
    table : ShadowedLightTable, optional
        ``light``'s shadowed light tabulated (`freqbrdf.estimate.light_table.shadowed_light_table`).

    Returns
    -------
    numpy.ndarray
        Shape ``(N, lmax + 1, 3)``, the problem's dtype; ``sum_l P[n, l]`` is
        the light at observation n, ``sum_l exp(-(alpha l)^2) P[n, l]`` its
        lobe-filtered value.
    """
    r = np.asarray(roughness, dtype=np.float64)
    check_shape(r, "roughness", (problem.n_texels,))
    check_finite(r, "roughness")
    workers = check_int(workers, "workers", 1)
    out = np.empty((problem.n_pairs, light.lmax + 1, 3), dtype=problem.dtype)
    if shadowing:
        refit_light(out, r, problem, light, np.arange(problem.n_observed), workers, table)
    else:
        lg = (light.basis.T.astype(np.float64) @ light.weighted_radiance)[None]  # (1, n, 3)
        pairs = np.arange(problem.n_pairs)
        _evaluate_light(out, pairs, np.zeros_like(pairs), lg, problem, workers)
    return out


def refit_light(
    out: np.ndarray, roughness: np.ndarray, problem: Problem, light: LightQuadrature, slots: np.ndarray,
    workers: int, table: ShadowedLightTable | None = None,
) -> None:
    """Refit the shadowed light of the observed texels ``slots`` (positions into ``problem.observed``)
    at ``roughness`` and overwrite their observations' rows of ``out`` (`light_terms`); from
    ``table`` where given."""
    texels = problem.observed[slots]
    if table is not None:
        a, b = recurrence_tables(out.shape[1] - 1)
        set_threads(workers)
        coefficients = table.coefficients.reshape(*table.coefficients.shape[:2], -1)  # coefficient-major rows
        corner, weight, v = table.weights(problem.normal[texels], roughness[texels])
        # texels in the order of their grid normals: neighbours share the table's rows in cache
        order = np.argsort(corner[:, 0], kind="stable")
        table_sums(coefficients, corner[order], weight[order], v[order], np.asarray(slots, dtype=np.int64)[order],
                   problem.start, problem.mirror, a, b, out)
        return
    lg = shadowed_light(light, problem.normal[texels], alpha_from_roughness(roughness[texels])[0], workers)
    local = np.full(problem.n_observed, -1, dtype=np.int64)
    local[slots] = np.arange(slots.shape[0])
    pairs = np.nonzero(local[problem.pair_slot] >= 0)[0]
    _evaluate_light(out, pairs, local[problem.pair_slot[pairs]], lg, problem, workers)


def _evaluate_light(
    out: np.ndarray, pairs: np.ndarray, rows: np.ndarray, lg: np.ndarray, problem: Problem, workers: int
) -> None:
    """``out[pairs[i], l] = sum_m lg[rows[i], lm] Y_lm(mirror of pairs[i])`` per degree l."""
    a, b = recurrence_tables(out.shape[1] - 1)
    set_threads(workers)
    degree_sums(lg, rows.astype(np.int64), pairs.astype(np.int64), problem.mirror, a, b, out)


def _check_terms(terms: np.ndarray, problem: Problem) -> np.ndarray:
    p = np.asarray(terms)
    check_shape(p, "terms", (problem.n_pairs, None, 3))
    check_finite(p, "terms")
    return p


def _data_term(xp: np.ndarray, problem: Problem, terms: np.ndarray, model: KernelModel,
               out: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per-texel L1 data term and gradient of the observed texels (`freqbrdf.estimate.optimise.kernels.l1_loss_gradient`)."""
    return l1_loss_gradient(np.ascontiguousarray(xp[: problem.n_observed]), terms, problem.pair_data, model, out)


def _objective(
    xp: np.ndarray, problem: Problem, terms: np.ndarray, model: KernelModel, tv_weight: float,
    lane: tuple[lanes.PairLanes, np.ndarray] | None = None,
) -> tuple[float, np.ndarray]:
    """`loss_and_gradient` of internal-order ``xp`` (texel-order sums, so independent of threads); the
    data term from ``lane`` (the pairs and the same ``terms`` laid out in lanes) where given."""
    if lane is None:
        loss_per_texel, grad_obs = _data_term(xp, problem, terms, model)
    else:
        if lane[0].model is not model or lane[0].pairs.start is not problem.start:
            raise ValueError("lane: the lanes of another model or problem")
        loss_per_texel, grad_obs = lanes.l1_loss_gradient_lanes(xp[: problem.n_observed], lane[1], lane[0])
    scale = 1.0 / (3.0 * problem.n_pairs)  # mean over pairs and channels
    grad = np.zeros_like(xp)
    grad[: problem.n_observed] = grad_obs * scale
    loss = float(np.sum(loss_per_texel)) * scale
    if tv_weight > 0:
        tv, tv_grad = problem.tv(xp)
        loss += tv_weight * tv
        grad += tv_weight * tv_grad
    return float(loss), grad


def forward(x: np.ndarray, problem: Problem, terms: np.ndarray, model: KernelModel) -> np.ndarray:
    """Model radiance of every observation.

    Parameters
    ----------
    x : numpy.ndarray
        Shape ``(T, 5)``, packed parameters (`pack_params`).
    problem : Problem
        Observations.
    terms : numpy.ndarray
        Shape ``(N, L, 3)``: `light_terms` (its ``shadowing`` picks the variant).
    model : KernelModel
        Which model: masking, lobe and view tables, point sources.

    Returns
    -------
    numpy.ndarray
        Shape ``(T, K, 3)``, float64, radiance; 0 where not observed.
    """
    x = check_params(x, problem)
    p = _check_terms(terms, problem)
    radiance = np.empty((problem.n_pairs, 3))
    _data_term(x[problem.perm], problem, p, model, radiance)
    out = np.zeros((problem.n_texels, problem.n_views, 3))
    out[problem.pair_texel, problem.pair_view] = radiance
    return out


def loss_and_gradient(
    x: np.ndarray, problem: Problem, terms: np.ndarray, model: KernelModel, tv_weight: float = 1e-3, workers: int = 1,
) -> tuple[float, np.ndarray]:
    """Objective of paper Eq. 13 plus total variation (section 4.3) and its analytic gradient, light terms held fixed.

    ``loss = mean_{pairs, c} |B - B_obs| + tv_weight * TV`` (module docstring).
    With ``g = sign(B - B_obs) / (3 N)`` and ``c5 = (1 - cos theta_o)^5``:

    - ``dL/dbase_c = sum_k g [(1 - m) E_c / pi + m (1 - c5) G1m Spec_c]``;
    - ``dL/dm = sum_kc g [-base_c E_c / pi + (base_c - 0.04)(1 - c5) G1m Spec_c]``;
    - ``dL/dr = 2 r sum_kc g F_c [G1m' Spec_c + G1m sum_l f_l' P_lc]`` with
      ``G1m' = dG1/dalpha = -2 alpha tan^2 / (s (1 + s)^2)``,
      ``s = sqrt(1 + alpha^2 tan^2)``, ``f_l' = -2 alpha l^2 exp(-(alpha l)^2)`` (the Gaussian lobe;
      GGX's from its table, `freqbrdf.sphere.lobes.lobe_table`)
      (where alpha is clamped at `ALPHA_MIN`, ``2 r`` becomes ``2 sqrt(ALPHA_MIN)``:
      a straight-through derivative, see `alpha_from_roughness`);

    plus ``tv_weight`` times the TV gradient (`total_variation`). With a ``view`` table,
    ``E_c / pi`` becomes ``d E_c / pi`` and ``(1 - c5) G1m``, ``c5 G1m`` become ``a``, ``b``
    (`freqbrdf.sphere.lobes.view_table`), each with its own derivative in alpha in ``dL/dr``.

    Parameters
    ----------
    x : numpy.ndarray
        Shape ``(T, 5)``, packed parameters.
    problem : Problem
        Observations.
    terms : numpy.ndarray
        Shape ``(N, L, 3)``: `light_terms` (its ``shadowing`` picks the variant).
    model : KernelModel
        Which model: masking, lobe and view tables, point sources.
    tv_weight : float
        Weight of TV, ``>= 0``.
    workers : int
        Threads.

    Returns
    -------
    loss : float
    grad : numpy.ndarray
        Shape ``(T, 5)``, float64.
    """
    x = check_params(x, problem)
    p = _check_terms(terms, problem)
    tv_weight = float(tv_weight)
    if not (np.isfinite(tv_weight) and tv_weight >= 0):
        raise ValueError(f"tv_weight must be a finite number >= 0, got {tv_weight!r}")
    set_threads(check_int(workers, "workers", 1))
    loss, grad_p = _objective(x[problem.perm], problem, p, model, tv_weight)
    grad = np.empty_like(grad_p)
    grad[problem.perm] = grad_p
    return loss, grad


def grid_start(
    problem: Problem, terms: np.ndarray, model: KernelModel, roughness: np.ndarray, metallic: np.ndarray,
    workers: int = 1, lane_pairs: lanes.PairLanes | None = None,
) -> np.ndarray:
    """Per-texel start of the optimiser: the best of a (roughness x metallic) grid.

    For fixed roughness and metallic the model is linear in the base colour
    (``B = (1 - m) base E / pi + (R0 (1 - c5) + c5) G1m Spec`` with
    ``R0 = 0.04 (1 - m) + m base``), so each grid point gets its base colour
    in closed form (least squares per channel, clipped to [0, 1]) and is
    ranked by the L1 objective. A descent from a constant start stalls in
    local minima on some texels (4 of 40 noise-free texels with random
    metallic, roughness off by up to 0.88); from the grid's best point 2 of
    them (up to 0.42), and none of the 64 of `tests/test_light.py`.

    Parameters
    ----------
    problem : Problem
        Observations.
    terms : numpy.ndarray
        Shape ``(N, L, 3)``: `light_terms` (its ``shadowing`` picks the variant).
    model : KernelModel
        Which model: masking, lobe and view tables, point sources.
    roughness, metallic : numpy.ndarray
        1-D grids of candidate values in [0, 1].
    workers : int
        Threads.
    lane_pairs : PairLanes, optional
        The pairs laid out in lanes (`freqbrdf.estimate.optimise.lanes.pair_lanes` of ``model``): the
        search runs on them, its light sums in the terms' precision (the same grid point, but where
        two tie within that rounding: a texel of one pair fits its 3 channels exactly at many).

    Returns
    -------
    numpy.ndarray
        Shape ``(T, 5)``, packed parameters; 0.5 for texels without observations.
    """
    p = _check_terms(terms, problem)
    set_threads(check_int(workers, "workers", 1))
    xp = np.full((problem.n_texels, N_PARAMS), 0.5)
    if lane_pairs is None:
        xp[: problem.n_observed] = grid_search(p, problem.pair_data, model, roughness, metallic)
    elif lane_pairs.model is not model:
        raise ValueError("lane_pairs: laid out for another model")
    else:
        xp[: problem.n_observed] = lanes.grid_search_lanes(lanes.lane_terms(p, lane_pairs), lane_pairs, roughness,
                                                           metallic)
    x = np.empty_like(xp)
    x[problem.perm] = xp
    return x


@dataclass(frozen=True, eq=False)
class ForwardModel:
    """A method's model of one capture: everything the objective needs besides the parameters
    and the current light terms (`light_terms`, which change at every refit).

    Attributes
    ----------
    problem : Problem
        The observations.
    light : LightQuadrature
        The environment at the model's degree l*, with its point sources (`model_light`).
    shadowing : bool
        Shadow the light by ``G1(theta_i)`` at each texel's roughness (refitted as it moves).
    kernel : KernelModel
        Masking, the lobe and view tables and the point sources, as the kernels read them.
    table : ShadowedLightTable, optional
        The shadowed light tabulated (``settings.light_table``); None: fitted per texel.
    lane_pairs : PairLanes, optional
        The pairs laid out for the objective's vectorised kernel (`freqbrdf.estimate.optimise.lanes`);
        None where it does not evaluate this model (the albedo weights).
    """

    problem: Problem
    light: LightQuadrature
    shadowing: bool
    kernel: KernelModel
    table: ShadowedLightTable | None = None
    lane_pairs: lanes.PairLanes | None = None

    @classmethod
    def of(cls, problem: Problem, light: LightQuadrature, method: str, settings: OptimiseSettings,
           table: ShadowedLightTable | None = None) -> ForwardModel:
        """The model of ``method`` (a method of rule ``optimise_svbrdf``) with ``settings``' lobe and
        weights; its shadowed light from ``table`` (fitted from ``light`` at ``settings.light_table``,
        e.g. rule ``light_table``'s), else from a table fitted here, if the settings and method use one."""
        shadowing, masking = method_terms(method)
        lobe, view = model_tables(settings, method, light.lmax)
        point = point_terms(problem, light.sources, shadowing)
        size = settings.light_table
        if not (shadowing and size.rows):
            table = None
        elif table is None:
            table = shadowed_light_table(light, size.rows, size.rank, settings.workers)
        else:
            table.check_fits(light, size)
        kernel = KernelModel(masking, lobe, view, point)
        layout = lanes.pair_lanes(problem.pair_data, kernel) if lanes.supports(kernel) else None
        return cls(problem, light, shadowing, kernel, table, layout)

    def light_terms(self, roughness: np.ndarray, workers: int) -> np.ndarray:
        """`light_terms` of every observation at ``roughness`` (T,)."""
        return light_terms(roughness, self.problem, self.shadowing, self.light, workers, self.table)

    def refit(self, terms: np.ndarray, roughness: np.ndarray, slots: np.ndarray, workers: int) -> None:
        """`refit_light` of the observed texels ``slots`` into ``terms``."""
        refit_light(terms, roughness, self.problem, self.light, slots, workers, self.table)

    def radiance(self, xp: np.ndarray, terms: np.ndarray) -> np.ndarray:
        """Model radiance (N, 3) of every observed pair at internal-order parameters ``xp`` (T, 5)."""
        out = np.empty((self.problem.n_pairs, 3))
        _data_term(xp, self.problem, terms, self.kernel, out)
        return out

    def lane_terms(self, terms: np.ndarray, out: np.ndarray | None = None) -> np.ndarray | None:
        """``terms`` laid out as this model's lanes (`freqbrdf.estimate.optimise.lanes.lane_terms`), into
        ``out`` if given; None without lanes."""
        return None if self.lane_pairs is None else lanes.lane_terms(terms, self.lane_pairs, out)

    def objective(self, xp: np.ndarray, terms: np.ndarray, tv_weight: float,
                  lane_terms: np.ndarray | None = None) -> tuple[float, np.ndarray]:
        """`loss_and_gradient` of internal-order parameters ``xp`` (T, 5), unchecked: the solvers' inner
        loop; from ``lane_terms`` (`lane_terms` of the same ``terms``) where given."""
        lane = None if lane_terms is None else (self.lane_pairs, lane_terms)
        return _objective(xp, self.problem, terms, self.kernel, tv_weight, lane)

    def grid_start(self, terms: np.ndarray, roughness: np.ndarray, metallic: np.ndarray, workers: int) -> np.ndarray:
        """`grid_start` of this model."""
        return grid_start(self.problem, terms, self.kernel, roughness, metallic, workers, self.lane_pairs)
