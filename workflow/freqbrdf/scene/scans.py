"""Scanned shapes: meshes without UVs, given a UV atlas by xatlas.

The npm package (:mod:`freqbrdf.scene.assets`) holds two meshes the project uses,
:data:`SCANS`: the Stanford bunny (2,826 vertices) and Suzanne (7,503), as glTF binaries
whose geometry is Draco-compressed, with positions and normals but no texture coordinates.
:func:`read_scan` decodes one; :func:`unwrap` gives any triangle mesh a UV atlas with
xatlas, the same code that unwraps a user's mesh without usable UVs at import;
:func:`scanned_mesh` makes a scan an object like the procedural ones (centred, radius 1,
its atlas packed for the textures' resolution).
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from freqbrdf.scene.assets import LICENCE, PACKAGE, VERSION, read_member
from freqbrdf.scene.meshes import Mesh, normalise_positions, vertex_normals


@dataclass(frozen=True)
class AtlasSettings:
    """How xatlas packs an atlas: for textures of ``resolution`` texels a side, ``padding``
    texels between charts (config ``textures.resolution``, ``meshes.atlas_padding``)."""

    resolution: int
    padding: int

    @classmethod
    def from_config(cls, config: dict) -> AtlasSettings:
        return cls(int(config["textures"]["resolution"]), int(config["meshes"]["atlas_padding"]))


@dataclass(frozen=True)
class Scan:
    """A scanned mesh of the package: its member and whose terms it comes under."""

    member: str
    credit: str
    licence: str


SCANS = {
    "bunny": Scan("package/models/bunny.glb.js",
                  "the Stanford bunny, Stanford Computer Graphics Laboratory (Stanford 3D Scanning Repository), "
                  f"via the npm package {PACKAGE} {VERSION}",
                  "Stanford 3D Scanning Repository terms (research use with credit; not CC0)"),
    "suzi": Scan("package/models/suzi.glb.js", f"Suzanne, Blender Foundation, via the npm package {PACKAGE} {VERSION}",
                 LICENCE),
}
_GLB_MAGIC = 0x46546C67
_JSON_CHUNK, _BIN_CHUNK = 0x4E4F534A, 0x004E4942


def read_scan(tarball: Path, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Positions and triangles of one scan, as stored.

    Parameters
    ----------
    tarball : Path
        The package's tarball (:func:`freqbrdf.scene.assets.fetch_package`).
    name : str
        A key of :data:`SCANS`.

    Returns
    -------
    positions : ndarray, shape (V, 3), float64
    faces : ndarray, shape (F, 3), int64

    Raises
    ------
    ValueError
        One line: an unknown name, or a member that is not a Draco-compressed glTF binary.
    """
    import DracoPy

    if name not in SCANS:
        raise ValueError(f"scan {name!r} is not one of the package's scans the project uses: {', '.join(SCANS)}")
    member = SCANS[name].member
    source = f"{tarball}:{member}"
    glb = read_member(tarball, member)
    if len(glb) < 20 or struct.unpack_from("<I", glb)[0] != _GLB_MAGIC:
        raise ValueError(f"{source}: not a glTF binary")
    chunks, offset = {}, 12
    while offset + 8 <= len(glb):
        length, kind = struct.unpack_from("<II", glb, offset)
        chunks[kind] = glb[offset + 8:offset + 8 + length]
        offset += 8 + length
    try:
        gltf = json.loads(chunks[_JSON_CHUNK])
        draco = gltf["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]
        view = gltf["bufferViews"][draco["bufferView"]]
        start = view.get("byteOffset", 0)
        decoded = DracoPy.decode(chunks[_BIN_CHUNK][start:start + view["byteLength"]])
    except (KeyError, IndexError, ValueError, TypeError) as exc:
        raise ValueError(f"{source}: not a Draco-compressed triangle mesh ({type(exc).__name__}: {exc})") from None
    return np.asarray(decoded.points, np.float64), np.asarray(decoded.faces, np.int64)


def unwrap(positions: np.ndarray, faces: np.ndarray, atlas: AtlasSettings, normals: np.ndarray | None = None) -> Mesh:
    """A triangle mesh with a UV atlas computed by xatlas (charts never overlap).

    Parameters
    ----------
    positions : ndarray, shape (V, 3)
    faces : ndarray, shape (F, 3), int
        Counter-clockwise seen from outside.
    atlas : AtlasSettings
        The textures' resolution and the texels between charts (xatlas' ``padding``,
        in its own atlas' texels).
    normals : ndarray, shape (V, 3), optional
        Unit shading normals to keep; by default smooth normals from the faces.

    Returns
    -------
    Mesh
        Vertices (and normals) duplicated along chart borders.
    """
    import xatlas

    packer = xatlas.Atlas()
    packer.add_mesh(np.ascontiguousarray(positions, np.float32), np.ascontiguousarray(faces, np.uint32))
    pack = xatlas.PackOptions()
    pack.resolution = atlas.resolution
    pack.padding = atlas.padding
    pack.bilinear = True
    packer.generate(pack_options=pack)
    vertex_map, atlas_faces, uvs = packer[0]
    # xatlas works in float32: take the positions from the input so duplicates along chart
    # borders stay bitwise identical to the vertex they copy.
    vertices = np.asarray(positions, np.float64)[vertex_map]
    normals = vertex_normals(vertices, atlas_faces) if normals is None else np.asarray(normals, np.float64)[vertex_map]
    return Mesh(vertices=vertices, normals=normals, uvs=np.clip(uvs, 0.0, 1.0), faces=atlas_faces)


def scanned_mesh(tarball: Path, name: str, atlas: AtlasSettings) -> Mesh:
    """One of :data:`SCANS` as an object: centred on its bounding box, radius 1, with a UV atlas."""
    positions, faces = read_scan(tarball, name)
    centre = 0.5 * (positions.min(axis=0) + positions.max(axis=0))
    positions = normalise_positions(positions, centre)
    a, b, c = (positions[faces[:, k]] for k in range(3))
    if np.einsum("ij,ij->", a, np.cross(b, c)) < 0:  # enclosed volume negative: clockwise triangles
        faces = faces[:, ::-1]
    return unwrap(positions, faces, atlas)


def overlapping_texels(uvs: np.ndarray, faces: np.ndarray, resolution: int) -> tuple[int, int]:
    """Texel centres that more than one UV triangle covers, and those any covers.

    Parameters
    ----------
    uvs : ndarray, shape (V, 2)
        In [0, 1].
    faces : ndarray, shape (F, 3), int
    resolution : int
        Texels a side.

    Returns
    -------
    twice, covered : int
        Centres strictly inside two or more triangles; inside at least one.
    """
    corners = np.asarray(uvs, np.float64)[np.asarray(faces)] * resolution - 0.5  # (F, 3, 2), texel centres at integers
    lo = np.clip(np.ceil(corners.min(axis=1)), 0, resolution - 1).astype(np.int64)
    hi = np.clip(np.floor(corners.max(axis=1)), 0, resolution - 1).astype(np.int64)
    size = np.maximum(hi - lo + 1, 0)
    counts = size[:, 0] * size[:, 1]
    owner = np.repeat(np.arange(len(corners)), counts)
    local = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    x = lo[owner, 0] + local % np.maximum(size[owner, 0], 1)
    y = lo[owner, 1] + local // np.maximum(size[owner, 0], 1)
    a, b, c = corners[owner, 0], corners[owner, 1], corners[owner, 2]
    point = np.stack([x, y], axis=1).astype(np.float64)

    def edge(p, q):  # twice the signed area of (p, q, point)
        return (q[:, 0] - p[:, 0]) * (point[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (point[:, 0] - p[:, 0])

    e0, e1, e2 = edge(b, c), edge(c, a), edge(a, b)
    eps = 1e-9
    inside = ((e0 > eps) & (e1 > eps) & (e2 > eps)) | ((e0 < -eps) & (e1 < -eps) & (e2 < -eps))
    hits = np.bincount(y[inside] * resolution + x[inside], minlength=resolution * resolution)
    return int((hits > 1).sum()), int((hits > 0).sum())
