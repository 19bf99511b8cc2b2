"""The observed pairs laid out with texels side by side in SIMD lanes, and the objective and grid start on them.

`pair_lanes` groups ``width`` consecutive observed texels (the problem sorts them by pair count,
so a group's texels hold about as many pairs) and stores the k-th pair of each side by side:
arrays ``(slots, ..., width)``, one slot per pair of the group's busiest texel, padding marked by
``valid = 0``. `lane_terms` lays the light terms out the same way after each refit, and
`l1_loss_gradient_lanes` evaluates `freqbrdf.estimate.optimise.kernels.l1_loss_gradient` on them
(`freqbrdf.estimate.optimise.compiled_lanes.l1_lanes_kernel`), `grid_search_lanes` the grid start's
`freqbrdf.estimate.optimise.kernels.grid_search`: the same model, vectorised across texels instead
of scalar per pair (docs/estimator.md, Cost). The other kernels (light terms, LM, posterior) keep the
pair-major layout; the solver holds both.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from freqbrdf.estimate.optimise import compiled_lanes
from freqbrdf.estimate.optimise.kernels import KernelModel, PairData, lobe_argument, point_arguments, view_argument
from freqbrdf.util.compile_once import first_call_locked
from freqbrdf.util.validation import check_int

__all__ = ["LANE_WIDTH", "PairLanes", "view_factors", "supports", "pair_lanes", "lane_terms", "l1_loss_gradient_lanes",
           "grid_search_lanes"]

LANE_WIDTH = 32  # texels per group: 8 iterations of a 4-double vector per loop (docs/estimator.md, Cost)
_GROUPS_PER_BLOCK = 2  # groups per parallel iteration on average (one set of scratch arrays each)
_MAX_VIEW_RANK = 4  # a diffuse factor of higher rank (none of the tables') is not laid out


@dataclass(frozen=True, eq=False)
class PairLanes:
    """The observed pairs of S texels in groups of ``width`` texels, pair slots side by side, for one model.

    Attributes
    ----------
    pairs : PairData
        The observations laid out.
    model : KernelModel
        The model they are laid out for (its point sources' geometry and diffuse factor are).
    width : int
        Texels per group, W.
    order : numpy.ndarray
        Shape ``(S,)``, int64: the texels by pair count, most first; group ``g`` holds
        ``order[g W:g W + W]``, so that a group's texels hold about as many pairs.
    slot_start : numpy.ndarray
        Shape ``(G + 1,)``, int64: first slot of each group.
    pair : numpy.ndarray
        Shape ``(K, W)``, int64: the pair in each slot and lane, -1 for padding.
    bounds : numpy.ndarray
        Shape ``(B + 1,)``, int64: blocks of groups of about equal slot counts, the kernel's parallel loop.
    radiance : numpy.ndarray
        Shape ``(K, 3, W)``: observed B (0 for padding).
    schlick, tan2, valid : numpy.ndarray
        Shape ``(K, W)``: ``(1 - cos theta_o)^5``, ``tan^2 theta_o`` and 1 for a pair, 0 for padding.
    view_alpha, view_mu : numpy.ndarray
        The model's diffuse factor as `view_factors`: its alpha factors ``(A, 2, R)``, float64,
        and its cos theta_o factors at each pair ``(K, R, W)``; ``(0, 2, 1)`` and ones without a table.
    geometry : numpy.ndarray
        Shape ``(K, P, 3, W)``: the point sources' pair geometry
        (`freqbrdf.estimate.optimise.model.pair_source_geometry`; P = 0 without sources).
    lobe, src : numpy.ndarray
        ``model``'s lobe table and point sources per texel as the kernels take them
        (`freqbrdf.estimate.optimise.kernels.lobe_argument`, `point_arguments`).
    """

    pairs: PairData
    model: KernelModel
    width: int
    order: np.ndarray
    slot_start: np.ndarray
    pair: np.ndarray
    bounds: np.ndarray
    radiance: np.ndarray
    schlick: np.ndarray
    tan2: np.ndarray
    valid: np.ndarray
    view_alpha: np.ndarray
    view_mu: np.ndarray
    geometry: np.ndarray
    lobe: np.ndarray
    src: np.ndarray


def view_factors(view: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The diffuse factor ``d`` of a `freqbrdf.sphere.lobes.view_table` as a sum of ``R`` products of
    a function of alpha and one of cos theta_o, exactly, if it is one; None otherwise.

    The principled diffuse term's factor is exactly of rank 3 (Lambert's is no table: ``d = 1``), so its
    cubic Hermite interpolant in ``log alpha`` times linear interpolation in cos theta_o is the
    sum of the factors' interpolants: a pair's cos theta_o factors are fixed for the job and a
    texel's alpha factors for an evaluation, and ``d`` costs ``R`` multiply-adds a pair instead of
    a gather from the table. The factors are the table's right singular vectors (cos theta_o) and
    its value and slope rows projected on them (alpha); the rank is kept if they give the table
    back to 1e-12 of its largest value.

    Parameters
    ----------
    view : numpy.ndarray
        Shape ``(A, 2, K, M)``: a view table; its last component is the diffuse factor.

    Returns
    -------
    alpha : numpy.ndarray
        Shape ``(A, 2, R)``: per alpha node the factors' values and slopes in log alpha.
    mu : numpy.ndarray
        Shape ``(R, M)``: per cos theta_o node the factors.
    """
    table = np.asarray(view, np.float64)[:, :, -1, :]
    _, singular, vt = np.linalg.svd(table[:, 0], full_matrices=False)
    for rank in range(1, _MAX_VIEW_RANK + 1):
        mu = vt[:rank]
        alpha = np.einsum("ahm,rm->ahr", table, mu)
        if np.abs(np.einsum("ahr,rm->ahm", alpha, mu) - table).max() <= 1e-12 * np.abs(table).max():
            return alpha, mu
    return None


def _diffuse_factors(model: KernelModel) -> tuple[np.ndarray, np.ndarray] | None:
    """``model``'s diffuse factor as `view_factors` (the paper's Lambertian term: an empty alpha table and
    a constant 1); None where the lanes do not evaluate it (the albedo weights, or no low rank)."""
    view = view_argument(model.view)
    if view.shape[0] == 0:
        return np.zeros((0, 2, 1)), np.ones((1, 2))
    return view_factors(view) if view.shape[2] == 1 else None


def supports(model: KernelModel) -> bool:
    """Whether `l1_loss_gradient_lanes` evaluates ``model``: the paper's specular weights and a
    diffuse factor of low rank (`view_factors`), not the albedo weights."""
    return _diffuse_factors(model) is not None


def pair_lanes(pairs: PairData, model: KernelModel, width: int = LANE_WIDTH) -> PairLanes:
    """`PairLanes` of ``pairs`` for ``model`` in groups of ``width`` texels.

    Parameters
    ----------
    pairs : PairData
        The observations (`freqbrdf.estimate.optimise.problem.Problem.pair_data`).
    model : KernelModel
        The model: the paper's specular weights (`supports`).
    width : int
        Texels per group, >= 1.
    """
    width = check_int(width, "width", 1)
    factors = _diffuse_factors(model)
    if factors is None:
        raise ValueError("model: the lanes take the paper's specular weights and a diffuse factor of low rank, "
                         "not view_weight albedo")
    counts = np.diff(pairs.start)
    n_obs = counts.shape[0]
    order = np.argsort(-counts, kind="stable").astype(np.int64)
    n_groups = -(-n_obs // width)
    padded = np.zeros(n_groups * width, np.int64)
    padded[:n_obs] = counts[order]
    slots = padded.reshape(n_groups, width).max(axis=1)
    slot_start = np.concatenate([[0], np.cumsum(slots)]).astype(np.int64)
    group = np.repeat(np.arange(n_groups), slots)
    k = (np.arange(slot_start[-1]) - slot_start[group])[:, None]  # rank of each slot in its group
    lane = group[:, None] * width + np.arange(width)[None, :]  # position in ``order``
    texel = order[np.minimum(lane, max(n_obs - 1, 0))] if n_obs else lane
    pair = np.where((lane < n_obs) & (k < padded[lane]), pairs.start[texel] + k, -1).astype(np.int64)
    geometry, src = point_arguments(model.point, pairs.start, pairs.radiance.dtype)
    if geometry.shape[0] == 0:  # no sources: (K, 0, 3, W)
        geometry = np.zeros((pairs.start[-1], 0, 3), geometry.dtype)
    # blocks of about equal work: a group's slots times its width, plus its texels' own (4 pairs' worth)
    work = np.cumsum(slots * width + 4 * width)
    n_blocks = max(-(-n_groups // _GROUPS_PER_BLOCK), 1)
    cuts = np.searchsorted(work, work[-1] * np.arange(1, n_blocks) / n_blocks) if n_groups else np.zeros(0, np.int64)
    bounds = np.unique(np.concatenate([[0], cuts, [n_groups]])).astype(np.int64)
    n_slots, dtype = pair.shape[0], pairs.radiance.dtype
    out = (np.empty((n_slots, 3, width), dtype), np.empty((n_slots, width), dtype), np.empty((n_slots, width), dtype),
           np.empty((n_slots, width), dtype), np.empty((n_slots, geometry.shape[1], 3, width), geometry.dtype),
           np.empty((n_slots, factors[1].shape[0], width), dtype))
    first_call_locked(compiled_lanes.layout_kernel, pair, pairs.radiance, pairs.schlick, pairs.tan2, geometry,
                      np.ascontiguousarray(factors[1]), *out)
    radiance, schlick, tan2, valid, lane_geometry, view_mu = out
    return PairLanes(pairs=pairs, model=model, width=width, order=order, slot_start=slot_start, pair=pair,
                     bounds=bounds, radiance=radiance, schlick=schlick, tan2=tan2, valid=valid, view_alpha=factors[0],
                     view_mu=view_mu, geometry=lane_geometry, lobe=lobe_argument(model.lobe, 0), src=src)


def lane_terms(terms: np.ndarray, lanes: PairLanes, out: np.ndarray | None = None) -> np.ndarray:
    """The light terms (N, L, 3) laid out as ``lanes``: (K, L, 3, W), 0 in padding; into ``out`` if given."""
    if terms.ndim != 3 or terms.shape[2] != 3 or terms.shape[0] < lanes.pair.max(initial=-1) + 1:
        raise ValueError(f"terms must be (N, L, 3) for the lanes' pairs, got shape {terms.shape}")
    shape = (lanes.pair.shape[0], terms.shape[1], 3, lanes.width)
    if out is None:
        out = np.empty(shape, terms.dtype)
    elif out.shape != shape or out.dtype != terms.dtype:
        raise ValueError(f"out must be {terms.dtype} of shape {shape}, got {out.dtype} {out.shape}")
    first_call_locked(compiled_lanes.gather_terms_kernel, np.ascontiguousarray(terms), lanes.pair, out)
    return out


def l1_loss_gradient_lanes(x: np.ndarray, terms: np.ndarray, lanes: PairLanes) -> tuple[np.ndarray, np.ndarray]:
    """`freqbrdf.estimate.optimise.kernels.l1_loss_gradient` of ``lanes.model`` from the lanes' layout.

    Parameters
    ----------
    x : numpy.ndarray
        Shape ``(S, 5)``, float64: base colour RGB, roughness, metallic per observed texel.
    terms : numpy.ndarray
        Shape ``(K, L, 3, W)``: `lane_terms`.
    lanes : PairLanes
        The observations and the model.

    Returns
    -------
    loss : numpy.ndarray
        Shape ``(S,)``: ``sum_{n, c} |B - B_obs|`` per texel.
    grad : numpy.ndarray
        Shape ``(S, 5)``: its gradient (sign(0) = 0).
    """
    n_obs = lanes.order.shape[0]
    if x.shape != (n_obs, 5):
        raise ValueError(f"x must be ({n_obs}, 5) for the lanes' texels, got shape {x.shape}")
    grad = np.empty((n_obs, 5))
    loss = np.empty(n_obs)
    model = lanes.model
    first_call_locked(compiled_lanes.l1_lanes_kernel, np.ascontiguousarray(x, np.float64), lanes.order,
                      lanes.slot_start, lanes.bounds, _flat(terms, lanes), lanes.radiance, lanes.schlick, lanes.tan2,
                      lanes.valid, lanes.view_mu, lanes.pairs.irradiance_pi, model.masking, model.alpha_min,
                      model.r0_dielectric, lanes.lobe, lanes.view_alpha, lanes.geometry, lanes.src, grad, loss)
    return loss, grad


def _flat(terms: np.ndarray, lanes: PairLanes) -> np.ndarray:
    """`lane_terms` (K, L, 3, W) checked, channels and lanes as one axis: (K, L, 3 W)."""
    if terms.ndim != 4 or terms.shape[0] != lanes.pair.shape[0] or terms.shape[2:] != (3, lanes.width):
        raise ValueError(f"terms must be lane_terms of these lanes, got shape {terms.shape}")
    if lanes.lobe.shape[0] and lanes.lobe.shape[2] < terms.shape[1]:
        raise ValueError(f"terms of degree {terms.shape[1] - 1} need a lobe_table of that degree, "
                         f"got one of degree {lanes.lobe.shape[2] - 1}")
    return terms.reshape(terms.shape[0], terms.shape[1], 3 * lanes.width)


def grid_search_lanes(terms: np.ndarray, lanes: PairLanes, roughness: np.ndarray, metallic: np.ndarray) -> np.ndarray:
    """`freqbrdf.estimate.optimise.kernels.grid_search` of ``lanes.model`` from the lanes' layout.

    Parameters
    ----------
    terms : numpy.ndarray
        Shape ``(K, L, 3, W)``: `lane_terms`.
    lanes : PairLanes
        The observations and the model.
    roughness, metallic : numpy.ndarray
        1-D grids.

    Returns
    -------
    numpy.ndarray
        Shape ``(S, 5)``, float64: per observed texel its best base colour RGB, roughness and metallic.
    """
    out = np.zeros((lanes.order.shape[0], 5))
    model = lanes.model
    first_call_locked(compiled_lanes.grid_lanes_kernel, lanes.order, lanes.slot_start, lanes.bounds,
                      _flat(terms, lanes), lanes.radiance, lanes.schlick, lanes.tan2, lanes.view_mu,
                      lanes.pairs.irradiance_pi, model.masking, model.alpha_min, model.r0_dielectric, lanes.lobe,
                      lanes.view_alpha, lanes.geometry, lanes.src, np.asarray(roughness, dtype=np.float64),
                      np.asarray(metallic, dtype=np.float64), int(np.diff(lanes.slot_start).max(initial=0)), out)
    return out
