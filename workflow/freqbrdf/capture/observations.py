"""Per-texel observations: what each texel of the UV atlas shows in each view.

Layout of one capture's observations (``T`` valid texels, ``K`` views, all
float32 unless stated; written by the ``extract_observations`` rule):

- ``texels.npz``: ``resolution`` (R), ``texel`` (T,) int64 flat index
  ``i * R + j`` into the R x R atlas, ``position`` (T, 3) world, ``normal``,
  ``tangent``, ``bitangent`` (T, 3) the local frame (n is the shading normal),
  ``dilated`` (T,) bool (texel centre just outside every chart, filled from the
  nearest triangle so bilinear lookups across UV seams see real values).
- ``radiance.npy`` (T, K, 3): outgoing radiance B_k(p), bilinear from the HDR
  view; 0 where not observed.
- ``weight.npy`` (T, K): cos(theta_o) where observed, else 0 (the sample
  weight of the paper's SH fit, section 4.2 and Fig. 3).
- ``wo_local.npy`` (T, K, 3): unit direction toward the camera in the local
  frame (x = tangent, y = bitangent, z = normal). The mirror direction in the
  same frame is ``(-x, -y, z)``.
- ``incoming.npy`` (T, K, 3): band-limited environment radiance L(w_r) seen
  along the world mirror direction.
- ``views.json``: view names in K order, the band-limit parameter and counts.

A (texel, view) pair is observed when the texel projects inside the image,
faces the camera, is not occluded (a ray cast toward the camera), lies where
the object mask covers the whole bilinear footprint, every pixel of that
footprint sees the texel's own surface (not an occluding part of the object
in front of it), and every pixel read is finite.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from freqbrdf.artefacts import SurfaceTexels
from freqbrdf.scene.cameras import Cameras, project
from freqbrdf.scene.meshes import Mesh
from freqbrdf.sphere.sh import filter_equirect

Occluded = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def tangent_frame(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal tangent and bitangent for unit normals, continuous except near n_z = -1.

    Uses the branchless construction of Duff et al. (2017, "Building an
    orthonormal basis, revisited").

    Parameters
    ----------
    normal : ndarray, shape (..., 3)
        Unit normals.

    Returns
    -------
    tangent, bitangent : ndarray, shape (..., 3)
        With ``tangent x bitangent = normal``.
    """
    x, y, z = normal[..., 0], normal[..., 1], normal[..., 2]
    sign = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z)
    b = x * y * a
    tangent = np.stack([1.0 + sign * x * x * a, sign * b, -sign * x], axis=-1)
    bitangent = np.stack([b, sign + y * y * a, -y], axis=-1)
    return tangent, bitangent


def _closest_on_triangle(p: np.ndarray, tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Barycentrics of the closest point of each 2D triangle to p, and the distance.

    p : (N, 2); tri : (N, 3, 2). Returns bary (N, 3) and distance (N,).
    """
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0, v1, v2 = b - a, c - a, p - a
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    safe = np.where(np.abs(den) > 1e-20, den, 1.0)
    l1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / safe
    l2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / safe
    bary = np.stack([1.0 - l1 - l2, l1, l2], axis=-1)
    inside = (bary >= -1e-9).all(axis=1) & (np.abs(den) > 1e-20)
    dist = np.where(inside, 0.0, np.inf)
    best = bary.copy()
    # Outside: the closest point lies on one of the three edges.
    for i, j in ((0, 1), (1, 2), (2, 0)):
        e = tri[:, j] - tri[:, i]
        t = np.clip(np.einsum("nk,nk->n", p - tri[:, i], e) / np.maximum(np.einsum("nk,nk->n", e, e), 1e-30), 0.0, 1.0)
        d = np.linalg.norm(tri[:, i] + t[:, None] * e - p, axis=1)
        better = ~inside & (d < dist)
        edge_bary = np.zeros_like(bary)
        edge_bary[:, i] = 1.0 - t
        edge_bary[:, j] = t
        best[better] = edge_bary[better]
        dist = np.where(better, d, dist)
    return best, dist


def rasterise_uv(
    mesh: Mesh, resolution: int, dilate_texels: float = 1.0, chunk_faces: int = 8192, *, compiled: bool = True
) -> SurfaceTexels:
    """Surface point and frame of every texel the mesh's UV atlas covers.

    A texel is valid when its centre lies in a UV triangle, or within
    ``dilate_texels`` (in texel units) of one: those border texels take the
    nearest point of the nearest triangle, so texels cut by a chart border are
    not lost.

    Parameters
    ----------
    mesh : Mesh
        Triangle mesh with per-vertex normals and uvs.
    resolution : int
        Atlas size R.
    dilate_texels : float
        Dilation distance in texels (0 disables it).
    chunk_faces : int
        Faces processed at once by the NumPy path (bounds memory).
    compiled : bool
        Find each texel's nearest triangle with the kernel of
        `freqbrdf.capture.kernels` (default; same result, 20x faster) instead
        of the NumPy reference.

    Returns
    -------
    SurfaceTexels
    """
    if resolution < 2:
        raise ValueError(f"resolution must be >= 2, got {resolution}")
    R = int(resolution)
    uv = mesh.uvs * R - 0.5  # texel-index coordinates: texel (i, j) centre at (x=j, y=i)
    if compiled:
        from freqbrdf.capture.kernels import nearest_faces  # imports numba: only where it runs

        best_face, best_bary, best_dist = nearest_faces(uv, mesh.faces, R, float(dilate_texels))
    else:
        best_face, best_bary, best_dist = _nearest_faces(uv, mesh.faces, R, dilate_texels, chunk_faces)
    texel = np.nonzero(best_face >= 0)[0]
    corners = mesh.faces[best_face[texel]]  # (T, 3)
    bary = best_bary[texel][..., None]
    position = (mesh.vertices[corners] * bary).sum(axis=1)
    normal = (mesh.normals[corners] * bary).sum(axis=1)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    tangent, bitangent = tangent_frame(normal)
    return SurfaceTexels(R, texel, position, normal, tangent, bitangent, best_dist[texel] > 0.0)


def _nearest_faces(
    uv: np.ndarray, faces: np.ndarray, R: int, dilate_texels: float, chunk_faces: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest UV triangle of every texel centre within ``dilate_texels`` (NumPy reference).

    ``uv`` (V, 2) in texel-index coordinates, ``faces`` (F, 3). Returns, per texel
    of the R x R atlas (flat ``i * R + j``): the face (-1: none), its barycentrics
    of the nearest point (R*R, 3) and the distance (0 inside; ties go to the
    lowest face index).
    """
    best_dist = np.full(R * R, np.inf)
    best_face = np.full(R * R, -1, dtype=np.int64)
    best_bary = np.zeros((R * R, 3))
    for start in range(0, len(faces), chunk_faces):
        chunk = np.arange(start, min(start + chunk_faces, len(faces)))
        tri = uv[faces[chunk]]  # (F, 3, 2)
        lo = np.clip(np.floor(tri.min(axis=1) - dilate_texels), 0, R - 1).astype(np.int64)
        hi = np.clip(np.ceil(tri.max(axis=1) + dilate_texels), 0, R - 1).astype(np.int64)
        nx, ny = hi[:, 0] - lo[:, 0] + 1, hi[:, 1] - lo[:, 1] + 1
        counts = nx * ny
        owner = np.repeat(np.arange(len(chunk)), counts)
        offset = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        px = lo[owner, 0] + offset % nx[owner]
        py = lo[owner, 1] + offset // nx[owner]
        bary, dist = _closest_on_triangle(np.stack([px, py], axis=1).astype(np.float64), tri[owner])
        keep = dist <= dilate_texels
        flat = (py * R + px)[keep]
        dist, bary, face = dist[keep], bary[keep], chunk[owner[keep]]
        # Per texel keep the candidate nearest its triangle (0 when inside one).
        order = np.lexsort((dist, flat))
        flat, dist, bary, face = flat[order], dist[order], bary[order], face[order]
        first = np.ones(len(flat), dtype=bool)
        first[1:] = flat[1:] != flat[:-1]
        flat, dist, bary, face = flat[first], dist[first], bary[first], face[first]
        better = dist < best_dist[flat]
        best_dist[flat[better]] = dist[better]
        best_face[flat[better]] = face[better]
        best_bary[flat[better]] = bary[better]
    return best_face, best_bary, best_dist


def band_limit_parameter(n_views: int, rule: str) -> float:
    """Band-limit width a' from the number of views (paper section 4.2: a signal sampled
    n times is band-limited to about n^(1/2), so roughness below a' = K^(-1/2) is not recovered).

    Parameters
    ----------
    n_views : int
        Number of views K.
    rule : {"paper", "reference"}
        ``paper``: a' = K^(-1/2); ``reference`` (authors' code): 1 / floor(sqrt(K)).
    """
    if n_views < 1:
        raise ValueError(f"n_views must be >= 1, got {n_views}")
    if rule == "paper":
        return float(n_views) ** -0.5
    if rule == "reference":
        return 1.0 / np.floor(np.sqrt(n_views))
    raise ValueError(f"band-limit rule must be 'paper' or 'reference', got {rule!r}")


def band_limited_envmap(envmap: np.ndarray, a_prime: float, lmax: int | None = None) -> np.ndarray:
    """Environment map low-passed by the SH filter exp(-(a' l)^2).

    Parameters
    ----------
    envmap : ndarray, shape (H, W, 3)
        Equirectangular radiance.
    a_prime : float
        Filter width (> 0); roughness below it cannot be recovered from K views.
    lmax : int, optional
        Highest degree kept; default ceil(3.5 / a'), where the filter is below 5e-6.

    Returns
    -------
    ndarray, shape (H, W, 3), float32
        The filtered map on the same grid.
    """
    if not a_prime > 0:
        raise ValueError(f"a_prime must be > 0, got {a_prime}")
    lmax = int(np.ceil(3.5 / a_prime)) if lmax is None else int(lmax)
    # The SH projection and its evaluation back on the grid, separably (rows share a
    # polar angle, columns an azimuth): 30x faster than the direct sums at 256 x 512.
    return filter_equirect(envmap, np.exp(-((a_prime * np.arange(lmax + 1)) ** 2))).astype(np.float32)


def equirect_corners(dirs: np.ndarray, height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """The four pixels of an equirect map around each direction and their bilinear weights.

    Pixel centres as `freqbrdf.sphere.sampling.equirect_directions` (rows from pole to
    pole, columns wrapping in azimuth), as Mitsuba's envmap interpolates.

    Parameters
    ----------
    dirs : numpy.ndarray
        Shape ``(..., 3)``, unit directions.
    height, width : int
        Map size (``height >= 2``).

    Returns
    -------
    index : numpy.ndarray
        Shape ``(..., 4)``, int64: flat pixel indices ``row * width + column``.
    weight : numpy.ndarray
        Shape ``(..., 4)``, float64: bilinear weights, summing to 1.
    """
    theta = np.arccos(np.clip(dirs[..., 1], -1.0, 1.0))
    phi = np.mod(np.arctan2(dirs[..., 0], -dirs[..., 2]), 2.0 * np.pi)
    row = theta / np.pi * (height - 1)
    col = phi / (2.0 * np.pi) * width - 0.5
    r0 = np.clip(np.floor(row).astype(np.int64), 0, height - 2)
    c0 = np.floor(col).astype(np.int64)
    fr = row - r0
    fc = col - c0
    c0, c1 = np.mod(c0, width), np.mod(c0 + 1, width)
    index = np.stack([r0 * width + c0, r0 * width + c1, (r0 + 1) * width + c0, (r0 + 1) * width + c1], axis=-1)
    weight = np.stack([(1.0 - fr) * (1.0 - fc), (1.0 - fr) * fc, fr * (1.0 - fc), fr * fc], axis=-1)
    return index, weight


def sample_equirect(envmap: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Bilinear lookup of an equirect map along world directions, as Mitsuba's envmap does.

    Parameters
    ----------
    envmap : ndarray, shape (H, W, C)
    dirs : ndarray, shape (..., 3)
        Unit directions.

    Returns
    -------
    ndarray, shape (..., C)
    """
    h, w = envmap.shape[:2]
    index, weight = equirect_corners(dirs, h, w)
    return np.einsum("...j,...jc->...c", weight, envmap.reshape(h * w, -1)[index])


def bilinear_views(images: np.ndarray, view: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear samples of several images at continuous pixel coordinates.

    Parameters
    ----------
    images : ndarray, shape (K, H, W, C) or (K, H, W)
    view : ndarray, shape (P,), int
        Which image each sample reads.
    x, y : ndarray, shape (P,)
        Pixel coordinates (pixel centres at +0.5), inside [0.5, W - 0.5] x [0.5, H - 0.5].

    Returns
    -------
    values : ndarray, shape (P, C) or (P,)
    finite : ndarray, shape (P,), bool
        False where any of the four pixels read is NaN or infinite.
    """
    _, h, w = images.shape[:3]
    fx, fy = x - 0.5, y - 0.5
    x0 = np.clip(np.floor(fx).astype(np.int64), 0, w - 2)
    y0 = np.clip(np.floor(fy).astype(np.int64), 0, h - 2)
    tx, ty = fx - x0, fy - y0
    if images.ndim == 4:
        tx, ty = tx[:, None], ty[:, None]
    taps = [images[view, y0, x0], images[view, y0, x0 + 1], images[view, y0 + 1, x0], images[view, y0 + 1, x0 + 1]]
    finite = np.logical_and.reduce([np.isfinite(t) if t.ndim == 1 else np.isfinite(t).all(axis=1) for t in taps])
    taps = [np.where(np.isfinite(t), t, 0.0) for t in taps]
    values = (taps[0] * (1 - tx) + taps[1] * tx) * (1 - ty) + (taps[2] * (1 - tx) + taps[3] * tx) * ty
    return values, finite


def edge_free_distances(distances: np.ndarray, jump: float = 0.1, *, compiled: bool = True) -> np.ndarray:
    """Mark pixels next to a depth discontinuity as unusable.

    A pixel's value is the mean radiance over its area, so a pixel whose
    neighbour sees a surface much nearer or farther (an occluding edge inside
    the object, or the silhouette) may mix two surfaces even when its centre
    does not.

    Parameters
    ----------
    distances : ndarray, shape (K, H, W)
        Pixel-centre distances (``inf`` for background).
    jump : float
        Distance change between neighbouring pixels that counts as an edge
        (object units; the object's radius is 1).
    compiled : bool
        Use the kernel of `freqbrdf.capture.kernels` (default; one pass instead
        of NumPy's nine over float64 copies) rather than this NumPy reference.

    Returns
    -------
    ndarray, shape (K, H, W), float32
        ``distances`` with NaN at pixels within one pixel of an edge or of the background.
    """
    if compiled:
        from freqbrdf.capture.kernels import edge_free_distances as kernel  # imports numba: only where it runs

        return kernel(distances, jump)
    d = distances.astype(np.float64)
    padded = np.pad(d, ((0, 0), (1, 1), (1, 1)), mode="edge")
    h, w = d.shape[1:]
    edge = ~np.isfinite(d)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            neighbour = padded[:, 1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
            with np.errstate(invalid="ignore"):
                edge |= ~np.isfinite(neighbour) | (np.abs(neighbour - d) > jump)
    return np.where(edge, np.nan, d).astype(np.float32)


def _footprint_distances(distances: np.ndarray, view: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Values of the four pixels a bilinear read at (x, y) uses, shape (P, 4)."""
    _, h, w = distances.shape
    x0 = np.clip(np.floor(x - 0.5).astype(np.int64), 0, w - 2)
    y0 = np.clip(np.floor(y - 0.5).astype(np.int64), 0, h - 2)
    return np.stack([distances[view, y0, x0], distances[view, y0, x0 + 1],
                     distances[view, y0 + 1, x0], distances[view, y0 + 1, x0 + 1]], axis=1)


def observe(
    texels: SurfaceTexels,
    cameras: Cameras,
    images: np.ndarray,
    coverage: np.ndarray,
    incoming_map: np.ndarray,
    occluded: Occluded,
    *,
    distances: np.ndarray | None = None,
    min_coverage: float = 0.99,
    ray_offset: float = 1e-3,
    footprint_slack: float = 2.0,
    compiled: bool = True,
) -> dict[str, np.ndarray]:
    """Observations of a set of texels in every view (one chunk of the capture).

    Parameters
    ----------
    texels, cameras : SurfaceTexels, Cameras
        T texels, K views.
    images, coverage : ndarray, shape (K, H, W, 3) and (K, H, W)
        Linear HDR views (NaN/Inf pixels are never observed) and object masks in [0, 1].
    incoming_map : ndarray, shape (He, We, 3)
        Band-limited environment map sampled along mirror directions.
    occluded : callable
        ``occluded(origins (P, 3), directions (P, 3), distances (P,)) -> (P,) bool``,
        e.g. :func:`freqbrdf.scene.raycast.occlusion_test` bound to the mesh.
    distances : ndarray, shape (K, H, W), optional
        Distance from each camera to the surface seen at each pixel centre
        (:func:`freqbrdf.scene.raycast.distance_maps`), NaN near an edge (`edge_free_distances`).
        When given, a pair is kept only if all four pixels it reads see the texel's own
        surface, which drops samples straddling an occlusion edge inside the object.
    min_coverage : float
        Smallest bilinear mask value accepted (no silhouette pixels mixing in background).
    ray_offset : float
        Offset of visibility rays along the normal, in object units, so a
        texel does not occlude itself.
    footprint_slack : float
        Depth tolerance of the footprint test in pixel footprints, divided by
        cos(theta_o) (a surface seen at a grazing angle changes depth fast).
    compiled : bool
        Use the compiled kernels of `view_geometry` and `pair_observations` (default)
        instead of their NumPy references (same observations).

    Returns
    -------
    dict
        ``radiance`` (T, K, 3), ``weight`` (T, K), ``wo_local`` (T, K, 3),
        ``incoming`` (T, K, 3), float32, ``nonfinite`` (int): pairs dropped
        because a pixel read was NaN or infinite, and ``view_candidates`` (K,) int:
        texels in front of each camera, inside its image and facing it (0: the
        camera sees none of these texels).
    """
    geometry = view_geometry(texels, cameras, incoming_map, compiled=compiled)
    ki, ti = np.nonzero(geometry["candidate"].T)  # view-major: consecutive reads hit the same image
    pairs = pair_observations(geometry, ti, ki, texels, cameras, images, coverage, distances,
                              min_coverage=min_coverage, ray_offset=ray_offset, footprint_slack=footprint_slack,
                              compiled=compiled)
    # Rays only for the pairs the pixel tests keep (every test is per pair, so their
    # order does not change which pairs pass); a blocked pair is unobserved again.
    usable = pairs["usable"]
    blocked = occluded(pairs["origins"][usable], pairs["directions"][usable], pairs["lengths"][usable])
    tb, kb = ti[usable][blocked], ki[usable][blocked]
    radiance, weight = pairs["radiance"], pairs["weight"]
    radiance[tb, kb] = 0.0
    weight[tb, kb] = 0.0
    return {"radiance": radiance, "weight": weight, "wo_local": geometry["wo_local"],
            "incoming": geometry["incoming"], "nonfinite": int((~pairs["finite"][usable] & ~blocked).sum()),
            "view_candidates": np.bincount(ki, minlength=len(cameras))}


def view_geometry(
    texels: SurfaceTexels, cameras: Cameras, incoming_map: np.ndarray, *, compiled: bool = True
) -> dict[str, np.ndarray]:
    """Where every texel lies in every view, and the light along its mirror direction.

    Parameters
    ----------
    texels, cameras : SurfaceTexels, Cameras
        T texels, K views.
    incoming_map : ndarray, shape (He, We, 3)
        Band-limited environment map sampled along mirror directions.
    compiled : bool
        Use the fused kernel of `freqbrdf.capture.kernels` (default); False
        runs the NumPy reference it is tested against (same values, to the last
        bit of an angle; 10x slower).

    Returns
    -------
    dict
        ``dist`` (T, K): distance to the camera; ``wo`` (T, K, 3): unit direction
        toward it (world); ``cos_o`` (T, K): its cosine with the normal; ``x``,
        ``y`` (T, K): pixel coordinates of the projection; ``candidate`` (T, K)
        bool: in front of the camera, inside the image and facing it;
        ``wo_local`` (T, K, 3) float32: ``wo`` in the texel's frame; ``incoming``
        (T, K, 3) float32: `sample_equirect` of ``incoming_map`` along the mirror
        direction.
    """
    frame = np.stack([texels.tangent, texels.bitangent, texels.normal], axis=1)  # (T, 3, 3), rows = local axes
    if compiled:
        from freqbrdf.capture.kernels import view_geometry as kernel  # imports numba: only where it runs

        return kernel(texels.position, texels.normal, frame, cameras.centres, cameras.world_to_camera, cameras.K,
                      cameras.width, cameras.height, incoming_map)
    p, n = texels.position, texels.normal
    to_cam = cameras.centres[None, :, :] - p[:, None, :]  # (T, K, 3)
    dist = np.linalg.norm(to_cam, axis=-1)
    wo = to_cam / dist[..., None]
    cos_o = np.einsum("tkc,tc->tk", wo, n)
    pix, depth = project(p, cameras.K, cameras.world_to_camera)  # (T, K, 2), (T, K)
    x, y = pix[..., 0], pix[..., 1]
    inside = (depth > 0) & (x >= 0.5) & (x <= cameras.width - 0.5) & (y >= 0.5) & (y <= cameras.height - 0.5)
    wr = 2.0 * cos_o[..., None] * n[:, None, :] - wo
    return {
        "dist": dist, "wo": wo, "cos_o": cos_o, "x": x, "y": y, "candidate": inside & (cos_o > 0.0),
        "wo_local": np.einsum("tij,tkj->tki", frame, wo).astype(np.float32),
        "incoming": sample_equirect(incoming_map, wr).astype(np.float32),
    }


def pair_observations(
    geometry: dict[str, np.ndarray], ti: np.ndarray, ki: np.ndarray, texels: SurfaceTexels, cameras: Cameras,
    images: np.ndarray, coverage: np.ndarray, distances: np.ndarray | None, *, min_coverage: float,
    ray_offset: float, footprint_slack: float, compiled: bool = True,
) -> dict[str, np.ndarray]:
    """What the views show of P candidate (texel, view) pairs, before the visibility test.

    Parameters
    ----------
    geometry : dict
        `view_geometry` of the T texels.
    ti, ki : ndarray, shape (P,), int
        Texel and view of each pair (each pair once).
    texels, cameras, images, coverage, distances, min_coverage, ray_offset, footprint_slack
        As in `observe`.
    compiled : bool
        Use the fused kernel of `freqbrdf.capture.kernels` (default) instead
        of this NumPy reference (same values).

    Returns
    -------
    dict
        ``usable`` (P,) bool: the object mask covers the bilinear footprint and,
        with ``distances``, every pixel of it sees the texel's own surface;
        ``finite`` (P,) bool: every pixel read is finite; ``radiance`` (T, K, 3)
        and ``weight`` (T, K), float32: the bilinear pixel value and cos(theta_o)
        of the usable, finite pairs, 0 elsewhere; ``origins``, ``directions``
        (P, 3) and ``lengths`` (P,): the segment from just off the surface to the
        camera that `observe` tests for occluders.
    """
    if compiled:
        from freqbrdf.capture.kernels import pair_observations as kernel  # imports numba: only where it runs

        return kernel(ti, ki, texels.position, texels.normal, cameras.centres, cameras.K[:, 0, 0], geometry, images,
                      coverage, distances, min_coverage, ray_offset, footprint_slack)
    dist, cos_o = geometry["dist"][ti, ki], geometry["cos_o"][ti, ki]
    x, y = geometry["x"][ti, ki], geometry["y"][ti, ki]
    mask, _ = bilinear_views(coverage, ki, x, y)
    usable = mask >= min_coverage
    if distances is not None:
        pixel_size = dist / cameras.K[ki, 0, 0]  # world size of one pixel at the texel
        slack = ray_offset + footprint_slack * pixel_size / np.maximum(cos_o, 0.1)
        gap = np.abs(_footprint_distances(distances, ki, x, y) - dist[:, None])
        usable &= (gap <= slack[:, None]).all(axis=1)  # NaN (edge pixels) fails
    values, finite = bilinear_views(images, ki, x, y)
    seen = usable & finite
    radiance = np.zeros(geometry["x"].shape + (3,), np.float32)
    radiance[ti[seen], ki[seen]] = values[seen]
    weight = np.zeros(geometry["x"].shape, np.float32)
    weight[ti[seen], ki[seen]] = cos_o[seen]
    origins = texels.position[ti] + ray_offset * texels.normal[ti]
    return {"usable": usable, "finite": finite, "radiance": radiance, "weight": weight, "origins": origins,
            "directions": geometry["wo"][ti, ki], "lengths": np.linalg.norm(cameras.centres[ki] - origins, axis=1)}

