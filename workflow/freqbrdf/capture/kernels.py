"""Compiled (numba) inner loops of observation extraction.

Each kernel fuses a step of `freqbrdf.capture.observations` that NumPy spreads over
many temporaries the size of a chunk's (texel, view) pairs, and its NumPy
counterpart there (``compiled=False``) is the reference the tests compare it
with:

- `view_geometry`: direction and distance to the camera, projection, local
  view direction and the band-limited light along the mirror direction of
  every pair (`freqbrdf.capture.observations.view_geometry`);
- `pair_observations`: the mask, depth-footprint and bilinear image reads of
  the candidate pairs and their visibility rays
  (`freqbrdf.capture.observations.pair_observations`);
- `edge_free_distances`: pixels next to a depth discontinuity marked unusable
  (`freqbrdf.capture.observations.edge_free_distances`);
- `nearest_faces`: each texel's nearest UV triangle
  (`freqbrdf.capture.observations.rasterise_uv`).

The arithmetic follows the NumPy code operation by operation (same order of
sums, `_dot3` for einsum's, no fused multiply-adds), so the results agree bit
for bit, except where ``acos``/``atan2`` of the platform's libm and NumPy's
vectorised versions differ in the last bit of an angle, which moves a bilinear
weight of the incoming light by about 1e-16.

The kernels are compiled on first use and cached on disk (numba ``cache=True``).
Each output element is written by exactly one iteration of the parallel loop,
so results do not depend on the number of threads. Importing this module
imports numba (about 0.2 s), so `freqbrdf.capture.observations` imports it lazily.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from freqbrdf.util.threads import set_threads  # one thread setting for every compiled kernel

__all__ = ["set_threads", "view_geometry", "pair_observations", "edge_free_distances", "nearest_faces"]


def _floats(array: np.ndarray) -> np.ndarray:
    """``array`` C-contiguous, float32 or float64 as given (the kernels compile for each,
    so their arithmetic matches NumPy's on the same values); other types as float64."""
    array = np.asarray(array)
    return np.ascontiguousarray(array, array.dtype if array.dtype in (np.float32, np.float64) else np.float64)


@numba.njit(cache=True, inline="always")
def _dot3(a0, a1, a2, b0, b1, b2):  # pragma: no cover - compiled
    """a . b summed as NumPy's einsum sums three products, (0 + 2) + 1 (its two SIMD lanes),
    so the kernels reproduce the reference's last bits."""
    return (a0 * b0 + a2 * b2) + a1 * b1

@numba.njit(parallel=True, cache=True, error_model="numpy")
def _view_geometry(position, normal, frame, centres, rotation, translation, intrinsics, width, height, envmap,
                   dist, wo, cos_o, x, y, candidate, wo_local, incoming):  # pragma: no cover - compiled
    n_tex, n_views = dist.shape
    env_h, env_w, n_ch = envmap.shape
    two_pi = 2.0 * np.pi
    for t in numba.prange(n_tex):
        px, py, pz = position[t, 0], position[t, 1], position[t, 2]
        nx, ny, nz = normal[t, 0], normal[t, 1], normal[t, 2]
        for k in range(n_views):
            # direction and distance to the camera
            tx, ty, tz = centres[k, 0] - px, centres[k, 1] - py, centres[k, 2] - pz
            d = math.sqrt(tx * tx + ty * ty + tz * tz)  # np.linalg.norm's order
            wx, wy, wz = tx / d, ty / d, tz / d
            c = _dot3(wx, wy, wz, nx, ny, nz)
            dist[t, k], cos_o[t, k] = d, c
            wo[t, k, 0], wo[t, k, 1], wo[t, k, 2] = wx, wy, wz
            # projection (freqbrdf.scene.cameras.project)
            cam0 = _dot3(rotation[k, 0, 0], rotation[k, 0, 1], rotation[k, 0, 2], px, py, pz) + translation[k, 0]
            cam1 = _dot3(rotation[k, 1, 0], rotation[k, 1, 1], rotation[k, 1, 2], px, py, pz) + translation[k, 1]
            cam2 = _dot3(rotation[k, 2, 0], rotation[k, 2, 1], rotation[k, 2, 2], px, py, pz) + translation[k, 2]
            u = _dot3(intrinsics[k, 0, 0], intrinsics[k, 0, 1], intrinsics[k, 0, 2], cam0, cam1, cam2)
            v = _dot3(intrinsics[k, 1, 0], intrinsics[k, 1, 1], intrinsics[k, 1, 2], cam0, cam1, cam2)
            w = _dot3(intrinsics[k, 2, 0], intrinsics[k, 2, 1], intrinsics[k, 2, 2], cam0, cam1, cam2)
            xk, yk = u / w, v / w
            x[t, k], y[t, k] = xk, yk
            candidate[t, k] = ((cam2 > 0) & (xk >= 0.5) & (xk <= width - 0.5) & (yk >= 0.5) & (yk <= height - 0.5)
                               & (c > 0.0))
            for i in range(3):
                wo_local[t, k, i] = _dot3(frame[t, i, 0], frame[t, i, 1], frame[t, i, 2], wx, wy, wz)
            # mirror direction and the light along it (observations.sample_equirect)
            two_c = 2.0 * c
            rx, ry, rz = two_c * nx - wx, two_c * ny - wy, two_c * nz - wz
            theta = math.acos(min(max(ry, -1.0), 1.0))
            # np.mod(atan2, 2 pi) as NumPy computes it: fmod is the identity on [-pi, pi],
            # then the divisor's sign (a negative angle gains 2 pi, -0 becomes +0)
            phi = math.atan2(rx, -rz)
            if phi < 0.0:
                phi += two_pi
            elif phi == 0.0:
                phi = 0.0
            row = theta / np.pi * (env_h - 1)
            col = phi / two_pi * env_w - 0.5
            r0 = min(max(int(math.floor(row)), 0), env_h - 2)
            c0 = int(math.floor(col))
            fr, fc = row - r0, col - c0
            c1 = c0 + 1
            # np.mod(c, W), dividing only at the seam (c0 = -1 or c1 = W), not for every pair
            if c0 < 0 or c0 >= env_w:
                c0 %= env_w
            if c1 < 0 or c1 >= env_w:
                c1 %= env_w
            for ch in range(n_ch):
                top = envmap[r0, c0, ch] * (1.0 - fc) + envmap[r0, c1, ch] * fc
                bottom = envmap[r0 + 1, c0, ch] * (1.0 - fc) + envmap[r0 + 1, c1, ch] * fc
                incoming[t, k, ch] = top * (1.0 - fr) + bottom * fr


def view_geometry(position: np.ndarray, normal: np.ndarray, frame: np.ndarray, centres: np.ndarray,
                  world_to_camera: np.ndarray, intrinsics: np.ndarray, width: int, height: int,
                  envmap: np.ndarray) -> dict[str, np.ndarray]:
    """Geometry of every (texel, view) pair and the light along its mirror direction.

    Parameters
    ----------
    position, normal : ndarray, shape (T, 3)
        World positions and unit shading normals of the texels.
    frame : ndarray, shape (T, 3, 3)
        Rows: tangent, bitangent, normal.
    centres : ndarray, shape (K, 3)
        Camera centres.
    world_to_camera, intrinsics : ndarray, shape (K, 4, 4) and (K, 3, 3)
        OpenCV cameras.
    width, height : int
        Image size (pixels).
    envmap : ndarray, shape (He, We, C)
        Equirectangular map (band-limited light), read bilinearly as
        `freqbrdf.capture.observations.sample_equirect` does.

    Returns
    -------
    dict
        As `freqbrdf.capture.observations.view_geometry`: ``dist`` (T, K),
        ``wo`` (T, K, 3), ``cos_o``, ``x``, ``y`` (T, K) float64, ``candidate``
        (T, K) bool, ``wo_local`` and ``incoming`` (T, K, 3) float32.
    """
    n_tex, n_views = len(position), len(centres)
    out = {
        "dist": np.empty((n_tex, n_views)), "wo": np.empty((n_tex, n_views, 3)), "cos_o": np.empty((n_tex, n_views)),
        "x": np.empty((n_tex, n_views)), "y": np.empty((n_tex, n_views)),
        "candidate": np.empty((n_tex, n_views), dtype=np.bool_),
        "wo_local": np.empty((n_tex, n_views, 3), np.float32),
        "incoming": np.empty((n_tex, n_views, envmap.shape[2]), np.float32),
    }
    f64 = [np.ascontiguousarray(a, dtype=np.float64) for a in (position, normal, frame, centres)]
    _view_geometry(*f64, np.ascontiguousarray(world_to_camera[:, :3, :3], dtype=np.float64),
                   np.ascontiguousarray(world_to_camera[:, :3, 3], dtype=np.float64),
                   np.ascontiguousarray(intrinsics, dtype=np.float64), int(width), int(height), _floats(envmap),
                   out["dist"], out["wo"], out["cos_o"], out["x"], out["y"], out["candidate"], out["wo_local"],
                   out["incoming"])
    return out


@numba.njit(parallel=True, cache=True, error_model="numpy")
def _pair_observations(ti, ki, position, normal, centres, wo, x, y, dist, cos_o, focal, images, coverage, distances,
                       min_coverage, ray_offset, footprint_slack, radiance, weight, usable, finite, origins, directions,
                       lengths):  # pragma: no cover - compiled
    h, w = coverage.shape[1], coverage.shape[2]
    n_ch = images.shape[3]
    for i in numba.prange(ti.shape[0]):
        t, k = ti[i], ki[i]
        # the four pixels of the bilinear read (observations.bilinear_views)
        fx, fy = x[t, k] - 0.5, y[t, k] - 0.5
        x0 = min(max(int(math.floor(fx)), 0), w - 2)
        y0 = min(max(int(math.floor(fy)), 0), h - 2)
        tx, ty = fx - x0, fy - y0
        c00, c01, c10, c11 = coverage[k, y0, x0], coverage[k, y0, x0 + 1], coverage[k, y0 + 1, x0], coverage[k, y0 + 1, x0 + 1]
        c00 = c00 if math.isfinite(c00) else 0.0
        c01 = c01 if math.isfinite(c01) else 0.0
        c10 = c10 if math.isfinite(c10) else 0.0
        c11 = c11 if math.isfinite(c11) else 0.0
        ok = (c00 * (1 - tx) + c01 * tx) * (1 - ty) + (c10 * (1 - tx) + c11 * tx) * ty >= min_coverage
        if ok and distances.shape[0] > 0:  # every footprint pixel sees the texel's own surface
            d = dist[t, k]
            slack = ray_offset + footprint_slack * (d / focal[k]) / max(cos_o[t, k], 0.1)
            ok = (abs(distances[k, y0, x0] - d) <= slack and abs(distances[k, y0, x0 + 1] - d) <= slack
                  and abs(distances[k, y0 + 1, x0] - d) <= slack and abs(distances[k, y0 + 1, x0 + 1] - d) <= slack)
        usable[i] = ok
        all_finite = True
        for ch in range(n_ch):
            v00, v01, v10, v11 = images[k, y0, x0, ch], images[k, y0, x0 + 1, ch], images[k, y0 + 1, x0, ch], images[k, y0 + 1, x0 + 1, ch]
            all_finite = all_finite and math.isfinite(v00) and math.isfinite(v01) and math.isfinite(v10) and math.isfinite(v11)
        finite[i] = all_finite
        if ok and all_finite:
            for ch in range(n_ch):
                v00, v01, v10, v11 = images[k, y0, x0, ch], images[k, y0, x0 + 1, ch], images[k, y0 + 1, x0, ch], images[k, y0 + 1, x0 + 1, ch]
                radiance[t, k, ch] = (v00 * (1 - tx) + v01 * tx) * (1 - ty) + (v10 * (1 - tx) + v11 * tx) * ty
            weight[t, k] = cos_o[t, k]
        # the visibility ray toward the camera, from just off the surface
        length2 = 0.0
        for c in range(3):
            o = position[t, c] + ray_offset * normal[t, c]
            origins[i, c] = o
            directions[i, c] = wo[t, k, c]
            length2 += (centres[k, c] - o) * (centres[k, c] - o)
        lengths[i] = math.sqrt(length2)


def pair_observations(ti: np.ndarray, ki: np.ndarray, position: np.ndarray, normal: np.ndarray, centres: np.ndarray,
                      focal: np.ndarray, geometry: dict[str, np.ndarray], images: np.ndarray, coverage: np.ndarray,
                      distances: np.ndarray | None, min_coverage: float, ray_offset: float, footprint_slack: float
                      ) -> dict[str, np.ndarray]:
    """What the views show of P candidate (texel, view) pairs, and their visibility rays.

    Parameters
    ----------
    ti, ki : ndarray, shape (P,), int
        Texel and view of each pair (each pair once).
    position, normal : ndarray, shape (T, 3)
        The texels' points and normals.
    centres : ndarray, shape (K, 3)
        Camera centres.
    focal : ndarray, shape (K,)
        Focal length of each view, in pixels.
    geometry : dict
        ``wo`` (T, K, 3), ``x``, ``y``, ``dist``, ``cos_o`` (T, K) of `view_geometry`.
    images, coverage : ndarray, shape (K, H, W, C) and (K, H, W)
    distances : ndarray, shape (K, H, W), or None
        Pixel-centre distances, NaN near edges; None skips the footprint test.
    min_coverage, ray_offset, footprint_slack : float
        As in `freqbrdf.capture.observations.observe`.

    Returns
    -------
    dict
        As `freqbrdf.capture.observations.pair_observations`.
    """
    n_tex, n_views = geometry["x"].shape
    n, n_ch = len(ti), images.shape[3]
    out = {
        "radiance": np.zeros((n_tex, n_views, n_ch), np.float32), "weight": np.zeros((n_tex, n_views), np.float32),
        "usable": np.empty(n, np.bool_), "finite": np.empty(n, np.bool_),
        "origins": np.empty((n, 3)), "directions": np.empty((n, 3)), "lengths": np.empty(n),
    }
    distances = np.empty((0, 1, 1), np.float32) if distances is None else distances
    _pair_observations(np.ascontiguousarray(ti, np.int64), np.ascontiguousarray(ki, np.int64),
                       *(np.ascontiguousarray(a, np.float64) for a in (position, normal, centres, geometry["wo"],
                                                                        geometry["x"], geometry["y"], geometry["dist"],
                                                                        geometry["cos_o"], focal)),
                       *(_floats(a) for a in (images, coverage, distances)),
                       float(min_coverage), float(ray_offset), float(footprint_slack),
                       *(out[name] for name in ("radiance", "weight", "usable", "finite", "origins", "directions",
                                                "lengths")))
    return out


@numba.njit(parallel=True, cache=True, error_model="numpy")
def _edge_free_distances(distances, jump, out):  # pragma: no cover - compiled
    n_views, h, w = distances.shape
    for row in numba.prange(n_views * h):
        k, i = row // h, row % h
        for j in range(w):
            d = np.float64(distances[k, i, j])
            edge = not math.isfinite(d)
            ii = max(i - 1, 0)  # the border repeats itself
            while not edge and ii <= min(i + 1, h - 1):
                for jj in range(max(j - 1, 0), min(j + 1, w - 1) + 1):
                    neighbour = np.float64(distances[k, ii, jj])
                    edge = edge or not math.isfinite(neighbour) or abs(neighbour - d) > jump
                ii += 1
            out[k, i, j] = np.nan if edge else distances[k, i, j]


def edge_free_distances(distances: np.ndarray, jump: float) -> np.ndarray:
    """``distances`` (K, H, W) with NaN within one pixel of a depth step above ``jump`` or of a
    non-finite value, float32 (as `freqbrdf.capture.observations.edge_free_distances`)."""
    out = np.empty(np.shape(distances), np.float32)
    _edge_free_distances(_floats(distances), float(jump), out)
    return out

@numba.njit(cache=True, error_model="numpy", fastmath=False)
def _nearest_faces(uv, faces, R, dilate, best_face, best_bary, best_dist):  # pragma: no cover - compiled
    bary = np.empty(3)
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        ax, ay, bx, by, cx, cy = uv[a, 0], uv[a, 1], uv[b, 0], uv[b, 1], uv[c, 0], uv[c, 1]
        x_lo = int(min(max(math.floor(min(ax, bx, cx) - dilate), 0), R - 1))
        y_lo = int(min(max(math.floor(min(ay, by, cy) - dilate), 0), R - 1))
        x_hi = int(min(max(math.ceil(max(ax, bx, cx) + dilate), 0), R - 1))
        y_hi = int(min(max(math.ceil(max(ay, by, cy) + dilate), 0), R - 1))
        v0x, v0y, v1x, v1y = bx - ax, by - ay, cx - ax, cy - ay
        den = v0x * v1y - v1x * v0y
        degenerate = not abs(den) > 1e-20
        safe = 1.0 if degenerate else den
        for py in range(y_lo, y_hi + 1):
            for px in range(x_lo, x_hi + 1):
                # observations._closest_on_triangle, operation by operation
                v2x, v2y = px - ax, py - ay
                l1 = (v2x * v1y - v1x * v2y) / safe
                l2 = (v0x * v2y - v2x * v0y) / safe
                bary[0], bary[1], bary[2] = 1.0 - l1 - l2, l1, l2
                if not degenerate and bary[0] >= -1e-9 and l1 >= -1e-9 and l2 >= -1e-9:
                    dist = 0.0
                else:
                    dist = np.inf
                    for i in range(3):
                        j = (i + 1) % 3
                        sx, sy = uv[faces[f, i], 0], uv[faces[f, i], 1]
                        ex, ey = uv[faces[f, j], 0] - sx, uv[faces[f, j], 1] - sy
                        t = ((px - sx) * ex + (py - sy) * ey) / max(ex * ex + ey * ey, 1e-30)
                        t = min(max(t, 0.0), 1.0)
                        qx, qy = sx + t * ex - px, sy + t * ey - py
                        d = math.sqrt(qx * qx + qy * qy)
                        if d < dist:
                            dist = d
                            bary[:] = 0.0
                            bary[i], bary[j] = 1.0 - t, t
                flat = py * R + px
                if dist <= dilate and dist < best_dist[flat]:  # ties: the lowest face index
                    best_dist[flat] = dist
                    best_face[flat] = f
                    best_bary[flat] = bary


def nearest_faces(uv: np.ndarray, faces: np.ndarray, R: int, dilate: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest UV triangle of every texel centre of an R x R atlas within ``dilate`` texels.

    Parameters
    ----------
    uv : ndarray, shape (V, 2)
        Vertex uvs in texel-index coordinates (texel (i, j) centre at x = j, y = i).
    faces : ndarray, shape (F, 3), int
    R : int
        Atlas size.
    dilate : float
        Largest distance (texels) of a texel centre from its triangle.

    Returns
    -------
    face : ndarray, shape (R*R,), int64
        Nearest face (-1: none within ``dilate``); ties go to the lowest index.
    bary : ndarray, shape (R*R, 3)
        Barycentrics of the nearest point of that face.
    dist : ndarray, shape (R*R,)
        Its distance (0 inside the triangle, inf without a face).
    """
    best_face = np.full(R * R, -1, dtype=np.int64)
    best_bary = np.zeros((R * R, 3))
    best_dist = np.full(R * R, np.inf)
    _nearest_faces(np.ascontiguousarray(uv, dtype=np.float64), np.ascontiguousarray(faces, dtype=np.int64), int(R),
                   float(dilate), best_face, best_bary, best_dist)
    return best_face, best_bary, best_dist
