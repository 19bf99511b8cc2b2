"""Ray casting against an object's mesh with Mitsuba: visibility and per-pixel distances.

Like :mod:`freqbrdf.scene.render`, every function takes the ``mitsuba`` module as
its first argument, so importing this module has no side effect.
"""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import numpy as np


def mesh_scene(mi: ModuleType, mesh: str | Path):
    """A scene holding only the mesh, for ray casting (visibility, hit points)."""
    return mi.load_dict({"type": "scene", "object": {"type": "ply", "filename": str(mesh)}})


def occlusion_test(
    mi: ModuleType, scene, origins: np.ndarray, directions: np.ndarray, distances: np.ndarray, chunk: int = 1 << 20
) -> np.ndarray:
    """Whether the segments ``origins + t * directions``, ``0 < t < distances``, hit the scene.

    Parameters
    ----------
    scene : mitsuba.Scene
        E.g. :func:`mesh_scene`.
    origins, directions : ndarray, shape (P, 3)
        Ray origins and unit directions (world).
    distances : ndarray, shape (P,)
        Segment lengths.
    chunk : int
        Rays traced per batch (bounds memory).

    Returns
    -------
    ndarray, shape (P,), bool
        True where something blocks the segment.
    """
    out = np.zeros(len(origins), dtype=bool)
    for s in range(0, len(origins), chunk):
        o = np.ascontiguousarray(origins[s : s + chunk], dtype=np.float32)
        d = np.ascontiguousarray(directions[s : s + chunk], dtype=np.float32)
        ray = mi.Ray3f(mi.Point3f(o[:, 0], o[:, 1], o[:, 2]), mi.Vector3f(d[:, 0], d[:, 1], d[:, 2]))
        ray.maxt = mi.Float(np.ascontiguousarray(distances[s : s + chunk], dtype=np.float32))
        out[s : s + chunk] = np.array(scene.ray_test(ray), dtype=bool)
    return out


def distance_maps(
    mi: ModuleType, scene, K: np.ndarray, world_to_camera: np.ndarray, width: int, height: int, chunk: int = 1 << 21
) -> np.ndarray:
    """Distance from each camera to the first surface seen through each pixel centre.

    Parameters
    ----------
    scene : mitsuba.Scene
        E.g. :func:`mesh_scene`.
    K : ndarray, shape (N, 3, 3)
    world_to_camera : ndarray, shape (N, 4, 4)
        OpenCV cameras.
    width, height : int
        Image size.
    chunk : int
        Rays traced per batch (bounds memory); whole views are batched together,
        since one large ray cast costs far less than many small ones.

    Returns
    -------
    ndarray, shape (N, height, width), float32
        Euclidean distance along the pixel-centre ray; ``inf`` where it misses.
    """
    jj, ii = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    pixels = np.stack([jj.ravel(), ii.ravel(), np.ones(jj.size)], axis=1)
    n_pix = len(pixels)
    out = np.empty((len(K), height, width), np.float32)
    per_batch = max(1, chunk // n_pix)
    for start in range(0, len(K), per_batch):
        views = range(start, min(start + per_batch, len(K)))
        # component-major (Dr.Jit takes one contiguous array per coordinate)
        o = np.empty((3, len(views) * n_pix), np.float32)
        d = np.empty((3, len(views) * n_pix), np.float32)
        for i, k in enumerate(views):
            R, t = world_to_camera[k, :3, :3], world_to_camera[k, :3, 3]
            rays = pixels @ np.linalg.inv(K[k]).T @ R  # camera rays rotated to world: R^T d
            # |rays| summed as np.linalg.norm does, without its slow reduction over 3-vectors
            length = np.sqrt(np.square(rays[:, 0]) + np.square(rays[:, 1]) + np.square(rays[:, 2]))
            for c in range(3):
                np.divide(rays[:, c], length, out=d[c, i * n_pix : (i + 1) * n_pix], casting="same_kind")
            o[:, i * n_pix : (i + 1) * n_pix] = (-R.T @ t)[:, None]
        ray = mi.Ray3f(mi.Point3f(o[0], o[1], o[2]), mi.Vector3f(d[0], d[1], d[2]))
        hit = np.array(scene.ray_intersect_preliminary(ray).t, dtype=np.float32)
        out[views.start : views.stop] = hit.reshape(len(views), height, width)
    return out
