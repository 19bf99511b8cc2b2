"""Gradient-descent SVBRDF estimator: the "mixed" pipeline (paper sections 4.1 and 4.3, Eqs. 11 and 13).

Per texel p the parameters are the base colour (RGB), roughness r and
metallic m, all in [0, 1]; ``alpha = max(r^2, 1e-3)`` as in Mitsuba's
``principled`` BSDF. For every observation (p, w_o) the model predicts

    B(p, w_o) = (1 - m) base d E(p) / pi + F(theta_o) G1m(theta_o) Spec(p, w_r)

- ``E(p)``: irradiance at the texel normal from the whole environment
  (an input, e.g. :func:`freqbrdf.light.irradiance`);
- ``F = R0 + (1 - R0)(1 - cos theta_o)^5``, ``R0 = 0.04 (1 - m) + m base``;
- ``G1(theta) = 2 / (1 + sqrt(1 + alpha^2 tan^2 theta))`` (GGX Smith); the
  masking term ``G1m = G1(theta_o)``;
- ``Spec = sum_{l <= l*} exp(-(alpha l)^2) sum_m Lg_lm Y_lm(w_r)``: the
  specular lobe as an SH filter at the world mirror direction ``w_r``, where
  ``Lg`` is the shadowed light ``G1(theta_i) L`` over the texel's upper
  hemisphere, integrated from the known environment map per texel normal
  and roughness (:func:`freqbrdf.light.shadowed_light`; paper section 4.2);
- ``d = 1`` (the paper's Lambertian term), or with ``diffuse="principled"`` the view
  dependence of the principled BSDF's diffuse lobe; ``view_weight="albedo"`` replaces
  ``F G1m`` by GGX's directional albedo (both: :func:`freqbrdf.lobes.view_table`).

Beyond the paper, the map's compact bright sources can leave ``Lg`` (`model_light`,
:func:`freqbrdf.light.extract_point_sources`): each adds the exact GGX microfacet term
``D G1(theta_i) G1m F(h.w_o) P / (4 cos theta_o)`` of its direction and power ``P`` to the
specular part (`point_terms`, ``freqbrdf.kernels._point_source``), which the SH at degree l*
would blur.

``Lg`` depends on alpha, so it is refitted every ``refit_every`` iterations
(for the texels whose roughness moved by more than ``refit_tolerance``)
and held constant in between (no gradient through the refit, as in the
authors' code). After a refit, `light_terms` stores the per-degree
contributions ``P[n, l, c] = sum_m Lg_lm,c Y_lm(w_r,n)`` of every observation
n, so ``Spec = sum_l exp(-(alpha l)^2) P[n, l]`` is cheap to evaluate and to
differentiate with respect to alpha.

Methods (the ``optimise_svbrdf`` entries of :data:`freqbrdf.methods.METHODS`):
``freq`` (shadowing and masking), ``freq_paper``
(the same on the light pre-filtered by the views' band limit a', as the
paper does: the fitted lobe then has width ``sqrt(alpha^2 + a'^2)``),
``freq_noshadow`` (``G1(theta_i) = 1``: the environment's own SH),
``freq_nomask`` (``G1m = 1``) and ``rh2001`` (neither: Ramamoorthi and
Hanrahan 2001).

Objective
---------
``loss = mean_{observed (p, k), c} |B_model - B_observed| + tv_weight * TV``:
the L1 data term is a plain mean over observed pairs (``weight > 0``) and the
three colour channels (observations are not weighted by cos theta_o). TV is the
anisotropic total variation of the parameter textures in UV space,

    TV = (1 / M) sum_{(i, j)} sum_q |x_iq - x_jq|,

over the M pairs of horizontally or vertically adjacent atlas texels that are
both among the T texels (flat index ``i * R + j``), summed over the five
parameter channels q (base R, G, B, roughness, metallic). Dividing by M makes
TV a mean absolute step per adjacency, like the data term a mean, so
``tv_weight`` keeps its meaning across texture resolutions and atlas
coverage. Both absolute values use ``sign(0) = 0`` as their derivative.

Gradients are analytic (see `loss_and_gradient`). Two solvers minimise the
objective (``OptimiseSettings.solver``):

- ``adam`` (default, as the authors' code): Adam (`adam_step`) updates all
  texels and views in one batch and clamps the parameters to [0, 1] after
  each step;
- ``lm``: per-texel Levenberg-Marquardt (:func:`freqbrdf.kernels.lm_sweep`).
  The 5 unknowns of a texel couple to other texels only through TV, so
  each sweep updates one colour of the atlas's checkerboard with the other
  held fixed, then the other colour (block coordinate descent); both
  absolute values are reweighted into least squares (IRLS), and a step is
  kept only if it lowers the texel's objective. On the tuning set it
  reaches a lower objective in 12 sweeps than Adam in 150 steps, but a
  higher parameter error (README "Second-order solver").

Without shadowing the fitted light does not depend on alpha, so
``freq_noshadow`` and ``rh2001`` fit it once.

Layout and cost
---------------
Only observed pairs are stored (`build_problem`; a 24-view capture observes
about 30% of its texel-view pairs), sorted by texel, so a texel's pairs are
one contiguous run. The per-pair work (light terms, loss, gradient, grid
start) runs in compiled kernels (:mod:`freqbrdf.kernels`) over texels on
``workers`` threads; each texel's sums are its own and the per-texel results
are summed in texel order, so results do not depend on the number of
threads. Timings are measured by ``bench/optimise_bench.py``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Mapping

import numpy as np
from scipy import sparse

from .artefacts import Observations
from .brdf import ALPHA_MIN, R0_DIELECTRIC, TEXTURES, alpha_from_roughness, tan2_theta
from .light import LightQuadrature, PointSources, extract_point_sources, irradiance, light_quadrature, shadowed_light
from .methods import get_method
from .lobes import DIFFUSE_LOBES, LOBES, VIEW_WEIGHTS, ggx_lobe_spectrum, lobe_table, view_table
from .kernels import degree_sums, grid_search, l1_loss_gradient, lm_sweep, set_threads
from .sh import recurrence_tables
from .shfit import mirror_directions
from .validation import check_choice, check_finite, check_int, check_shape

__all__ = [
    "PARAM_COLUMNS",
    "SOLVERS",
    "OptimiseSettings",
    "estimate_light",
    "Problem",
    "identifiable_roughness",
    "model_tables",
    "atlas_neighbours",
    "build_problem",
    "pack_params",
    "unpack_params",
    "light_terms",
    "refit_light",
    "forward",
    "total_variation",
    "loss_and_gradient",
    "adam_step",
    "optimise",
]

PARAM_COLUMNS = ("base_r", "base_g", "base_b", "roughness", "metallic")  # columns of a packed (T, 5) array
_N_PARAMS = len(PARAM_COLUMNS)
_DTYPES = ("float32", "float64")
SOLVERS = ("adam", "lm")
_LM_TRIES = 4  # damping increases per texel and LM sweep before its step is given up


# --------------------------------------------------------------------------
# settings and validation
# --------------------------------------------------------------------------


def _check_method(method: str) -> tuple[bool, bool]:
    """(shadowing, masking) of a method; its light's pre-filter is the caller's (`light_quadrature`)."""
    entry = get_method(method, "optimise_svbrdf")
    return entry.shadowing, entry.masking


@dataclass(frozen=True)
class OptimiseSettings:
    """Settings of `optimise` (defaults: paper section 4.3 and the authors' code).

    Attributes
    ----------
    solver : {"adam", "lm"}
        ``lm``: per-texel Levenberg-Marquardt on reweighted least squares,
        the atlas's two checkerboard colours in turn (`lm_sweep`); ``adam``:
        Adam on all texels at once (the authors' code).
    lobe : {"gaussian", "ggx"}
        Zonal spectrum of the specular lobe (`freqbrdf.lobes.LOBES`): the
        paper's ``exp(-(alpha l)^2)`` or GGX's own (`freqbrdf.lobes.ggx_lobe_spectrum`).
    view_weight : {"paper", "albedo"}
        Weight of the filtered light per view (`freqbrdf.lobes.VIEW_WEIGHTS`): the paper's
        ``F(theta_o) G1(theta_o)`` or GGX's directional albedo (`freqbrdf.lobes.view_table`),
        for the methods with shadowing and masking; the others ablate the paper's terms and keep its weight.
    diffuse : {"lambert", "principled"}
        The diffuse term's view dependence (`freqbrdf.lobes.DIFFUSE_LOBES`): the paper's
        Lambertian, or the principled BSDF's (`freqbrdf.lobes.principled_diffuse_albedo`).
    sweeps : int
        ``lm``: sweeps over both colours (one damped Gauss-Newton step per texel each).
    sweep_refit_every : int
        ``lm``: sweeps between refits of the shadowed light.
    sweep_tolerance : float
        ``lm``: stop once a sweep lowers the objective by less than this
        fraction (after the last refit).
    irls_floor, tv_floor : float
        ``lm``: floors of the reweighting of the data residuals (relative
        to each texel's mean radiance) and of the TV differences.
    damping : float
        ``lm``: initial Marquardt damping of every texel.
    iterations : int
        Adam steps (one full batch each).
    grid_start : bool
        Start each texel from the best point of a roughness x metallic grid
        (`grid_start`) unless an explicit start is given.
    grid_roughness, grid_metallic : int
        Grid points in [0, 1] of each.
    lr : float
        Adam learning rate.
    betas : tuple of float
        Adam decay rates of the first and second moment.
    eps : float
        Adam denominator offset.
    refit_every : int
        Iterations between refits of the shadowed light ``Lg`` (the first
        fit is at iteration 0; methods without shadowing fit once).
    refit_tolerance : float
        A refit skips texels whose roughness moved less than this since
        their last fit (at roughness 0.5 and 80 degrees from the normal,
        ``G1`` changes by 3%).
    tv_weight : float
        Weight of the total variation of the parameter textures, ``>= 0``.
    min_roughness : float
        Lower bound of the fitted roughness, in [0, 1), e.g.
        `identifiable_roughness` of the light's degree: below it the model
        does not resolve the lobe (README "Identifiable roughness").
    workers : int
        Threads (texels run concurrently; results are identical
        for any number).
    dtype : {"float32", "float64"}
        Precision of the per-observation arrays (parameters, gradients and
        Adam moments are always float64; the loss is accumulated in float64).
    """

    solver: str = "adam"
    lobe: str = "gaussian"
    view_weight: str = "paper"
    diffuse: str = "lambert"
    sweeps: int = 12
    sweep_refit_every: int = 4
    sweep_tolerance: float = 1e-4
    irls_floor: float = 1e-2
    tv_floor: float = 1e-2
    damping: float = 1e-2
    iterations: int = 150
    grid_start: bool = True
    grid_roughness: int = 21
    grid_metallic: int = 5
    lr: float = 0.02
    betas: tuple[float, float] = (0.9, 0.999)
    eps: float = 1e-8
    refit_every: int = 50
    refit_tolerance: float = 0.02
    tv_weight: float = 1e-3
    min_roughness: float = 0.0
    workers: int = 1
    dtype: str = "float32"

    def __post_init__(self) -> None:
        for name, choices in (("solver", SOLVERS), ("lobe", LOBES), ("view_weight", VIEW_WEIGHTS),
                              ("diffuse", DIFFUSE_LOBES), ("dtype", _DTYPES)):
            check_choice(getattr(self, name), name, choices)
        check_int(self.sweeps, "sweeps", 0)
        check_int(self.sweep_refit_every, "sweep_refit_every", 1)
        for name in ("sweep_tolerance", "irls_floor", "tv_floor", "damping"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        check_int(self.iterations, "iterations", 0)
        check_int(self.grid_roughness, "grid_roughness", 2)
        check_int(self.grid_metallic, "grid_metallic", 2)
        check_int(self.refit_every, "refit_every", 1)
        check_int(self.workers, "workers", 1)
        if not (np.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"lr must be a finite number > 0, got {self.lr!r}")
        if len(self.betas) != 2 or not all(0.0 <= b < 1.0 for b in self.betas):
            raise ValueError(f"betas must be two numbers in [0, 1), got {self.betas!r}")
        if not (np.isfinite(self.eps) and self.eps > 0):
            raise ValueError(f"eps must be a finite number > 0, got {self.eps!r}")
        if not (np.isfinite(self.refit_tolerance) and self.refit_tolerance >= 0):
            raise ValueError(f"refit_tolerance must be a finite number >= 0, got {self.refit_tolerance!r}")
        if not (np.isfinite(self.tv_weight) and self.tv_weight >= 0):
            raise ValueError(f"tv_weight must be a finite number >= 0, got {self.tv_weight!r}")
        if not 0.0 <= self.min_roughness < 1.0:
            raise ValueError(f"min_roughness must be in [0, 1), got {self.min_roughness!r}")

    @classmethod
    def from_config(cls, config: Mapping[str, object], workers: int = 1) -> OptimiseSettings:
        """Settings from config ``optimise`` (``min_roughness: auto`` is `identifiable_roughness`
        of ``lmax``; ``init: grid`` starts from the grid)."""
        bound = config["min_roughness"]
        return cls(solver=config["solver"], lobe=config["lobe"], view_weight=config["view_weight"],
                   diffuse=config["diffuse"], sweeps=config["sweeps"],
                   sweep_refit_every=config["sweep_refit_every"],
                   iterations=config["iterations"], lr=config["lr"], refit_every=config["refit_every"],
                   tv_weight=config["tv_weight"], workers=workers, grid_start=config["init"] == "grid",
                   min_roughness=identifiable_roughness(config["lmax"], lobe=config["lobe"]) if bound == "auto"
                   else float(bound))


def estimate_light(
    envmap: np.ndarray, obs: Observations, method: str, lmax: int, point_sources: Mapping[str, float] | None = None,
) -> tuple[LightQuadrature, np.ndarray]:
    """The light of a method's model at degree ``lmax`` and the irradiance at the texel normals:
    the map as it is, or low-passed by the views' band limit a' for a ``prefiltered`` method
    (``freq_paper``: paper section 4.2). With ``point_sources`` (``max_radius_deg``,
    ``min_radiance``: `freqbrdf.light.extract_point_sources`), for a method that is not
    pre-filtered, the map's compact bright sources leave the SH light and ride along as ``LightQuadrature.sources``;
    the irradiance is always the whole map's."""
    return model_light(envmap, obs, method, lmax, point_sources), irradiance(envmap, obs.texels.normal)


def model_light(
    envmap: np.ndarray, obs: Observations, method: str, lmax: int, point_sources: Mapping[str, float] | None = None,
) -> LightQuadrature:
    """The light of `estimate_light` without the irradiance."""
    prefiltered = get_method(method).prefiltered
    if prefiltered or not point_sources or not point_sources["max_radius_deg"]:
        return light_quadrature(envmap, lmax, prefilter=obs.a_prime if prefiltered else 0.0)
    residual, sources = extract_point_sources(envmap, point_sources["max_radius_deg"], point_sources["min_radiance"])
    return dataclasses.replace(light_quadrature(residual, lmax), sources=sources)


def point_terms(
    problem: Problem, sources: PointSources | None, shadowing: bool,
) -> tuple[np.ndarray, np.ndarray] | None:
    """The kernels' ``point`` argument (`freqbrdf.kernels.l1_loss_gradient`) for ``sources``: each
    pair's view and, per observed texel (internal order) and source, its direction in the
    texel's frame, ``tan^2 theta_i`` (0 without ``shadowing``: G1 = 1) and its power.
    None if there are no sources."""
    if sources is None or not len(sources.power):
        return None
    local = np.einsum("tij,sj->tsi", problem.frame[problem.observed], sources.directions)  # (T_obs, S, 3)
    cos_i = local[..., 2]
    tan2_i = tan2_theta(np.clip(cos_i, 1e-6, 1.0)) if shadowing else np.zeros_like(cos_i)
    power = np.broadcast_to(sources.power[None], cos_i.shape + (3,))
    return problem.wo_local, np.concatenate([local, tan2_i[..., None], power], axis=2)


# --------------------------------------------------------------------------
# BRDF terms
# --------------------------------------------------------------------------


def identifiable_roughness(lmax: int, tail: float = 0.05, lobe: str = "gaussian") -> float:
    """Smallest roughness whose lobe the model at degree l* represents.

    The lobe ``exp(-(alpha l)^2)`` applied to a point light has its value at
    the mirror direction spread over degrees with weights ``(2l + 1) exp(-(alpha l)^2)``;
    the share above l* is about ``exp(-(alpha (l* + 1))^2)``. Requiring it
    below ``tail`` gives ``alpha >= sqrt(ln(1 / tail)) / (l* + 1)``, and
    ``roughness = sqrt(alpha)``: 0.29 at l* = 20 (measured on noise-free texels
    under the sun: roughness 0.3 recovered within 0.04, 0.25 off by up to 0.13).
    GGX's spectrum (`freqbrdf.lobes.ggx_lobe_spectrum`) keeps more of the high
    degrees; its share above l* is summed numerically (to degree 16 (l* + 1))
    and the alpha where it falls below ``tail`` bisected (to 1e-4): 0.356 at l* = 20.

    Parameters
    ----------
    lmax : int
        Degree l* of the model's light.
    tail : float
        Largest share of the lobe allowed above l*, in (0, 1).
    lobe : {"gaussian", "ggx"}
        The lobe (`freqbrdf.lobes.LOBES`).

    Returns
    -------
    float
        Roughness in (0, 1).
    """
    lmax = check_int(lmax, "lmax", 0)
    if not 0.0 < tail < 1.0:
        raise ValueError(f"tail must be in (0, 1), got {tail!r}")
    if check_choice(lobe, "lobe", LOBES) == "gaussian":
        return float(np.sqrt(min(np.sqrt(np.log(1.0 / tail)) / (lmax + 1), 1.0)))
    degrees = np.arange(16 * (lmax + 1) + 1)

    def share_above(alpha: float) -> float:
        weight = (2 * degrees + 1) * ggx_lobe_spectrum(np.array([alpha]), degrees[-1])[0][0]
        return float(weight[lmax + 1 :].sum() / weight.sum())

    if share_above(1.0) >= tail:
        return 1.0
    lo, hi = ALPHA_MIN, 1.0  # the share falls as the lobe widens: bisect for where it crosses ``tail``
    while hi - lo > 1e-4:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if share_above(mid) >= tail else (lo, mid)
    return float(np.sqrt(hi))


def atlas_neighbours(texel: np.ndarray, resolution: int) -> np.ndarray:
    """Horizontally and vertically adjacent pairs among the given atlas texels.

    Parameters
    ----------
    texel : numpy.ndarray
        Shape ``(T,)``, unique flat indices ``i * R + j``.
    resolution : int
        Atlas size R.

    Returns
    -------
    numpy.ndarray
        Shape ``(M, 2)``, int64 positions into ``texel`` (not flat indices):
        all horizontal pairs (row-major), then all vertical ones.
    """
    resolution = check_int(resolution, "resolution", 1)
    t = np.asarray(texel)
    lookup = np.full(resolution * resolution, -1, dtype=np.int64)
    lookup[t] = np.arange(t.shape[0])
    grid = lookup.reshape(resolution, resolution)
    pairs = np.concatenate(
        [
            np.stack([grid[:, :-1].ravel(), grid[:, 1:].ravel()], axis=1),
            np.stack([grid[:-1, :].ravel(), grid[1:, :].ravel()], axis=1),
        ]
    )
    return pairs[(pairs >= 0).all(axis=1)]


# --------------------------------------------------------------------------
# observations
# --------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Problem:
    """Observations of one capture in the layout the estimator works on.

    Build with `build_problem`. There are N observed (texel, view) pairs,
    sorted by texel; T_obs of the T texels have at least one. Internally the
    parameters live in a permuted texel order (``perm``): the observed texels,
    then the others, so that the observed ones are a contiguous slice.

    Attributes
    ----------
    n_texels, n_views : int
        T and K.
    pair_texel, pair_view : numpy.ndarray
        Shape ``(N,)``, int64: texel (0..T-1) and view of each pair.
    pair_slot : numpy.ndarray
        Shape ``(N,)``, int64: index of the pair's texel in ``observed``.
    observed : numpy.ndarray
        Shape ``(T_obs,)``, int64: texels with at least one pair, ascending.
    weight, cos_o : numpy.ndarray
        Shape ``(N,)``, float64: fit weight and ``cos theta_o``.
    mirror : numpy.ndarray
        Shape ``(N, 3)``, float64: mirror direction (unit, world frame).
    wo_local : numpy.ndarray
        Shape ``(N, 3)``, float64: view direction in the texel's frame.
    frame : numpy.ndarray
        Shape ``(T, 3, 3)``, float64: rows tangent, bitangent, normal (world frame).
    normal : numpy.ndarray
        Shape ``(T, 3)``, float64: texel normal (world frame).
    irradiance : numpy.ndarray
        Shape ``(T, 3)``, float64: E at each texel normal.
    neighbours : numpy.ndarray
        Shape ``(M, 2)``, int64: `atlas_neighbours` of the texels.
    perm : numpy.ndarray
        Shape ``(T,)``, int64: texel at each internal position.
    start : numpy.ndarray
        Shape ``(T_obs + 1,)``, int64: first pair of each observed texel.
    radiance : numpy.ndarray
        Shape ``(N, 3)``, ``dtype``: observed B of each pair.
    schlick, tan2 : numpy.ndarray
        Shape ``(N,)``, ``dtype``: ``(1 - cos theta_o)^5`` and ``tan^2 theta_o``.
    irradiance_pi : numpy.ndarray
        Shape ``(T_obs, 3)``, float64: ``E / pi`` of the observed texels.
    tv_operator, tv_adjoint : scipy.sparse.csr_matrix
        Shapes ``(M, T)`` and ``(T, M)``: ``x_i - x_j`` of each neighbour pair
        (internal order) and its transpose.
    nb_start, nb : numpy.ndarray
        Shapes ``(T + 1,)`` and ``(2 M,)``, int64: the neighbours of internal
        texel s are ``nb[nb_start[s]:nb_start[s + 1]]`` (internal order).
    colours : tuple of numpy.ndarray
        The internal texels of each colour of the atlas's checkerboard
        (``(i + j) % 2`` of atlas row i, column j): no two of one colour are
        neighbours.
    dtype : numpy.dtype
        Precision of the per-observation arrays of the loss.
    """

    n_texels: int
    n_views: int
    pair_texel: np.ndarray
    pair_view: np.ndarray
    pair_slot: np.ndarray
    observed: np.ndarray
    weight: np.ndarray
    cos_o: np.ndarray
    mirror: np.ndarray
    wo_local: np.ndarray
    frame: np.ndarray
    normal: np.ndarray
    irradiance: np.ndarray
    neighbours: np.ndarray
    perm: np.ndarray
    start: np.ndarray
    radiance: np.ndarray
    schlick: np.ndarray
    tan2: np.ndarray
    irradiance_pi: np.ndarray
    tv_operator: sparse.csr_matrix
    tv_adjoint: sparse.csr_matrix
    nb_start: np.ndarray
    nb: np.ndarray
    colours: tuple[np.ndarray, np.ndarray]
    dtype: np.dtype

    @property
    def n_pairs(self) -> int:
        """Number of observed pairs N."""
        return int(self.pair_texel.shape[0])

    @property
    def n_observed(self) -> int:
        """Number of texels with at least one pair, T_obs."""
        return int(self.observed.shape[0])


def _difference_operator(neighbours: np.ndarray, n_texels: int) -> sparse.csr_matrix:
    """Sparse (M, T) matrix taking x to ``x_i - x_j`` for each neighbour pair (i, j)."""
    m = neighbours.shape[0]
    rows = np.repeat(np.arange(m), 2)
    vals = np.tile([1.0, -1.0], m)
    return sparse.csr_matrix((vals, (rows, neighbours.ravel())), shape=(m, n_texels))


def _adjacency(pairs: np.ndarray, n_texels: int) -> tuple[np.ndarray, np.ndarray]:
    """Neighbour lists (CSR: start (T + 1,), index (2 M,)) of undirected pairs (M, 2)."""
    both = np.concatenate([pairs, pairs[:, ::-1]])
    both = both[np.lexsort((both[:, 1], both[:, 0]))]
    start = np.concatenate([[0], np.cumsum(np.bincount(both[:, 0], minlength=n_texels))])
    return start.astype(np.int64), both[:, 1].astype(np.int64)


def _check_inputs(obs: Observations, irradiance: np.ndarray) -> np.ndarray:
    """Validate the arrays `build_problem` reads; return the irradiance (T, 3) as float64."""
    w = np.asarray(obs.weight)
    check_shape(w, "weight", (None, None))
    n_tex, n_views = w.shape
    for name in ("radiance", "wo_local"):
        check_shape(np.asarray(getattr(obs, name)), name, (n_tex, n_views, 3))
    frame = obs.frame
    check_shape(frame, "frame", (n_tex, 3, 3))
    check_finite(frame, "frame")
    e = np.asarray(irradiance, dtype=np.float64)
    check_shape(e, "irradiance", (n_tex, 3))
    check_finite(e, "irradiance")
    t, resolution = np.asarray(obs.texels.texel), check_int(obs.texels.resolution, "resolution", 1)
    check_shape(t, "texel", (n_tex,))
    if not np.issubdtype(t.dtype, np.integer):
        raise TypeError(f"texel must hold integers, got dtype {t.dtype}")
    if n_tex and (t.min() < 0 or t.max() >= resolution * resolution):
        bad = t[(t < 0) | (t >= resolution * resolution)][0]
        raise ValueError(
            f"texel indices must be in [0, {resolution * resolution}) for resolution {resolution}, got {bad}"
        )
    if np.unique(t).shape[0] != n_tex:
        raise ValueError("texel indices must be unique")
    check_finite(w, "weight")
    if (w < 0).any():
        i, k = np.argwhere(w < 0)[0]
        raise ValueError(f"weight must be >= 0, got {float(w[i, k])!r} at texel {i}, view {k}")
    return e


def _observed_pairs(obs: Observations) -> tuple[np.ndarray, ...]:
    """Texel and view of every observed pair (row-major, so sorted by texel), its radiance (n, 3),
    unit direction to the camera (n, 3) and cos theta_o (n,), checked to be usable."""
    pt, pv = np.nonzero(np.asarray(obs.weight) > 0)
    if pt.shape[0] == 0:
        raise ValueError("weight has no observed pair (no entry > 0)")
    b_p = np.asarray(obs.radiance)[pt, pv].astype(np.float64)
    wo_p = np.asarray(obs.wo_local)[pt, pv].astype(np.float64)
    for name, a in (("radiance", b_p), ("wo_local", wo_p)):
        bad = ~np.isfinite(a).all(axis=1)
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(
                f"{name} must be finite where weight > 0, got {a[i].tolist()} at texel {pt[i]}, view {pv[i]}"
            )
    norm = np.sqrt(np.einsum("ni,ni->n", wo_p, wo_p))
    cos_o = wo_p[:, 2] / np.where(norm > 0, norm, 1.0)
    bad = ~(cos_o > 0)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(
            f"wo_local must point above the surface (z > 0) where weight > 0, got {wo_p[i].tolist()} "
            f"at texel {pt[i]}, view {pv[i]}"
        )
    return pt, pv, b_p, wo_p / norm[:, None], cos_o


def build_problem(obs: Observations, irradiance: np.ndarray, dtype: str = "float32") -> Problem:
    """Validate a capture's observations and arrange them for the estimator.

    Parameters
    ----------
    obs : Observations
        The capture's T texels x K views: ``radiance`` B, ``weight`` (pairs
        with ``weight > 0`` are the observations), ``wo_local``, the texel
        frames and atlas indices (:class:`freqbrdf.artefacts.Observations`).
    irradiance : numpy.ndarray
        Shape ``(T, 3)``, E at the texel normals (radiance times sr).
    dtype : {"float32", "float64"}
        Precision of the per-observation arrays of the loss.

    Returns
    -------
    Problem
    """
    if dtype not in _DTYPES:
        raise ValueError(f"dtype must be one of {_DTYPES}, got {dtype!r}")
    e = _check_inputs(obs, irradiance)
    n_tex, n_views = obs.weight.shape
    fr, t, resolution = obs.frame.astype(np.float64), np.asarray(obs.texels.texel), int(obs.texels.resolution)
    w = np.asarray(obs.weight)
    pt, pv, b_p, wo_p, cos_o = _observed_pairs(obs)

    all_counts = np.bincount(pt, minlength=n_tex)
    observed = np.nonzero(all_counts)[0].astype(np.int64)
    counts = all_counts[observed]
    ftype = np.dtype(dtype)
    perm = np.concatenate([observed, np.nonzero(all_counts == 0)[0]]).astype(np.int64)
    position = np.empty(n_tex, dtype=np.int64)
    position[perm] = np.arange(n_tex)
    neighbours = atlas_neighbours(t, resolution)
    tv_op = _difference_operator(position[neighbours], n_tex)
    nb_start, nb = _adjacency(position[neighbours], n_tex)
    parity = (t[perm] // resolution + t[perm] % resolution) % 2
    return Problem(
        n_texels=n_tex,
        n_views=n_views,
        pair_texel=pt.astype(np.int64),
        pair_view=pv.astype(np.int64),
        pair_slot=np.repeat(np.arange(observed.shape[0], dtype=np.int64), counts),
        observed=observed,
        weight=w[pt, pv].astype(np.float64),
        cos_o=cos_o,
        mirror=np.einsum("nji,nj->ni", fr[pt], mirror_directions(wo_p)),
        wo_local=np.asarray(wo_p, dtype=np.float64),
        frame=fr,
        normal=fr[:, 2] / np.linalg.norm(fr[:, 2], axis=1, keepdims=True),
        irradiance=e,
        neighbours=neighbours,
        perm=perm,
        start=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        radiance=b_p.astype(ftype),
        schlick=((1.0 - cos_o) ** 5).astype(ftype),
        tan2=tan2_theta(cos_o).astype(ftype),
        irradiance_pi=e[observed] / np.pi,
        tv_operator=tv_op,
        tv_adjoint=tv_op.T.tocsr(),
        nb_start=nb_start,
        nb=nb,
        colours=(np.nonzero(parity == 0)[0].astype(np.int64), np.nonzero(parity == 1)[0].astype(np.int64)),
        dtype=ftype,
    )


def pack_params(params: Mapping[str, np.ndarray], n_texels: int) -> np.ndarray:
    """Parameter textures as one ``(T, 5)`` array (columns `PARAM_COLUMNS`).

    Parameters
    ----------
    params : mapping
        ``base_color`` (T, 3), ``roughness`` (T,), ``metallic`` (T,), in [0, 1].
    n_texels : int
        T.

    Returns
    -------
    numpy.ndarray
        Shape ``(T, 5)``, float64.
    """
    missing = [k for k in TEXTURES if k not in params]
    if missing:
        raise ValueError(f"params lacks {missing}; expected keys {TEXTURES}")
    out = np.empty((n_texels, _N_PARAMS))
    for name, cols, shape in (
        ("base_color", slice(0, 3), (n_texels, 3)),
        ("roughness", 3, (n_texels,)),
        ("metallic", 4, (n_texels,)),
    ):
        a = np.asarray(params[name], dtype=np.float64)
        check_shape(a, name, shape)
        check_finite(a, name)
        if (a < 0).any() or (a > 1).any():
            raise ValueError(f"{name} must be in [0, 1], got {float(a[(a < 0) | (a > 1)][0])!r}")
        out[:, cols] = a
    return out


def unpack_params(x: np.ndarray) -> dict[str, np.ndarray]:
    """Inverse of `pack_params`: ``(T, 5)`` -> ``base_color`` (T, 3), ``roughness``, ``metallic`` (T,)."""
    x = np.asarray(x, dtype=np.float64)
    check_shape(x, "x", (None, _N_PARAMS))
    return {"base_color": x[:, :3].copy(), "roughness": x[:, 3].copy(), "metallic": x[:, 4].copy()}


def _check_x(x: np.ndarray, problem: Problem) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    check_shape(x, "x", (problem.n_texels, _N_PARAMS))
    check_finite(x, "x")
    return x


# --------------------------------------------------------------------------
# shadowed light
# --------------------------------------------------------------------------
def light_terms(
    roughness: np.ndarray,
    problem: Problem,
    shadowing: bool,
    light: LightQuadrature,
    workers: int = 1,
) -> np.ndarray:
    """Per-degree contributions of the (shadowed) environment light at each observation.

    With shadowing, ``Lg`` is the SH fit (degree ``light.lmax``) of
    ``G1(theta_i, alpha) L`` over each texel's upper hemisphere by dense
    quadrature of the known environment (paper section 4.2, Fig. 2:
    :func:`freqbrdf.light.shadowed_light`); without it, ``Lg`` is the
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
        The environment (:func:`freqbrdf.light.light_quadrature`).
    workers : int
        Threads of the evaluation.

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
        refit_light(out, r, problem, light, np.arange(problem.n_observed), workers)
    else:
        lg = (light.basis.T.astype(np.float64) @ light.weighted_radiance)[None]  # (1, n, 3)
        pairs = np.arange(problem.n_pairs)
        _evaluate_light(out, pairs, np.zeros_like(pairs), lg, problem, workers)
    return out


def refit_light(
    out: np.ndarray, roughness: np.ndarray, problem: Problem, light: LightQuadrature, slots: np.ndarray,
    workers: int,
) -> None:
    """Refit the shadowed light of the observed texels ``slots`` (positions into ``problem.observed``)
    at ``roughness`` and overwrite their observations' rows of ``out`` (`light_terms`)."""
    alpha = alpha_from_roughness(roughness[problem.observed[slots]])[0]
    lg = shadowed_light(light, problem.normal[problem.observed[slots]], alpha, workers)  # (s, n, 3)
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


def _check_light(light: np.ndarray, problem: Problem) -> np.ndarray:
    p = np.asarray(light)
    check_shape(p, "light", (problem.n_pairs, None, 3))
    check_finite(p, "light")
    return p


# --------------------------------------------------------------------------
# model, loss and gradient
# --------------------------------------------------------------------------
def _tv(xp: np.ndarray, op: sparse.csr_matrix, adjoint: sparse.csr_matrix) -> tuple[float, np.ndarray]:
    """TV and its gradient with a difference operator and its transpose (see `total_variation`)."""
    if op.shape[0] == 0:
        return 0.0, np.zeros_like(xp)
    diff = op @ xp
    # sign(0) = 0: a flat pair pulls neither texel
    return float(np.abs(diff).sum() / op.shape[0]), adjoint @ (np.sign(diff) / op.shape[0])


def total_variation(x: np.ndarray, neighbours: np.ndarray) -> tuple[float, np.ndarray]:
    """Mean absolute difference of adjacent texels, summed over parameter channels.

    Parameters
    ----------
    x : numpy.ndarray
        Shape ``(T, Q)``, parameter channels per texel.
    neighbours : numpy.ndarray
        Shape ``(M, 2)``, adjacent texel pairs (`atlas_neighbours`).

    Returns
    -------
    tv : float
        ``(1/M) sum_pairs sum_q |x_iq - x_jq|`` (0 without pairs).
    grad : numpy.ndarray
        Shape ``(T, Q)``, float64, its (sub)gradient with ``sign(0) = 0``.
    """
    x = np.asarray(x, dtype=np.float64)
    check_shape(x, "x", (None, None))
    nb = np.asarray(neighbours)
    check_shape(nb, "neighbours", (None, 2))
    if nb.size and (nb.min() < 0 or nb.max() >= x.shape[0]):
        raise ValueError(f"neighbours must index the {x.shape[0]} rows of x, got {nb.min()}..{nb.max()}")
    op = _difference_operator(nb, x.shape[0])
    return _tv(x, op, op.T.tocsr())


def _l1(xp: np.ndarray, problem: Problem, light: np.ndarray, masking: bool, model: np.ndarray | None = None,
        lobe: np.ndarray | None = None, view: np.ndarray | None = None, point: tuple | None = None):
    """Per-texel L1 data term and gradient of the observed texels (`freqbrdf.kernels.l1_loss_gradient`)."""
    return l1_loss_gradient(
        np.ascontiguousarray(xp[: problem.n_observed]), problem.start, light, problem.radiance, problem.schlick,
        problem.tan2, problem.irradiance_pi, masking, ALPHA_MIN, R0_DIELECTRIC, model, lobe, view, point,
    )


def _loss_and_gradient(
    xp: np.ndarray, problem: Problem, light: np.ndarray, masking: bool, tv_weight: float,
    lobe: np.ndarray | None = None, view: np.ndarray | None = None, point: tuple | None = None,
) -> tuple[float, np.ndarray]:
    """`loss_and_gradient` of internal-order ``xp`` (texel-order sums, so independent of threads)."""
    loss_per_texel, grad_obs = _l1(xp, problem, light, masking, lobe=lobe, view=view, point=point)
    scale = 1.0 / (3.0 * problem.n_pairs)  # mean over pairs and channels
    grad = np.zeros_like(xp)
    grad[: problem.n_observed] = grad_obs * scale
    loss = float(np.sum(loss_per_texel)) * scale
    if tv_weight > 0:
        tv, tv_grad = _tv(xp, problem.tv_operator, problem.tv_adjoint)
        loss += tv_weight * tv
        grad += tv_weight * tv_grad
    return float(loss), grad


def forward(x: np.ndarray, problem: Problem, light: np.ndarray, masking: bool,
            lobe: np.ndarray | None = None, view: np.ndarray | None = None, point: tuple | None = None) -> np.ndarray:
    """Model radiance of every observation.

    Parameters
    ----------
    x : numpy.ndarray
        Shape ``(T, 5)``, packed parameters (`pack_params`).
    problem : Problem
        Observations.
    light : numpy.ndarray
        Shape ``(N, L, 3)``: `light_terms` (its ``shadowing`` picks the variant).
    masking : bool
        Apply ``G1(theta_o)`` to the specular term.
    lobe : numpy.ndarray, optional
        The lobe spectrum (:func:`freqbrdf.lobes.lobe_table`); default the paper's Gaussian.
    view : numpy.ndarray, optional
        The weights per view, specular and diffuse (:func:`freqbrdf.lobes.view_table`); default the paper's
        ``F(theta_o) G1(theta_o)`` and Lambertian diffuse term.
    point : tuple of numpy.ndarray, optional
        Point sources outside ``light`` (`point_terms`); default none.

    Returns
    -------
    numpy.ndarray
        Shape ``(T, K, 3)``, float64, radiance; 0 where not observed.
    """
    x = _check_x(x, problem)
    p = _check_light(light, problem)
    model = np.empty((problem.n_pairs, 3))
    _l1(x[problem.perm], problem, p, masking, model, lobe, view, point)
    out = np.zeros((problem.n_texels, problem.n_views, 3))
    out[problem.pair_texel, problem.pair_view] = model
    return out


def loss_and_gradient(
    x: np.ndarray, problem: Problem, light: np.ndarray, masking: bool, tv_weight: float = 1e-3, workers: int = 1,
    lobe: np.ndarray | None = None, view: np.ndarray | None = None, point: tuple | None = None,
) -> tuple[float, np.ndarray]:
    """Objective of paper Eq. 13 plus total variation (section 4.3) and its analytic gradient, light terms held fixed.

    ``loss = mean_{pairs, c} |B - B_obs| + tv_weight * TV`` (module docstring).
    With ``g = sign(B - B_obs) / (3 N)`` and ``c5 = (1 - cos theta_o)^5``:

    - ``dL/dbase_c = sum_k g [(1 - m) E_c / pi + m (1 - c5) G1m Spec_c]``;
    - ``dL/dm = sum_kc g [-base_c E_c / pi + (base_c - 0.04)(1 - c5) G1m Spec_c]``;
    - ``dL/dr = 2 r sum_kc g F_c [G1m' Spec_c + G1m sum_l f_l' P_lc]`` with
      ``G1m' = dG1/dalpha = -2 alpha tan^2 / (s (1 + s)^2)``,
      ``s = sqrt(1 + alpha^2 tan^2)``, ``f_l' = -2 alpha l^2 exp(-(alpha l)^2)`` (the Gaussian lobe;
      GGX's from its table, `freqbrdf.lobes.lobe_table`)
      (where alpha is clamped at `ALPHA_MIN`, ``2 r`` becomes ``2 sqrt(ALPHA_MIN)``:
      a straight-through derivative, see `alpha_from_roughness`);

    plus ``tv_weight`` times the TV gradient (`total_variation`). With a ``view`` table,
    ``E_c / pi`` becomes ``d E_c / pi`` and ``(1 - c5) G1m``, ``c5 G1m`` become ``a``, ``b``
    (`freqbrdf.lobes.view_table`), each with its own derivative in alpha in ``dL/dr``.

    Parameters
    ----------
    x : numpy.ndarray
        Shape ``(T, 5)``, packed parameters.
    problem : Problem
        Observations.
    light : numpy.ndarray
        Shape ``(N, L, 3)``, `light_terms`.
    masking : bool
        Apply ``G1(theta_o)``.
    tv_weight : float
        Weight of TV, ``>= 0``.
    workers : int
        Threads.
    lobe : numpy.ndarray, optional
        The lobe spectrum (:func:`freqbrdf.lobes.lobe_table`); default the paper's Gaussian.
    view : numpy.ndarray, optional
        The weights per view, specular and diffuse (:func:`freqbrdf.lobes.view_table`); default the paper's
        ``F(theta_o) G1(theta_o)`` and Lambertian diffuse term.
    point : tuple of numpy.ndarray, optional
        Point sources outside ``light`` (`point_terms`); default none.

    Returns
    -------
    loss : float
    grad : numpy.ndarray
        Shape ``(T, 5)``, float64.
    """
    x = _check_x(x, problem)
    p = _check_light(light, problem)
    tv_weight = float(tv_weight)
    if not (np.isfinite(tv_weight) and tv_weight >= 0):
        raise ValueError(f"tv_weight must be a finite number >= 0, got {tv_weight!r}")
    set_threads(check_int(workers, "workers", 1))
    loss, grad_p = _loss_and_gradient(x[problem.perm], problem, p, masking, tv_weight, lobe, view, point)
    grad = np.empty_like(grad_p)
    grad[problem.perm] = grad_p
    return loss, grad


def grid_start(
    problem: Problem, light: np.ndarray, masking: bool, roughness: np.ndarray, metallic: np.ndarray,
    workers: int = 1, lobe: np.ndarray | None = None, view: np.ndarray | None = None, point: tuple | None = None,
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
    light : numpy.ndarray
        Shape ``(N, L, 3)``, `light_terms` (shadowed at any fixed roughness).
    masking : bool
        Apply ``G1(theta_o)``.
    roughness, metallic : numpy.ndarray
        1-D grids of candidate values in [0, 1].
    workers : int
        Threads.
    lobe : numpy.ndarray, optional
        The lobe spectrum (:func:`freqbrdf.lobes.lobe_table`); default the paper's Gaussian.
    view : numpy.ndarray, optional
        The weights per view, specular and diffuse (:func:`freqbrdf.lobes.view_table`); default the paper's
        ``F(theta_o) G1(theta_o)`` and Lambertian diffuse term.
    point : tuple of numpy.ndarray, optional
        Point sources outside ``light`` (`point_terms`); default none.

    Returns
    -------
    numpy.ndarray
        Shape ``(T, 5)``, packed parameters; 0.5 for texels without observations.
    """
    p = _check_light(light, problem)
    set_threads(check_int(workers, "workers", 1))
    xp = np.full((problem.n_texels, _N_PARAMS), 0.5)
    xp[: problem.n_observed] = grid_search(
        problem.start, p, problem.radiance, problem.schlick, problem.tan2, problem.irradiance_pi, masking,
        ALPHA_MIN, R0_DIELECTRIC, roughness, metallic, lobe, view, point,
    )
    x = np.empty_like(xp)
    x[problem.perm] = xp
    return x


# --------------------------------------------------------------------------
# optimisation
# --------------------------------------------------------------------------
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
    settings: OptimiseSettings = OptimiseSettings(),
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Per-texel principled parameters minimising the L1 + TV objective (Adam or LM: ``settings.solver``).

    Parameters
    ----------
    obs : Observations
        The capture's T texels x K views (:class:`freqbrdf.artefacts.Observations`);
        the atlas indices of its texels define the TV neighbours.
    irradiance : numpy.ndarray
        Shape ``(T, 3)``: E at the texel normals (:func:`freqbrdf.light.irradiance`).
    light : LightQuadrature
        The environment that lit the capture, at the model's degree l*
        (:func:`freqbrdf.light.light_quadrature`).
    init : mapping, optional
        ``base_color`` (T, 3), ``roughness`` (T,), ``metallic`` (T,) in [0, 1],
        e.g. the spectrum-only estimate; default 0.5 everywhere.
    method : str
        A method of rule ``optimise_svbrdf`` in :data:`freqbrdf.methods.METHODS`.
    settings : OptimiseSettings
        Solver and SH fit settings.

    Returns
    -------
    params : dict of numpy.ndarray
        ``base_color`` (T, 3), ``roughness`` (T,), ``metallic`` (T,), float64
        in [0, 1]. Texels without observations move only through TV.
    loss_curve : numpy.ndarray
        The objective at the start of each Adam iteration or LM sweep
        (after that iteration's refit, if any, so it may jump at refits);
        an LM run that meets ``sweep_tolerance`` early has fewer entries
        than ``sweeps``.
    """
    shadowing, masking = _check_method(method)
    if not isinstance(settings, OptimiseSettings):
        raise TypeError(f"settings must be an OptimiseSettings, got {type(settings).__name__}")
    problem = build_problem(obs, irradiance, settings.dtype)
    lobe, view = model_tables(settings, method, light.lmax)
    point = point_terms(problem, light.sources, shadowing)
    xp = _start(problem, light, init, shadowing, masking, lobe, view, point, settings)[problem.perm]  # internal order
    descend = _descend_lm if settings.solver == "lm" else _descend
    xp, curve = descend(xp, problem, light, shadowing, masking, lobe, view, point, settings)
    x = np.empty_like(xp)
    x[problem.perm] = xp
    return unpack_params(x), curve


def model_tables(settings: OptimiseSettings, method: str, lmax: int) -> tuple[np.ndarray, np.ndarray]:
    """The lobe (`freqbrdf.lobes.lobe_table`) and view (`freqbrdf.lobes.view_table`) tables of
    ``method``'s model at degree ``lmax``: ``settings.view_weight`` applies to the methods with
    shadowing and masking, the others ablate the paper's terms and keep its specular weight."""
    shadowing, masking = _check_method(method)
    view_weight = settings.view_weight if shadowing and masking else "paper"
    return lobe_table(settings.lobe, lmax), view_table(view_weight, settings.diffuse, settings.lobe, lmax)


def _start(
    problem: Problem, light: LightQuadrature, init: Mapping[str, np.ndarray] | None, shadowing: bool, masking: bool,
    lobe: np.ndarray, view: np.ndarray, point: tuple | None, settings: OptimiseSettings,
) -> np.ndarray:
    """Packed start parameters (T, 5): ``init``, else the grid start or 0.5 everywhere."""
    if init is not None:
        return pack_params(init, problem.n_texels)
    if settings.grid_start:
        # shadowed at a middle roughness: with the unshadowed light (no horizon) 1 of the 64
        # texels of the noise-free test in tests/test_light.py starts in another basin
        return grid_start(
            problem, light_terms(np.full(problem.n_texels, 0.5), problem, shadowing, light, settings.workers),
            masking, np.linspace(0.0, 1.0, settings.grid_roughness), np.linspace(0.0, 1.0, settings.grid_metallic),
            settings.workers, lobe, view, point,
        )
    return np.full((problem.n_texels, _N_PARAMS), 0.5)


class _ShadowedLight:
    """The light terms of the observations, refitted for the texels whose roughness moved."""

    def __init__(self, xp: np.ndarray, problem: Problem, light: LightQuadrature, shadowing: bool,
                 settings: OptimiseSettings):
        self.problem, self.light, self.shadowing, self.settings = problem, light, shadowing, settings
        self.roughness = np.empty(problem.n_texels)
        self.roughness[problem.perm] = xp[:, 3]
        self.terms = light_terms(self.roughness, problem, shadowing, light, settings.workers)
        self.fitted = self.roughness[problem.observed]  # roughness each texel's light was fitted at

    def refit(self, xp: np.ndarray) -> int:
        """Refit the texels that moved by more than ``refit_tolerance`` since their last fit (most
        stay near their start); returns how many. Without shadowing the fitted light does not
        depend on alpha: the first fit is exact."""
        if not self.shadowing:
            return 0
        self.roughness[self.problem.perm] = xp[:, 3]
        now = self.roughness[self.problem.observed]
        slots = np.nonzero(np.abs(now - self.fitted) > self.settings.refit_tolerance)[0]
        if slots.size:
            refit_light(self.terms, self.roughness, self.problem, self.light, slots, self.settings.workers)
            self.fitted[slots] = now[slots]
        return int(slots.size)


def _descend_lm(
    xp: np.ndarray, problem: Problem, light: LightQuadrature, shadowing: bool, masking: bool, lobe: np.ndarray,
    view: np.ndarray, point: tuple | None, settings: OptimiseSettings,
) -> tuple[np.ndarray, np.ndarray]:
    """Levenberg-Marquardt sweeps from ``xp`` (internal order; `freqbrdf.kernels.lm_sweep`), refitting
    the shadowed light every ``sweep_refit_every`` sweeps; returns the parameters and the objective
    at the start of each sweep.

    Each sweep updates the texels of one checkerboard colour with the other's held fixed, then the
    other colour: block coordinate descent, so the objective does not rise between refits. The
    objective is the one Adam minimises (`loss_and_gradient`), L1 data term and TV alike.
    """
    xp = xp.copy()
    xp[:, 3] = np.maximum(xp[:, 3], settings.min_roughness)
    if not settings.sweeps:
        return xp, np.empty(0)
    set_threads(settings.workers)
    lg = _ShadowedLight(xp, problem, light, shadowing, settings)
    lower = np.array([0.0, 0.0, 0.0, settings.min_roughness, 0.0])
    upper = np.ones(_N_PARAMS)
    lam = np.full(problem.n_texels, settings.damping)
    n_edges = max(problem.tv_operator.shape[0], 1)
    curve: list[float] = []
    last_refit = 0
    for sweep in range(settings.sweeps):
        if sweep and sweep % settings.sweep_refit_every == 0 and lg.refit(xp):
            last_refit = sweep
        loss = _loss_and_gradient(xp, problem, lg.terms, masking, settings.tv_weight, lobe, view, point)[0]
        if sweep > last_refit and curve[-1] - loss < settings.sweep_tolerance * curve[-1]:
            break
        curve.append(loss)
        for texels in problem.colours:
            lm_sweep(xp, texels, problem.start, lg.terms, problem.radiance, problem.schlick, problem.tan2,
                     problem.irradiance_pi, masking, ALPHA_MIN, R0_DIELECTRIC, problem.nb_start, problem.nb,
                     1.0 / (3.0 * problem.n_pairs), settings.tv_weight / n_edges, lower, upper,
                     settings.irls_floor, settings.tv_floor, lam, _LM_TRIES, lobe, view, point)
    return xp, np.asarray(curve)


def _descend(
    xp: np.ndarray, problem: Problem, light: LightQuadrature, shadowing: bool, masking: bool, lobe: np.ndarray,
    view: np.ndarray, point: tuple | None, settings: OptimiseSettings,
) -> tuple[np.ndarray, np.ndarray]:
    """Adam from ``xp`` (internal order), refitting the shadowed light every ``refit_every`` steps;
    returns the parameters and the loss at the start of each iteration."""
    xp = xp.copy()
    xp[:, 3] = np.maximum(xp[:, 3], settings.min_roughness)
    if not settings.iterations:
        return xp, np.empty(0)
    m1 = np.zeros_like(xp)
    m2 = np.zeros_like(xp)
    curve = np.empty(settings.iterations)
    set_threads(settings.workers)
    lg = _ShadowedLight(xp, problem, light, shadowing, settings)
    for it in range(settings.iterations):
        if it and it % settings.refit_every == 0:
            lg.refit(xp)
        curve[it], grad = _loss_and_gradient(xp, problem, lg.terms, masking, settings.tv_weight, lobe, view, point)
        xp, m1, m2 = adam_step(xp, grad, m1, m2, it + 1, settings.lr, settings.betas, settings.eps)
        xp[:, 3] = np.maximum(xp[:, 3], settings.min_roughness)
    return xp, curve
