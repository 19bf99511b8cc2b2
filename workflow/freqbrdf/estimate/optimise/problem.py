"""The observations of one capture in the layout the estimator works on (`Problem`),
the packed parameters, and the total variation of the parameter textures (paper section 4.3)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from freqbrdf.artefacts import Observations
from freqbrdf.estimate.optimise.kernels import PairData, tv_loss_gradient
from freqbrdf.estimate.optimise.settings import DTYPES, N_PARAMS
from freqbrdf.estimate.shfit import mirror_directions
from freqbrdf.sphere.brdf import TEXTURES, tan2_theta
from freqbrdf.util.validation import check_finite, check_int, check_shape

__all__ = ["Problem", "atlas_neighbours", "build_problem", "pack_params", "unpack_params", "check_params",
           "total_variation"]


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
    tv_edges : numpy.ndarray
        Shape ``(M, 2)``, int64: the neighbour pairs (i, j) in internal order, whose
        ``x_i - x_j`` the TV sums.
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
    tv_edges: np.ndarray
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

    @property
    def pair_data(self) -> PairData:
        """The observed texels' pairs as the kernels read them."""
        return PairData(self.start, self.radiance, self.schlick, self.tan2, self.irradiance_pi)

    def tv(self, xp: np.ndarray) -> tuple[float, np.ndarray]:
        """`total_variation` of internal-order parameters ``xp`` (T, 5) and its gradient."""
        return _tv(xp, self.tv_edges)


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
    if dtype not in DTYPES:
        raise ValueError(f"dtype must be one of {DTYPES}, got {dtype!r}")
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
    edges = position[neighbours]  # internal order, int64
    nb_start, nb = _adjacency(edges, n_tex)
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
        tv_edges=edges,
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
    out = np.empty((n_texels, N_PARAMS))
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
    check_shape(x, "x", (None, N_PARAMS))
    return {"base_color": x[:, :3].copy(), "roughness": x[:, 3].copy(), "metallic": x[:, 4].copy()}


def check_params(x: np.ndarray, problem: Problem) -> np.ndarray:
    """``x`` as packed float64 parameters (T, 5) of ``problem``, checked to be finite."""
    x = np.asarray(x, dtype=np.float64)
    check_shape(x, "x", (problem.n_texels, N_PARAMS))
    check_finite(x, "x")
    return x


def _tv(x: np.ndarray, edges: np.ndarray) -> tuple[float, np.ndarray]:
    """TV and its gradient over the edges (see `total_variation`); 0 without edges."""
    if edges.shape[0] == 0:
        return 0.0, np.zeros_like(x, dtype=np.float64)
    return tv_loss_gradient(x, edges)


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
    return _tv(x, nb)  # `tv_loss_gradient` checks that they index x's rows
