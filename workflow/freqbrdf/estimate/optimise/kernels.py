"""The gradient-descent estimator's compiled kernels, as Python sees them: checked arguments.

Each kernel (`freqbrdf.estimate.optimise.compiled`, the light's in
`freqbrdf.estimate.optimise.compiled_light`, the others in
`freqbrdf.estimate.optimise.compiled_steps`) fuses a computation that NumPy would spread over
several texture-sized temporaries. The tests compare each with an independent
evaluation: `freqbrdf.sphere.sh.real_sh` (degree sums), a direct evaluation of the model and
central differences (loss and gradient), dense quadrature of the environment (shadowing
factors, through `freqbrdf.estimate.light.shadowed_light`). The kernels are compiled on first
use and cached on disk (numba ``cache=True``), so only the first job on a machine pays the
compile; each kernel's first call in a process waits for the others' (`freqbrdf.util.compile_once`),
so jobs that start together on an empty cache compile once, not each.

What travels together is bundled: `PairData` (the observed pairs, from
`freqbrdf.estimate.optimise.problem.Problem.pair_data`), `KernelModel` (which model: masking,
lobe and view tables, point sources) and `LmStep` (the settings of one LM sweep). Threads:
the kernels run on numba's thread pool (`freqbrdf.util.threads.set_threads`); results do
not depend on the number of threads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from freqbrdf.estimate.optimise import compiled, compiled_light, compiled_steps
from freqbrdf.sphere.brdf import ALPHA_MIN, R0_DIELECTRIC
from freqbrdf.util.compile_once import first_call_locked

__all__ = ["PairData", "KernelModel", "LmStep", "lobe_argument", "view_argument", "point_arguments", "degree_sums",
           "shadowing_factors", "basis_factors", "table_sums", "l1_loss_gradient", "grid_search", "lm_sweep", "tv_loss_gradient", "adam_update", "texel_information",
           "source_geometry"]


@dataclass(frozen=True, eq=False)
class PairData:
    """The observed (texel, view) pairs of S texels as every kernel reads them, sorted by texel.

    Attributes
    ----------
    start : numpy.ndarray
        Shape ``(S + 1,)``, int64: first pair of each texel.
    radiance : numpy.ndarray
        Shape ``(N, 3)``: observed B.
    schlick, tan2 : numpy.ndarray
        Shape ``(N,)``: ``(1 - cos theta_o)^5`` and ``tan^2 theta_o``.
    irradiance_pi : numpy.ndarray
        Shape ``(S, 3)``, float64: irradiance over pi.
    """

    start: np.ndarray
    radiance: np.ndarray
    schlick: np.ndarray
    tan2: np.ndarray
    irradiance_pi: np.ndarray


@dataclass(frozen=True, eq=False)
class KernelModel:
    """Which model the kernels evaluate (paper Eq. 11 and this package's extensions).

    Attributes
    ----------
    masking : bool
        Apply ``G1(theta_o)`` (``G1m = 1`` without).
    lobe : numpy.ndarray, optional
        The lobe spectrum ``f_l`` (`freqbrdf.sphere.lobes.lobe_table`); None: the paper's
        ``exp(-(alpha l)^2)``.
    view : numpy.ndarray, optional
        The weights per view, specular and diffuse (`freqbrdf.sphere.lobes.view_table`); None:
        the paper's ``F(theta_o) G1(theta_o)`` and Lambertian diffuse term.
    point : tuple of numpy.ndarray, optional
        Point sources outside the SH light (`freqbrdf.estimate.light.extract_point_sources`):
        ``geometry`` (N, P, 3), per pair and source its half vector's ``sin^2 theta_h``,
        ``c5h`` and ``1 / (4 cos theta_o)`` (`freqbrdf.estimate.optimise.model.pair_source_geometry`),
        and ``src`` (S, P, 4), per texel and source ``tan^2 theta_i`` (0: no shadowing) and the
        power per channel. Each adds the exact GGX microfacet term
        to the specular parts ``R0 a + b``. None: no point sources.
    alpha_min, r0_dielectric : float
        Clamp of alpha (`freqbrdf.sphere.brdf.ALPHA_MIN`) and the dielectric's normal
        reflectance (`freqbrdf.sphere.brdf.R0_DIELECTRIC`).
    """

    masking: bool
    lobe: np.ndarray | None = None
    view: np.ndarray | None = None
    point: tuple[np.ndarray, np.ndarray] | None = None
    alpha_min: float = ALPHA_MIN
    r0_dielectric: float = R0_DIELECTRIC


@dataclass(frozen=True)
class LmStep:
    """Settings of one Levenberg-Marquardt sweep (`lm_sweep`).

    Attributes
    ----------
    data_scale, tv_scale : float
        Weights of the data term's sum (``1 / (3 N)``: a mean) and of each TV edge
        (``tv_weight / M``).
    lower, upper : numpy.ndarray
        Shape ``(5,)``: bounds of each parameter.
    irls_floor, tv_floor : float
        Floors of the reweighting of the data residuals (relative to the texel's mean
        observed radiance) and of the TV differences.
    tries : int
        Attempts per texel.
    """

    data_scale: float
    tv_scale: float
    lower: np.ndarray
    upper: np.ndarray
    irls_floor: float
    tv_floor: float
    tries: int


def degree_sums(
    lg: np.ndarray, rows: np.ndarray, pairs: np.ndarray, mirror: np.ndarray, a: np.ndarray, b: np.ndarray,
    out: np.ndarray,
) -> None:
    """``out[pairs[i], l, c] = sum_m lg[rows[i], lm, c] Y_lm(mirror[pairs[i]])`` for every degree l.

    The per-degree light terms of the estimator (paper Eq. 11: the SH light
    at each observation's mirror direction, split by degree so that a lobe
    filter can weight them), with ``Y`` evaluated on the fly instead of
    stored (at 256^2 texels x 24 views and l* = 20 a stored table is 0.8 GB).

    Parameters
    ----------
    lg : numpy.ndarray
        Shape ``(S, (lmax+1)**2, 3)``, float32 or float64, any strides: SH
        expansions (`freqbrdf.estimate.light.shadowed_light`).
    rows : numpy.ndarray
        Shape ``(P,)``, int64: expansion of each evaluated pair.
    pairs : numpy.ndarray
        Shape ``(P,)``, int64: rows of ``out`` and ``mirror`` to evaluate.
    mirror : numpy.ndarray
        Shape ``(N, 3)``, float64: directions (normalised here).
    a, b : numpy.ndarray
        Shape ``(lmax+1, lmax+1)``: `freqbrdf.sphere.sh.recurrence_tables` of lmax.
    out : numpy.ndarray
        Shape ``(N, lmax+1, 3)``, written in place at ``pairs``.
    """
    if out.shape[2] != 3 or lg.shape[2] != 3:
        raise ValueError(f"degree_sums needs RGB expansions, got lg {lg.shape} and out {out.shape}")
    first_call_locked(compiled_light.degree_sums_kernel, lg, rows, pairs, mirror, a, b, out)


def shadowing_factors(normals: np.ndarray, directions: np.ndarray, alpha: np.ndarray, out: np.ndarray) -> None:
    """Smith ``G1(n . w, alpha)`` of every texel normal and direction, 0 below the horizon.

    ``G1 = 2 / (1 + sqrt(1 + alpha^2 tan^2 theta))`` with ``cos theta = n . w``
    (paper section 4.2, the shadowing of the incoming light); ``alpha = 0``
    gives the bare horizon (1 above, 0 below). Float32, as the products it feeds.

    Parameters
    ----------
    normals : numpy.ndarray
        Shape ``(T, 3)``, float32, unit.
    directions : numpy.ndarray
        Shape ``(3, Q)``, float32, unit (one direction per column).
    alpha : numpy.ndarray
        Shape ``(T,)``, float64: GGX width per texel.
    out : numpy.ndarray
        Shape ``(T, Q)``, float32, written in place.
    """
    first_call_locked(compiled_light.shadowing_kernel, normals, directions, alpha, out)


def basis_factors(normals: np.ndarray, directions: np.ndarray, u: np.ndarray, out: np.ndarray) -> None:
    """The shadowing basis functions ``u_k(n . w)`` of every normal and direction, 0 below the horizon.

    The separable form of `shadowing_factors` (`freqbrdf.estimate.light_table.ShadowingBasis`):
    ``u_k`` is tabulated at ``P`` even steps of ``cos theta`` in [0, 1] and interpolated linearly.

    Parameters
    ----------
    normals, directions : numpy.ndarray
        As `shadowing_factors`.
    u : numpy.ndarray
        Shape ``(R, P)``, float32: the basis functions' samples.
    out : numpy.ndarray
        Shape ``(T R, Q)``, float32, written in place: row ``t R + k`` is ``u_k`` of normal t.
    """
    first_call_locked(compiled_light.basis_factors_kernel, normals, directions, u, out)


def table_sums(
    coefficients: np.ndarray, corner: np.ndarray, corner_weight: np.ndarray, v: np.ndarray, slots: np.ndarray,
    start: np.ndarray, mirror: np.ndarray, a: np.ndarray, b: np.ndarray, out: np.ndarray,
) -> None:
    """`degree_sums` of the pairs of texels ``slots`` whose light comes from a table.

    The light of texel i is ``sum_j corner_weight[i, j] sum_k v[i, k] coefficients[corner[i, j], k]``
    (`freqbrdf.estimate.light_table.ShadowedLightTable`: interpolated between the grid normals
    around the texel's normal, combined over the shadowing basis at its roughness), assembled
    once per texel in a buffer and evaluated at its pairs' mirror directions.

    Parameters
    ----------
    coefficients : numpy.ndarray
        Shape ``(G, R, 3 (lmax+1)^2)``, float32: SH coefficients per grid normal and basis
        function, coefficient-major (``3 lm + c``; RGB only).
    corner, corner_weight : numpy.ndarray
        Shape ``(S, J)``, int64 and float64: the grid normals around each texel and their weights.
    v : numpy.ndarray
        Shape ``(S, R)``, float64: each basis function's weight at the texel's roughness.
    slots : numpy.ndarray
        Shape ``(S,)``, int64: the texels, as positions into ``start``.
    start : numpy.ndarray
        Shape ``(T_obs + 1,)``, int64: first pair of each texel (pairs sorted by texel).
    mirror, a, b, out : numpy.ndarray
        As `degree_sums` with ``C = 3``; ``out`` is written at the pairs of ``slots``.
    """
    if out.shape[2] != 3 or coefficients.shape[2] != 3 * out.shape[1] ** 2:
        raise ValueError(f"table_sums needs RGB coefficients of degree {out.shape[1] - 1}, got rows of "
                         f"{coefficients.shape[2]} for output of shape {out.shape}")
    first_call_locked(compiled_light.table_sums_kernel, coefficients, corner, corner_weight, v, slots, start, mirror, a, b, out)


def lobe_argument(lobe: np.ndarray | None, n_degrees: int) -> np.ndarray:
    """``lobe`` (`freqbrdf.sphere.lobes.lobe_table`) as the kernels take it, checked against the light terms'
    ``n_degrees``; None: the Gaussian (an empty table)."""
    if lobe is None:
        return np.empty((0, 2, n_degrees))
    lobe = np.ascontiguousarray(lobe, np.float64)
    if lobe.ndim != 3 or lobe.shape[1] != 2 or lobe.shape[2] < n_degrees or lobe.shape[0] == 1:
        raise ValueError(f"lobe must be a lobe_table of degree >= {n_degrees - 1}, got shape {lobe.shape}")
    return lobe


def view_argument(view: np.ndarray | None) -> np.ndarray:
    """``view`` (`freqbrdf.sphere.lobes.view_table`) as the kernels take it: checked, read-only; None: the paper's
    ``F(theta_o) G1(theta_o)``.

    Read-only whatever it was: numba compiles a kernel once per type, and a read-only array is
    another type than a writable one (`view_table`'s are read-only, cached; an empty one was not,
    which cost every model kernel a second compile).
    """
    view = np.empty((0, 2, 3, 0)) if view is None else np.ascontiguousarray(view, np.float64)
    if view.ndim != 4 or view.shape[1] != 2 or view.shape[2] not in (1, 3) or (view.size and min(view.shape[0], view.shape[3]) < 2):
        raise ValueError(f"view must be a view_table, got shape {view.shape}")
    view = view.view()  # a view's flag can be cleared without touching the caller's array
    view.flags.writeable = False
    return view


def point_arguments(point: tuple[np.ndarray, np.ndarray] | None, start: np.ndarray, dtype: np.dtype
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``point`` (``geometry`` (N, P, 3), ``src`` (S, P, 4)) checked against the pairs and texels of
    ``start``; None: no point sources (an empty geometry of ``dtype``, the pairs', so that the
    kernels compile once per dtype)."""
    if point is None:
        return np.zeros((0, 0, 3), dtype), np.zeros((start.shape[0] - 1, 0, 4))
    geometry, src = np.ascontiguousarray(point[0]), np.ascontiguousarray(point[1], np.float64)
    if (geometry.shape != (start[-1], src.shape[1] if src.ndim == 3 else -1, 3)
            or geometry.dtype not in (np.float32, np.float64) or src.ndim != 3
            or src.shape[0] != start.shape[0] - 1 or src.shape[2] != 4):
        raise ValueError(f"point must be (geometry (N, P, 3), src (S, P, 4)) for {start.shape[0] - 1} texels and "
                         f"{start[-1]} pairs, got {geometry.dtype} shape {geometry.shape} and shape {src.shape}")
    return geometry, src


def _arguments(terms: np.ndarray, pairs: PairData, model: KernelModel, texels: np.ndarray | None = None) -> tuple:
    """The arguments every model kernel takes, in the kernels' order, checked: the last, the blocks
    of its parallel loop over ``texels`` (default: every observed texel), of equal work each."""
    if texels is None:
        texels = np.arange(pairs.start.shape[0] - 1)
    return (pairs.start, terms, pairs.radiance, pairs.schlick, pairs.tan2, pairs.irradiance_pi, model.masking,
            model.alpha_min, model.r0_dielectric, lobe_argument(model.lobe, terms.shape[1]), view_argument(model.view),
            *point_arguments(model.point, pairs.start, pairs.radiance.dtype),
            compiled_steps.block_bounds(pairs.start, texels))


def l1_loss_gradient(
    x: np.ndarray, terms: np.ndarray, pairs: PairData, model: KernelModel, out: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-texel L1 data term of the mixed model and its gradient (paper Eqs. 11 and 13).

    For the pairs ``n`` of texel ``s`` (``start[s] <= n < start[s+1]``):
    ``B = (1 - m) base E / pi + F G1m sum_l f_l(alpha) terms[n, l]``,
    ``F = R0 (1 - c5) + c5``, ``R0 = r0_dielectric (1 - m) + m base``; with a
    ``view`` table ``F G1m`` becomes ``R0 a + b`` and ``E / pi`` becomes ``d E / pi``, ``a``, ``b``
    and ``d`` read at (alpha, cos theta_o),
    ``alpha = max(r^2, alpha_min)`` (derivative ``2 max(r, sqrt(alpha_min))``,
    as `freqbrdf.sphere.brdf.alpha_from_roughness`).

    Parameters
    ----------
    x : numpy.ndarray
        Shape ``(S, 5)``, float64: base colour RGB, roughness, metallic per texel.
    terms : numpy.ndarray
        Shape ``(N, L, 3)``: per-degree light terms of each pair
        (`freqbrdf.estimate.optimise.model.light_terms`).
    pairs : PairData
        The observations of the S texels.
    model : KernelModel
        Which model.
    out : numpy.ndarray, optional
        Shape ``(N, 3)``, float64: filled with the model radiance.

    Returns
    -------
    loss : numpy.ndarray
        Shape ``(S,)``: ``sum_{n, c} |B - B_obs|`` per texel.
    grad : numpy.ndarray
        Shape ``(S, 5)``: its gradient (sign(0) = 0).
    """
    grad = np.empty((x.shape[0], 5))
    loss = np.empty(x.shape[0])
    first_call_locked(compiled.l1_kernel, x, *_arguments(terms, pairs, model), grad, loss, np.empty((0, 3)) if out is None else out)
    return loss, grad


def texel_information(
    x: np.ndarray, terms: np.ndarray, pairs: PairData, model: KernelModel,
) -> tuple[np.ndarray, np.ndarray]:
    """Per texel, the Gauss-Newton curvature ``J^T J`` of its model radiance and its squared residual.

    ``J`` is the exact derivative of the model of `l1_loss_gradient` over the texel's pairs and
    channels, in base colour RGB, roughness and metallic (the same rows as the LM sweeps'), so one
    pass over the pairs gives what a finite-difference Jacobian needs six passes and an
    ``(N, 3, 5)`` array for.

    Parameters
    ----------
    x : numpy.ndarray
        Shape ``(S, 5)``, float64: parameters of the S observed texels.
    terms, pairs, model
        As for `l1_loss_gradient`.

    Returns
    -------
    curvature : numpy.ndarray
        Shape ``(S, 5, 5)``, float64, symmetric: ``sum_{n, c} J_nc^T J_nc`` per texel.
    squares : numpy.ndarray
        Shape ``(S,)``, float64: ``sum_{n, c} (B - B_obs)^2`` per texel.
    """
    info = np.empty((x.shape[0], 5, 5))
    squares = np.empty(x.shape[0])
    first_call_locked(compiled.information_kernel, np.ascontiguousarray(x, dtype=np.float64), *_arguments(terms, pairs, model), info,
                                squares)
    return info, squares


def grid_search(
    terms: np.ndarray, pairs: PairData, model: KernelModel, roughness: np.ndarray, metallic: np.ndarray,
) -> np.ndarray:
    """Per texel, the (roughness, metallic) grid point of least L1 data term, with its best base colour.

    The model of `l1_loss_gradient` is linear in the base colour once
    roughness and metallic are fixed, so each grid point's base colour is
    the least-squares one per channel, clipped to [0, 1]; grid points are
    ranked by their L1 cost (ties: the first, roughness outer).

    Parameters
    ----------
    terms, pairs, model
        As for `l1_loss_gradient`.
    roughness, metallic : numpy.ndarray
        1-D grids, float64.

    Returns
    -------
    numpy.ndarray
        Shape ``(S, 5)``, float64: base colour RGB, roughness, metallic.
    """
    out = np.zeros((pairs.start.shape[0] - 1, 5))
    first_call_locked(compiled.grid_kernel, *_arguments(terms, pairs, model), np.asarray(roughness, dtype=np.float64),
                         np.asarray(metallic, dtype=np.float64), int(np.diff(pairs.start).max(initial=0)), out)
    return out


def lm_sweep(
    x: np.ndarray, texels: np.ndarray, terms: np.ndarray, pairs: PairData, model: KernelModel,
    neighbours: tuple[np.ndarray, np.ndarray], step: LmStep, lam: np.ndarray,
) -> np.ndarray:
    """One damped Gauss-Newton (Levenberg-Marquardt) step per texel of ``texels`` on the L1 + TV objective.

    Texel s minimises its own part of the objective with its TV neighbours
    held fixed: ``step.data_scale sum_{n, c} |B - B_obs| + step.tv_scale sum_{j, q} |x_sq - x_jq|``
    (model of `l1_loss_gradient`). Both absolute values are replaced by
    quadratics at the current point (iteratively reweighted least squares,
    weight ``1 / max(|r|, floor)``: the floor is ``step.irls_floor`` times the
    texel's mean observed radiance for the data, ``step.tv_floor`` for TV), whose damped
    Gauss-Newton system ``(H + lam diag(H)) step = -grad`` is solved with
    the parameters that sit on a bound and are pushed outwards held there.
    The step, clipped to ``[step.lower, step.upper]``, is kept only if it lowers the
    texel's true objective; ``lam`` is then divided by 3, else multiplied
    by 4 and the step solved again (up to ``step.tries`` times; ``lam`` stays in
    [1e-6, 1e6]). A texel whose quadratic predicts no decrease (converged,
    or held by its bounds) is left as it is, its ``lam`` unchanged. When no
    two of ``texels`` are neighbours (one colour of the atlas's
    checkerboard) the updates are exact block coordinate descent: the total
    objective never rises, and the result does not depend on the number of
    threads.

    Parameters
    ----------
    x : numpy.ndarray
        Shape ``(S, 5)``, float64: parameters, updated in place at ``texels``.
    texels : numpy.ndarray
        Shape ``(U,)``, int64: rows of ``x`` to update.
    terms, pairs, model
        As for `l1_loss_gradient`; ``pairs`` covers the first ``len(pairs.start) - 1``
        rows of ``x`` (the observed texels), the others have no data term.
    neighbours : tuple of numpy.ndarray
        ``nb_start`` (S + 1,) and ``nb`` (2 M,), int64: the TV neighbours of row s
        are ``nb[nb_start[s]:nb_start[s + 1]]``.
    step : LmStep
        Weights, bounds, floors and tries.
    lam : numpy.ndarray
        Shape ``(S,)``: damping per texel, updated in place.

    Returns
    -------
    numpy.ndarray
        Shape ``(U,)``: each texel's objective before its step.
    """
    nb_start, nb = neighbours
    cost = np.empty(texels.shape[0])
    first_call_locked(compiled.lm_kernel, x, texels, *_arguments(terms, pairs, model, texels), nb_start, nb, float(step.data_scale),
                       float(step.tv_scale), step.lower, step.upper, float(step.irls_floor), float(step.tv_floor), lam,
                       int(step.tries), cost)
    return cost


def tv_loss_gradient(x: np.ndarray, edges: np.ndarray) -> tuple[float, np.ndarray]:
    """Mean absolute difference over the edges, summed over channels, and its gradient.

    Parameters
    ----------
    x : numpy.ndarray
        Shape ``(T, Q)``, float64: parameter channels per texel.
    edges : numpy.ndarray
        Shape ``(M, 2)``, int64, ``M >= 1``: the texel pairs (i, j), each within ``[0, T)``.

    Returns
    -------
    tv : float
        ``(1/M) sum_edges sum_q |x_iq - x_jq|``.
    grad : numpy.ndarray
        Shape ``(T, Q)``: its (sub)gradient, ``sign(0) = 0``.
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    edges = np.ascontiguousarray(edges, dtype=np.int64)
    if x.ndim != 2 or edges.ndim != 2 or edges.shape[1] != 2 or not edges.shape[0]:
        raise ValueError(f"x must be (T, Q) and edges (M >= 1, 2), got shapes {x.shape} and {edges.shape}")
    if edges.min() < 0 or edges.max() >= x.shape[0]:
        raise ValueError(f"edges must index the {x.shape[0]} rows of x, got {edges.min()}..{edges.max()}")
    grad = np.empty_like(x)
    return float(first_call_locked(compiled_steps.tv_kernel, x, edges, grad)), grad


def adam_update(
    x: np.ndarray, grad: np.ndarray, m1: np.ndarray, m2: np.ndarray, step: int, lr: float,
    betas: tuple[float, float], eps: float, floor: np.ndarray,
) -> None:
    """`freqbrdf.estimate.optimise.solve.adam_step` in place, then ``x = max(x, floor)`` per column.

    The same numbers as the NumPy update, bit for bit, in one pass over the arrays.

    Parameters
    ----------
    x, grad, m1, m2 : numpy.ndarray
        Shape ``(T, Q)``, float64, C-contiguous: parameters, gradient and the two moment
        estimates; ``x``, ``m1`` and ``m2`` are updated in place.
    step : int
        1-based step number (bias correction).
    lr, eps : float
        Learning rate and denominator offset.
    betas : tuple of float
        Moment decay rates.
    floor : numpy.ndarray
        Shape ``(Q,)``, float64: lower bound of each column after the clamp to [0, 1].
    """
    arrays = {"x": x, "grad": grad, "m1": m1, "m2": m2}
    for name, a in arrays.items():
        if a.shape != x.shape or a.dtype != np.float64 or not a.flags.c_contiguous:
            raise ValueError(f"adam_update: {name} must be C-contiguous float64 of shape {x.shape}, "
                             f"got {a.dtype} {a.shape}")
    floor = np.ascontiguousarray(floor, dtype=np.float64)
    if floor.shape != x.shape[1:]:
        raise ValueError(f"adam_update: floor must have shape {x.shape[1:]}, got {floor.shape}")
    b1, b2 = betas
    first_call_locked(compiled_steps.adam_kernel, x, grad, m1, m2, float(lr), 1.0 - b1**step, 1.0 - b2**step, float(b1), float(b2),
                         float(eps), floor)


def source_geometry(wo: np.ndarray, incoming: np.ndarray, slot: np.ndarray, out: np.ndarray) -> None:
    """`freqbrdf.estimate.optimise.model.pair_source_geometry` into ``out`` (N, S, 3), float32 or
    float64: the half vector's ``sin^2 theta_h``, Schlick's ``(1 - h.wo)^5`` and ``1 / (4 cos theta_o)``
    (0 where the source or the view is below the horizon) of every pair and source, in one pass
    instead of NumPy's temporaries per source; ``wo`` (N, 3), ``incoming`` (T, S, 3)
    float64 and ``slot`` (N,) int64, C-contiguous, checked by the caller."""
    first_call_locked(compiled_steps.source_geometry_kernel, wo, incoming, slot, out)
