"""The known environment light as the frequency-domain model sees it.

Two quantities of the mixed pipeline (Wiersma et al. 2024, section 4.2 and
Fig. 2) come from the environment map alone, not from the sparse views:

- the shadowed incoming light ``Lg = G1(theta_i, alpha) L`` of every texel,
  whose SH coefficients the specular lobe filters (Eq. 11). The paper fits it
  "on Fibonacci samples" of the map; here the samples are a Gauss-Legendre x
  uniform-azimuth product grid (`LightQuadrature`), which integrates the
  band-limited light times a spherical harmonic exactly, and the shadowing
  factor is applied per texel normal and roughness (`shadowed_light`);
- the irradiance ``E(n)`` of the diffuse term (Eq. 14), by quadrature of the
  map on a grid of normals (`irradiance`), accurate for point-like lamps and
  a sun, unlike the nine-coefficient (degree 2) approximation.

Beyond the paper, the map's compact bright sources (a sun, small lamps:
`extract_point_sources`) can be taken out of the map and kept as point
sources (`PointSources`), which the estimator evaluates with the exact
microfacet BRDF rather than through the SH of degree l*: a source much
narrower than the SH's resolution (about 180 / (l* + 1) degrees) is blurred
and rings at that degree, which biases the smooth texels it lights most.

Light from below a texel's horizon does not reach it: ``Lg`` is 0 where
``n . w <= 0``, with or without the shadowing term. With it, ``Lg`` falls
continuously to 0 at the horizon (``G1(90 deg) = 0`` for ``alpha > 0``).

All directions and coefficients are in the world frame (+Y up, see
:mod:`freqbrdf.sphere.sh`); arrays are float64 unless stated.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from freqbrdf.estimate.optimise.kernels import shadowing_factors
from freqbrdf.util.threads import set_threads
from freqbrdf.capture.observations import sample_equirect
from freqbrdf.sphere.sh import angles_to_directions, eval_rings, project_equirect, real_sh, ring_factors, sh_degrees
from freqbrdf.sphere.sampling import equirect_directions, equirect_solid_angles

__all__ = [
    "LightQuadrature",
    "PointSources",
    "dilate",
    "extract_point_sources",
    "label_components",
    "light_quadrature",
    "shadowed_light",
    "project_factors",
    "irradiance",
    "downsample_equirect",
]

_TEXEL_CHUNK = 1024  # texels per block (the texels x nodes shadowing matrix: 15 MB)


@dataclass(frozen=True)
class LightQuadrature:
    """Nodes of a product quadrature of the sphere carrying a band-limited light.

    The nodes are ring-major: ``n_rings`` Gauss-Legendre rings in
    ``cos theta`` times ``2 n_rings`` uniform azimuths. On such a grid
    ``Y_lm(w_jk) = Theta_lm(theta_j) Phi_m(phi_k)`` (``Phi_m = cos(m phi)``,
    1 or ``sin(|m| phi)``), so an integral against every ``Y_lm`` factorises
    into a sum over azimuths per ring and then a sum over rings (the tables
    ``azimuthal`` and ``polar``, with ``M = 2 lmax + 1`` orders indexed
    ``m + lmax``).

    Attributes
    ----------
    lmax : int
        SH degree of the shadowed light fitted from the nodes (the model's l*).
    directions : numpy.ndarray
        Shape ``(Q, 3)``, unit node directions (world frame), ``Q = 2 n_rings^2``.
    weighted_radiance : numpy.ndarray
        Shape ``(Q, C)``: light radiance at each node times its weight (sr).
    basis : numpy.ndarray
        Shape ``(Q, (lmax+1)**2)``, float32: ``Y_lm`` at the nodes.
    n_rings : int
        Rings of the grid.
    azimuthal : numpy.ndarray
        Shape ``(n_rings, 2 n_rings, C * M)``, float32: weighted radiance times
        ``Phi_m`` at each node, channel-major.
    polar : numpy.ndarray
        Shape ``(M, n_rings, lmax + 1)``, float32: ``Theta_lm`` at each ring
        (0 where ``l < |m|``).
    sources : PointSources, optional
        Sources taken out of the map before the quadrature (`extract_point_sources`),
        which the estimator adds as points; None: the whole map is in the nodes.
    """

    lmax: int
    directions: np.ndarray
    weighted_radiance: np.ndarray
    basis: np.ndarray
    n_rings: int
    azimuthal: np.ndarray
    polar: np.ndarray
    sources: PointSources | None = None


@dataclass(frozen=True)
class PointSources:
    """Compact bright sources taken out of an environment map, each as a direction and a power.

    Attributes
    ----------
    directions : numpy.ndarray
        Shape ``(S, 3)``, unit directions towards the sources (world frame).
    power : numpy.ndarray
        Shape ``(S, C)``: each source's radiance integrated over its solid
        angle, i.e. the irradiance it gives a surface facing it.
    """

    directions: np.ndarray
    power: np.ndarray


def extract_point_sources(
    envmap: np.ndarray, max_radius_deg: float, min_radiance: float,
) -> tuple[np.ndarray, PointSources]:
    """Split an environment map into compact bright sources and the rest.

    The pixels whose brightness (radiance averaged over channels) exceeds
    ``min_radiance`` times the map's mean brightness over the sphere form
    8-connected components; those whose solid angle is that of a cap of
    angular radius at most ``max_radius_deg`` become sources. Each source's
    pixels are set to the mean radiance of the ring of pixels around it (the
    background), and what lay above the background is the source: its power
    is that excess integrated over solid angle and its direction the
    excess-weighted mean direction. The map's total power is conserved
    (residual plus sources).

    Parameters
    ----------
    envmap : numpy.ndarray
        Shape ``(H, W, C)``, equirectangular radiance.
    max_radius_deg : float
        Largest angular radius of a source, degrees (0: no sources).
    min_radiance : float
        Threshold on brightness, in units of the map's mean brightness (> 1).

    Returns
    -------
    residual : numpy.ndarray
        Shape ``(H, W, C)``, float64: the map without the sources.
    sources : PointSources
        ``S >= 0`` sources, brightest first.
    """
    env = np.asarray(envmap, dtype=np.float64)
    if env.ndim != 3:
        raise ValueError(f"envmap must have shape (H, W, C), got shape {env.shape}")
    if not (np.isfinite(max_radius_deg) and max_radius_deg >= 0):
        raise ValueError(f"max_radius_deg must be a finite number >= 0, got {max_radius_deg!r}")
    if not (np.isfinite(min_radiance) and min_radiance > 1):
        raise ValueError(f"min_radiance must be a finite number > 1, got {min_radiance!r}")
    h, w, n_ch = env.shape
    residual = env.copy()
    omega = np.broadcast_to(equirect_solid_angles(h, w)[:, None], (h, w))
    brightness = env.mean(axis=2)
    mean = float((brightness * omega).sum() / omega.sum())
    labels, count = label_components(brightness > min_radiance * mean)
    max_omega = 2.0 * np.pi * (1.0 - np.cos(np.radians(max_radius_deg)))
    directions, power = [], []
    dirs = equirect_directions(h, w)
    for k in range(1, count + 1):
        inside = labels == k
        if omega[inside].sum() > max_omega:
            continue
        ring = dilate(inside, 2) & (labels == 0)
        background = env[ring].mean(axis=0) if ring.any() else np.zeros(n_ch)
        excess = np.maximum(env[inside] - background, 0.0) * omega[inside][:, None]  # (P, C)
        centre = (excess.mean(axis=1)[:, None] * dirs[inside]).sum(axis=0)
        if not np.any(centre):
            continue
        residual[inside] = np.minimum(env[inside], background)
        directions.append(centre / np.linalg.norm(centre))
        power.append(excess.sum(axis=0))
    order = np.argsort([-p.mean() for p in power], kind="stable")
    return residual, PointSources(np.asarray(directions, dtype=np.float64).reshape(-1, 3)[order],
                                  np.asarray(power, dtype=np.float64).reshape(-1, n_ch)[order])


def label_components(mask: np.ndarray) -> tuple[np.ndarray, int]:
    """The 8-connected components of a 2D mask, numbered 1, 2, ... in the raster order of their
    first pixel, as ``scipy.ndimage.label`` with a 3 x 3 structure numbers them (the map's edges
    do not wrap); SciPy's import would cost an estimate job 0.3 s for this alone.

    Parameters
    ----------
    mask : numpy.ndarray
        Shape ``(H, W)``, bool.

    Returns
    -------
    labels : numpy.ndarray
        Shape ``(H, W)``, int32: 0 outside the mask.
    count : int
        Number of components.
    """
    mask = np.asarray(mask, dtype=bool)
    if mask.ndim != 2:
        raise ValueError(f"label_components: mask must be 2D, got shape {mask.shape}")
    h, w = mask.shape
    labels = np.zeros((h, w), dtype=np.int32)
    count = 0
    for i, j in zip(*np.nonzero(mask)):  # raster order; bright pixels are few
        if labels[i, j]:
            continue
        count += 1
        labels[i, j] = count
        stack = [(i, j)]
        while stack:
            y, x = stack.pop()
            for ny in range(max(y - 1, 0), min(y + 2, h)):
                for nx in range(max(x - 1, 0), min(x + 2, w)):
                    if mask[ny, nx] and not labels[ny, nx]:
                        labels[ny, nx] = count
                        stack.append((ny, nx))
    return labels, count


def dilate(mask: np.ndarray, steps: int) -> np.ndarray:
    """The pixels within ``steps`` 4-connected steps of a 2D mask (edges not wrapped), as
    ``scipy.ndimage.binary_dilation`` with its default cross and ``iterations=steps``.

    Parameters
    ----------
    mask : numpy.ndarray
        Shape ``(H, W)``, bool.
    steps : int
        Steps, >= 0.

    Returns
    -------
    numpy.ndarray
        Shape ``(H, W)``, bool.
    """
    out = np.asarray(mask, dtype=bool).copy()
    for _ in range(steps):
        grown = out.copy()
        grown[1:] |= out[:-1]
        grown[:-1] |= out[1:]
        grown[:, 1:] |= out[:, :-1]
        grown[:, :-1] |= out[:, 1:]
        out = grown
    return out


def light_quadrature(envmap: np.ndarray, lmax: int, prefilter: float = 0.0, light_lmax: int | None = None) -> LightQuadrature:
    """Quadrature nodes for the shadowed light of one environment map.

    The map is projected onto SH up to ``light_lmax`` (default ``max(2 lmax, 48)``,
    at most ``H / 2``: under the museum's 2.5-degree lamps the lobe-filtered
    shadowed light is then within 1.2% RMS of a per-pixel integration at
    l* = 20 and 0.08 <= alpha <= 0.8), optionally low-passed by ``exp(-(prefilter l)^2)`` (the paper's band limit
    a', section 4.2), and synthesised at the nodes of a Gauss-Legendre
    (``n`` nodes in cos theta) x uniform (``2n`` in phi) grid with
    ``n = (light_lmax + lmax) // 2 + 8``: exact for the product of the light
    and any ``Y_lm`` with ``l <= lmax``, with margin for the smooth shadowing factor.

    Parameters
    ----------
    envmap : numpy.ndarray
        Shape ``(H, W, C)``, equirectangular radiance (Mitsuba layout).
    lmax : int
        Degree of the shadowed light to be fitted (>= 0).
    prefilter : float
        Width a' of the Gaussian SH pre-filter (0: none).
    light_lmax : int, optional
        Degree of the light itself.

    Returns
    -------
    LightQuadrature
    """
    if isinstance(lmax, bool) or not isinstance(lmax, (int, np.integer)) or lmax < 0:
        raise ValueError(f"lmax must be an int >= 0, got {lmax!r}")
    if not (np.isfinite(prefilter) and prefilter >= 0):
        raise ValueError(f"prefilter must be a finite number >= 0, got {prefilter!r}")
    env = np.asarray(envmap, dtype=np.float64)
    if env.ndim != 3:
        raise ValueError(f"envmap must have shape (H, W, C), got shape {env.shape}")
    if light_lmax is None:
        # an H-row map resolves degrees up to about H / 2: beyond, its pixel quadrature aliases
        light_lmax = max(int(lmax), min(max(2 * int(lmax), 48), env.shape[0] // 2))
    height = env.shape[0]
    while height % 2 == 0 and height // 2 >= 2 * light_lmax + 8 and env.shape[1] % height == 0:
        height //= 2  # fewer pixels to project, still twice the rows the degree needs
    if height < env.shape[0]:
        env = downsample_equirect(env, height)
    coeffs = project_equirect(env, light_lmax) * np.exp(-((prefilter * sh_degrees(light_lmax)) ** 2))[:, None]
    n = (light_lmax + int(lmax)) // 2 + 8
    t, w_t = np.polynomial.legendre.leggauss(n)
    phi = 2.0 * np.pi * (np.arange(2 * n) + 0.5) / (2 * n)
    directions = angles_to_directions(np.arccos(t)[:, None], phi[None, :]).reshape(-1, 3)
    weights = np.repeat(w_t * (2.0 * np.pi / (2 * n)), 2 * n)
    weighted = eval_rings(coeffs, np.arccos(t), phi).reshape(-1, coeffs.shape[1]) * weights[:, None]
    azimuthal, polar = _ring_tables(np.arccos(t), phi, weighted.reshape(n, 2 * n, -1), int(lmax))
    return LightQuadrature(
        lmax=int(lmax),
        directions=directions,
        weighted_radiance=weighted,
        basis=real_sh(directions, int(lmax)).astype(np.float32),
        n_rings=n,
        azimuthal=azimuthal,
        polar=polar,
    )


def _ring_tables(theta: np.ndarray, phi: np.ndarray, weighted: np.ndarray, lmax: int) -> tuple[np.ndarray, np.ndarray]:
    """`LightQuadrature.azimuthal` and `.polar` of rings ``theta`` (n,), azimuths ``phi`` (2n,)
    and the weighted radiance on the grid (n, 2n, C)."""
    polar, trig = ring_factors(theta, phi, lmax)  # (n, M, L), (2n, M)
    azimuthal = np.einsum("jkc,km->jkcm", weighted, trig).reshape(weighted.shape[0], weighted.shape[1], -1)
    polar = polar.transpose(1, 0, 2)  # (M, n, L)
    return azimuthal.astype(np.float32), polar.astype(np.float32)


def shadowed_light(
    quadrature: LightQuadrature, normals: np.ndarray, alpha: np.ndarray | None = None, workers: int = 1
) -> np.ndarray:
    """SH coefficients of the light that reaches each texel, shadowed by ``G1(theta_i)``.

    ``Lg_lm(n) = int_{n.w > 0} G1(n . w, alpha) L(w) Y_lm(w) dw`` (paper
    section 4.2; without ``alpha``, ``G1 = 1``: the light of the upper
    hemisphere only). Computed in float32, as products of the texels'
    shadowing factors at the nodes with the factorised basis of the
    quadrature grid (`LightQuadrature`).

    Parameters
    ----------
    quadrature : LightQuadrature
        Nodes of the environment (`light_quadrature`).
    normals : numpy.ndarray
        Shape ``(T, 3)``, unit texel normals (world frame).
    alpha : numpy.ndarray, optional
        Shape ``(T,)``, GGX width per texel.
    workers : int
        Threads of the shadowing factors (the matrix products use BLAS's own).

    Returns
    -------
    numpy.ndarray
        Shape ``(T, (lmax+1)**2, C)``, float32, world-frame coefficients.
    """
    n = np.asarray(normals, dtype=np.float64)
    if n.ndim != 2 or n.shape[1] != 3:
        raise ValueError(f"normals must have shape (T, 3), got shape {n.shape}")
    if alpha is not None:
        alpha = np.asarray(alpha, dtype=np.float64)
        if alpha.shape != (n.shape[0],):
            raise ValueError(f"alpha must have shape ({n.shape[0]},), got shape {alpha.shape}")
    normals32 = n.astype(np.float32)
    alpha = np.zeros(n.shape[0]) if alpha is None else alpha  # alpha 0: G1 = 1 above the horizon
    return project_factors(
        quadrature, n.shape[0], lambda a, b, dirs, out: shadowing_factors(normals32[a:b], dirs, alpha[a:b], out), workers
    )


def project_factors(
    quadrature: LightQuadrature, n_columns: int, factors: Callable[[int, int, np.ndarray, np.ndarray], None],
    workers: int = 1, multiple: int = 1,
) -> np.ndarray:
    """SH coefficients of the quadrature's light times each of ``n_columns`` functions on the nodes.

    ``out[j, lm] = sum_q f_j(w_q) weighted_radiance_q Y_lm(w_q)``, column by column:
    ``factors(a, b, directions, out)`` writes ``f_j`` for ``a <= j < b`` at the nodes
    ``directions`` (3, Q) into ``out`` (b - a, Q), float32 (`shadowed_light`: ``G1`` at a texel's
    normal and roughness).

    Parameters
    ----------
    quadrature : LightQuadrature
        Nodes of the environment (`light_quadrature`).
    n_columns : int
        Number of functions.
    factors : callable
        Writes the functions' values at the nodes, a block of columns at a time.
    workers : int
        Threads of ``factors`` (the matrix products use BLAS's own).
    multiple : int
        Every block of columns but the last starts and ends at a multiple of this.

    Returns
    -------
    numpy.ndarray
        Shape ``(n_columns, (lmax+1)**2, C)``, float32.
    """
    q = quadrature
    n_coef = q.basis.shape[1]
    n_ch = q.weighted_radiance.shape[1]
    n_orders = q.polar.shape[0]
    # products with the columns on the last axis: every operand is a (possibly transposed)
    # matrix that BLAS takes as it is; each block's result is reordered once, while in cache
    azimuthal = np.ascontiguousarray(q.azimuthal.transpose(0, 2, 1))  # (n, C*M, 2n)
    polar = np.ascontiguousarray(q.polar.transpose(0, 2, 1))  # (M, L, n)
    dirs = np.ascontiguousarray(q.directions.T, dtype=np.float32)
    out = np.empty((n_columns, n_coef, n_ch), np.float32)
    block = max(multiple, _TEXEL_CHUNK - _TEXEL_CHUNK % multiple)
    g = np.empty((min(n_columns, block), dirs.shape[1]), np.float32)
    set_threads(workers)
    for a in range(0, n_columns, block):
        b = min(n_columns, a + block)
        factors(a, b, dirs, g[: b - a])
        # sum over each ring's azimuths, then over rings (LightQuadrature): about 6 times
        # fewer operations than one product with every node's Y_lm
        rings = np.matmul(azimuthal, g[: b - a].reshape(b - a, q.n_rings, -1).transpose(1, 2, 0))  # (n, C*M, t)
        per_ring = rings.reshape(q.n_rings, n_ch, n_orders, b - a).transpose(1, 2, 0, 3)  # (C, M, n, t)
        per_degree = np.matmul(polar, per_ring).transpose(3, 1, 2, 0)  # (t, M, L, C)
        for l in range(q.lmax + 1):  # flat indices l^2 .. l^2 + 2l are the orders m = -l .. l
            out[a:b, l * l : (l + 1) * (l + 1)] = per_degree[:, q.lmax - l : q.lmax + l + 1, l]
    return out


def downsample_equirect(envmap: np.ndarray, height: int) -> np.ndarray:
    """Equirectangular map resampled to ``height`` rows by solid-angle-weighted box filtering.

    Rows of the source are assigned to the nearest target row (by polar angle)
    and columns to target columns in blocks of ``W / (2 height)``, so the
    radiant power of every target pixel is that of the source pixels it
    covers (the total is preserved exactly).

    Parameters
    ----------
    envmap : numpy.ndarray
        Shape ``(H, W, C)`` with ``W`` a multiple of ``2 height``.
    height : int
        Target height (>= 2, <= H).

    Returns
    -------
    numpy.ndarray
        Shape ``(height, 2 height, C)``, float64.
    """
    env = np.asarray(envmap, dtype=np.float64)
    h, w = env.shape[:2]
    if not 2 <= height <= h or w % (2 * height):
        raise ValueError(f"cannot downsample a {h} x {w} map to height {height}: need 2 <= height <= {h} "
                         f"and the width a multiple of {2 * height}")
    src = env * equirect_solid_angles(h, w)[:, None, None]
    src = src.reshape(h, 2 * height, w // (2 * height), -1).sum(axis=2)
    rows = np.rint(np.arange(h) * (height - 1) / (h - 1)).astype(np.int64)
    power = np.zeros((height, 2 * height, env.shape[2]))
    np.add.at(power, rows, src)
    return power / equirect_solid_angles(height, 2 * height)[:, None, None]


def irradiance(
    envmap: np.ndarray, normals: np.ndarray, grid_height: int = 64, source_height: int = 64, bright: int = 2048
) -> np.ndarray:
    """Irradiance ``E(n) = int max(n . w, 0) L(w) dw`` at surface normals (paper Eq. 14).

    Quadrature of the map (box-filtered to ``source_height`` rows) in two
    parts: its ``bright`` most powerful pixels (lamps, the sun) exactly at
    every normal, and the rest at the normals of an equirectangular grid of
    ``grid_height`` rows, interpolated bilinearly (that part is smooth in the
    normal, whereas a bright lamp puts a kink at its terminator). Unlike a low
    SH degree this stays accurate on the side facing away from a small bright
    lamp or the sun. Occlusion by the object itself is ignored, as in the
    paper's model.

    Parameters
    ----------
    envmap : numpy.ndarray
        Shape ``(H, W, C)``, equirectangular radiance.
    normals : numpy.ndarray
        Shape ``(T, 3)``, unit normals (world frame).
    grid_height, source_height : int
        Rows of the normal grid and of the filtered map.
    bright : int
        Pixels summed exactly at every normal.

    Returns
    -------
    numpy.ndarray
        Shape ``(T, C)``, radiance times sr (``pi L`` for a constant map).
    """
    env = np.asarray(envmap, dtype=np.float64)
    if env.ndim != 3:
        raise ValueError(f"envmap must have shape (H, W, C), got shape {env.shape}")
    n = np.asarray(normals, dtype=np.float64)
    if n.ndim != 2 or n.shape[1] != 3:
        raise ValueError(f"normals must have shape (T, 3), got shape {n.shape}")
    h, w = env.shape[:2]
    power = (env * equirect_solid_angles(h, w)[:, None, None]).reshape(h * w, -1)
    top = np.argsort(-power.sum(axis=1), kind="stable")[:bright]
    rest = env.reshape(h * w, -1).copy()
    rest[top] = 0.0
    small = downsample_equirect(rest.reshape(env.shape), min(source_height, h))
    hs, ws = small.shape[:2]
    small_power = (small * equirect_solid_angles(hs, ws)[:, None, None]).reshape(hs * ws, -1)
    grid = equirect_directions(grid_height, 2 * grid_height).reshape(-1, 3)
    table = _clamped_cosine_sums(grid, equirect_directions(hs, ws).reshape(-1, 3), small_power)
    out = sample_equirect(table.reshape(grid_height, 2 * grid_height, -1), n)
    return out + _clamped_cosine_sums(n, equirect_directions(h, w).reshape(-1, 3)[top], power[top])


def _clamped_cosine_sums(normals: np.ndarray, directions: np.ndarray, power: np.ndarray) -> np.ndarray:
    """``sum_p max(n . d_p, 0) power_p`` per normal (T, 3) over sources (P, 3) of power (P, C),
    in float32 blocks of 1,024 normals whose cosines stay in cache."""
    n32, dirs, p32 = normals.astype(np.float32), directions.T.astype(np.float32), power.astype(np.float32)
    out = np.empty((n32.shape[0], p32.shape[1]))
    cosines = np.empty((min(n32.shape[0], 1024), dirs.shape[1]), np.float32)
    for a in range(0, n32.shape[0], 1024):
        block = cosines[: min(n32.shape[0] - a, 1024)]
        np.matmul(n32[a : a + 1024], dirs, out=block)
        out[a : a + 1024] = np.maximum(block, 0.0, out=block) @ p32
    return out
