"""Meshes made outside the project (PLY or OBJ, any common layout) read into a :class:`Mesh`.

:func:`freqbrdf.scene.ply.read_ply` reads back only the exact layout the pipeline
writes; :func:`read_mesh` is the door for a user's file. PLY goes through
``plyfile`` and OBJ through ``trimesh``; either way the result is cleaned the
same way (:func:`clean_mesh`): polygons fanned into triangles, unused vertices
dropped, normals recomputed where the file has none or non-finite ones, a UV
atlas computed by xatlas where the file's UVs are missing or unusable (with a
warning), and every problem reported in one line naming the file.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

from freqbrdf.scene.meshes import Mesh, vertex_normals
from freqbrdf.scene.scans import AtlasSettings, overlapping_texels, unwrap

# Texture-coordinate property names found in the wild: the pipeline and
# MeshLab (u v), Blender's PLY exporter (s t), and VCG / Open3D (texture_u texture_v).
UV_NAMES: tuple[tuple[str, str], ...] = (("u", "v"), ("s", "t"), ("texture_u", "texture_v"))
MESH_SUFFIXES = (".ply", ".obj")


def triangulate(polygons: list[np.ndarray] | np.ndarray) -> np.ndarray:
    """Fan-triangulate polygons given as vertex-index sequences.

    Parameters
    ----------
    polygons : sequence of int arrays (n_i >= 3,) or ndarray (F, n)

    Returns
    -------
    ndarray, shape (F', 3), int64
        Triangles ``(p0, p_i, p_i+1)`` of every polygon, in polygon order.

    Raises
    ------
    ValueError
        If a polygon has fewer than three corners.
    """
    triangles = []
    for polygon in polygons:
        polygon = np.asarray(polygon, dtype=np.int64)
        if len(polygon) < 3:
            raise ValueError(f"a face has {len(polygon)} corners (need at least 3)")
        fan = np.arange(1, len(polygon) - 1)
        triangles.append(np.stack([np.full(len(fan), polygon[0]), polygon[fan], polygon[fan + 1]], axis=1))
    return np.concatenate(triangles) if triangles else np.zeros((0, 3), np.int64)


def clean_mesh(vertices: np.ndarray, faces: np.ndarray, uvs: np.ndarray | None, normals: np.ndarray | None,
               source: str | os.PathLike, atlas: AtlasSettings | None = None,
               log: logging.Logger | None = None) -> Mesh:
    """A :class:`Mesh` from raw arrays: unused vertices dropped, missing normals recomputed,
    and, given ``atlas``, a UV atlas computed where the file's UVs are unusable.

    Parameters
    ----------
    vertices : ndarray, shape (V, 3)
    faces : ndarray, shape (F, 3), int
    uvs : ndarray, shape (V, 2), or None
        Texture coordinates in [0, 1]; None means the file has none.
    normals : ndarray, shape (V, 3), or None
        Shading normals; rows that are non-finite or zero (and all of them when
        None) are replaced by area-weighted face normals.
    source : path-like
        The user's file, named in every error.
    atlas : AtlasSettings, optional
        Where UVs are missing, non-finite, outside [0, 1] or overlapping (more than
        1% of the texels they cover at ``atlas.resolution``), unwrap the mesh with
        xatlas (:func:`freqbrdf.scene.scans.unwrap`) and say so in ``log``, instead of
        refusing it. Without it overlaps are not checked.
    log : logging.Logger, optional

    Returns
    -------
    Mesh

    Raises
    ------
    ValueError
        One line naming ``source``: no faces, indices out of range, non-finite
        positions, vertices whose normal cannot be recomputed, or (without
        ``atlas``) unusable UVs.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(faces) == 0:
        raise ValueError(f"{source}: mesh has no faces")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise ValueError(f"{source}: face index out of range (mesh has {len(vertices)} vertices)")
    used = np.zeros(len(vertices), dtype=bool)
    used[faces.ravel()] = True
    remap = np.cumsum(used) - 1
    faces = remap[faces]
    vertices = vertices[used]
    uvs = None if uvs is None else np.asarray(uvs, dtype=np.float64)[used]
    if not np.isfinite(vertices).all():
        raise ValueError(f"{source}: {int((~np.isfinite(vertices)).any(axis=1).sum())} used vertices have non-finite positions")
    problem = uv_problem(uvs, faces, None if atlas is None else atlas.resolution)
    if problem and atlas is None:
        raise ValueError(f"{source}: {problem}; the SVBRDF textures need a UV atlas in [0, 1] "
                         "(tiled or UDIM layouts are not supported)")
    given = np.full((len(vertices), 3), np.nan) if normals is None else np.asarray(normals, dtype=np.float64)[used]
    length = np.linalg.norm(given, axis=1)
    bad = ~np.isfinite(length) | (length <= 1e-12)
    if bad.any():
        try:
            computed = vertex_normals(vertices, faces)
        except ValueError as exc:
            raise ValueError(f"{source}: cannot recompute normals ({exc})") from None
        given = np.where(bad[:, None], computed, given)
        length = np.where(bad, 1.0, length)
    if problem:
        (log or logging.getLogger(__name__)).warning(
            "%s: %s: unwrapped with xatlas (%d texels, padding %d)", source, problem, atlas.resolution, atlas.padding)
        return unwrap(vertices, faces, atlas, normals=given / length[:, None])
    # uv_problem allows a little slack for exporters that write 1.0000001; the atlas is the unit square.
    return Mesh(vertices=vertices, normals=given / length[:, None], uvs=np.clip(uvs, 0.0, 1.0), faces=faces)


def uv_problem(uvs: np.ndarray | None, faces: np.ndarray, resolution: int | None) -> str:
    """Why a mesh's UVs cannot serve as its atlas ('' when they can).

    Parameters
    ----------
    uvs : ndarray, shape (V, 2), or None
    faces : ndarray, shape (F, 3), int
    resolution : int, optional
        Texels a side at which overlaps are counted (None: not checked).
    """
    if uvs is None:
        return "mesh has no texture coordinates (UVs)"
    if not np.isfinite(uvs).all():
        return f"{int((~np.isfinite(uvs)).any(axis=1).sum())} used vertices have non-finite UVs"
    if uvs.min() < -1e-4 or uvs.max() > 1.0 + 1e-4:
        return f"UVs span [{uvs.min():.3g}, {uvs.max():.3g}], outside the atlas [0, 1]"
    if resolution is not None:
        twice, covered = overlapping_texels(np.clip(uvs, 0.0, 1.0), faces, resolution)
        if twice > 0.01 * max(covered, 1):
            return f"UV charts overlap on {twice} of the {covered} texels they cover"
    return ""


def _ply_arrays(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Positions, triangles, uvs and normals of a PLY file (any property types)."""
    from plyfile import PlyData

    try:
        ply = PlyData.read(str(path))
        vertex = ply["vertex"].data
        face = ply["face"].data
    except KeyError as exc:
        raise ValueError(f"{path}: PLY file has no {exc.args[0]!r} element") from None
    except Exception as exc:  # plyfile raises PlyParseError, ValueError or struct errors
        raise ValueError(f"{path}: not a readable PLY file ({exc})") from None
    names = vertex.dtype.names
    if not {"x", "y", "z"} <= set(names):
        raise ValueError(f"{path}: PLY vertices have no x, y, z properties (have {', '.join(names)})")
    positions = np.stack([vertex[c] for c in "xyz"], axis=1)
    uv_names = next((pair for pair in UV_NAMES if set(pair) <= set(names)), None)
    uvs = None if uv_names is None else np.stack([vertex[c] for c in uv_names], axis=1)
    normals = np.stack([vertex[c] for c in ("nx", "ny", "nz")], axis=1) if {"nx", "ny", "nz"} <= set(names) else None
    index_name = next((n for n in ("vertex_indices", "vertex_index") if n in face.dtype.names), None)
    if index_name is None:
        raise ValueError(f"{path}: PLY faces have no vertex_indices property (have {', '.join(face.dtype.names)})")
    try:
        triangles = triangulate(list(face[index_name]))
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    return positions, triangles, uvs, normals


def _obj_arrays(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Positions, triangles, uvs and normals of an OBJ file, every group merged.

    trimesh splits a position used with several ``vt`` (a UV seam) into one
    vertex per pair, which is the per-vertex layout :class:`Mesh` needs.
    """
    from trimesh.exchange.obj import load_obj

    try:
        with open(path, "rb") as handle:
            loaded = load_obj(handle, skip_materials=True, group_material=False)
    except Exception as exc:
        raise ValueError(f"{path}: not a readable OBJ file ({exc})") from None
    parts = list(loaded.get("geometry", {}).values()) if "geometry" in loaded else [loaded]
    parts = [p for p in parts if len(p.get("faces", [])) and len(p.get("vertices", []))]
    if not parts:
        raise ValueError(f"{path}: OBJ file has no faces")
    positions, triangles, uvs, normals, offset = [], [], [], [], 0
    for part in parts:
        vertices = np.asarray(part["vertices"], dtype=np.float64)
        try:
            triangles.append(triangulate(list(np.asarray(part["faces"]))) + offset)
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None
        uv = getattr(part.get("visual"), "uv", None)
        uvs.append(None if uv is None else np.asarray(uv, dtype=np.float64))
        n = part.get("vertex_normals")
        normals.append(np.full((len(vertices), 3), np.nan) if n is None else np.asarray(n, dtype=np.float64))
        positions.append(vertices)
        offset += len(vertices)
    uv_all = None if any(u is None for u in uvs) else np.concatenate(uvs)
    return np.concatenate(positions), np.concatenate(triangles), uv_all, np.concatenate(normals)


def read_mesh(path: str | os.PathLike, atlas: AtlasSettings | None = None,
              log: logging.Logger | None = None) -> Mesh:
    """Read a user's PLY or OBJ mesh into a clean :class:`Mesh`.

    Parameters
    ----------
    path : path-like
        ``.ply`` (ASCII or binary, any property types; uv names ``u v``,
        ``s t`` or ``texture_u texture_v``) or ``.obj`` (``v``/``vt``/``vn``,
        polygons of any size, several groups).
    atlas, log
        See :func:`clean_mesh`: given ``atlas``, unusable UVs are replaced by xatlas'.

    Returns
    -------
    Mesh
        Positions in the file's units and axes; see :func:`clean_mesh`.

    Raises
    ------
    FileNotFoundError, ValueError
        One line naming ``path``.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: mesh file not found")
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise ValueError(f"{path}: unsupported mesh format {suffix!r} (use {' or '.join(MESH_SUFFIXES)})")
    vertices, faces, uvs, normals = (_ply_arrays if suffix == ".ply" else _obj_arrays)(path)
    return clean_mesh(vertices, faces, uvs, normals, path, atlas, log)
