"""Binary PLY files of a :class:`freqbrdf.scene.meshes.Mesh`, in the one layout the pipeline writes.

PLY files written by :func:`write_ply` store float32 attributes, so a round trip
through a file rounds positions, normals and uvs to float32.

The layout of any other PLY file is read by :mod:`freqbrdf.capture.mesh_io`.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from freqbrdf.scene.meshes import Mesh
from freqbrdf.util.io import atomic_path

_PLY_PROPS = ("x", "y", "z", "nx", "ny", "nz", "u", "v")
_PLY_FACE_DTYPE = np.dtype([("count", "u1"), ("index", "<i4", (3,))])
_PLY_VERTEX_BYTES = 4 * len(_PLY_PROPS)


def _ply_header(n_vertices: int, n_faces: int) -> bytes:
    lines = ["ply", "format binary_little_endian 1.0", f"element vertex {n_vertices}"]
    lines += [f"property float {p}" for p in _PLY_PROPS]
    lines += [f"element face {n_faces}", "property list uchar int vertex_indices", "end_header"]
    return ("\n".join(lines) + "\n").encode("ascii")


def write_ply(path: str | os.PathLike[str], mesh: Mesh) -> None:
    """Write a mesh as a binary little-endian PLY file, atomically.

    Vertex properties are ``float x y z nx ny nz u v`` (float32, so values are
    rounded to single precision); faces are ``list uchar int vertex_indices``.
    The data go to a temporary file in the destination directory which is then
    renamed over ``path``, so readers never see a partial file.  The file gets
    mode 0o644.

    Parameters
    ----------
    path : str or os.PathLike
        Destination file; its directory must exist.
    mesh : Mesh
        Mesh to store (V vertices, F triangles).
    """
    path = Path(path)
    vertex_data = np.concatenate([mesh.vertices, mesh.normals, mesh.uvs], axis=1).astype("<f4")
    face_data = np.empty(len(mesh.faces), dtype=_PLY_FACE_DTYPE)
    face_data["count"] = 3
    face_data["index"] = mesh.faces
    with atomic_path(path) as tmp, open(tmp, "wb") as handle:
        handle.write(_ply_header(len(mesh.vertices), len(mesh.faces)))
        handle.write(vertex_data.tobytes())
        handle.write(face_data.tobytes())


def read_ply(path: str | os.PathLike[str]) -> Mesh:
    """Read a PLY file in exactly the layout produced by :func:`write_ply`.

    Parameters
    ----------
    path : str or os.PathLike
        File to read.

    Returns
    -------
    Mesh
        Mesh with float32 values widened to float64 (normals are not
        renormalised, so a write/read round trip is exact at float32 precision).

    Raises
    ------
    ValueError
        One line naming ``path`` if the file is missing, unreadable, truncated,
        has trailing data, or is not in that exact PLY layout.
    """
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise ValueError(f"{path}: cannot read PLY file ({exc.strerror or exc})") from None
    marker = b"end_header\n"
    end = data.find(marker, 0, 4096)
    if end < 0:
        raise ValueError(f"{path}: not a PLY file written by write_ply (no end_header)")
    header_end = end + len(marker)
    try:
        header = data[:header_end].decode("ascii")
    except UnicodeDecodeError:
        raise ValueError(f"{path}: PLY header is not ASCII") from None
    counts = re.fullmatch(r"ply\nformat binary_little_endian 1\.0\nelement vertex (\d+)\n"
                          r"(?:.*\n)*?element face (\d+)\n(?:.*\n)*", header)
    if counts is None:
        raise ValueError(f"{path}: not a binary_little_endian PLY file written by write_ply")
    n_vert, n_face = int(counts.group(1)), int(counts.group(2))
    if header != _ply_header(n_vert, n_face).decode("ascii"):
        raise ValueError(f"{path}: PLY header does not match the layout written by write_ply")
    expected = header_end + n_vert * _PLY_VERTEX_BYTES + n_face * _PLY_FACE_DTYPE.itemsize
    if len(data) != expected:
        kind = "truncated" if len(data) < expected else "has trailing data"
        raise ValueError(f"{path}: PLY file {kind} ({len(data)} bytes, expected {expected})")
    vertex_data = np.frombuffer(data, dtype="<f4", count=n_vert * len(_PLY_PROPS),
                                offset=header_end).reshape(n_vert, len(_PLY_PROPS))
    face_data = np.frombuffer(data, dtype=_PLY_FACE_DTYPE, count=n_face,
                              offset=header_end + n_vert * _PLY_VERTEX_BYTES)
    if np.any(face_data["count"] != 3):
        raise ValueError(f"{path}: PLY file contains non-triangle faces")
    faces = face_data["index"]
    if faces.size and (faces.min() < 0 or faces.max() >= n_vert):
        raise ValueError(f"{path}: PLY face index out of range")
    if not np.all(np.isfinite(vertex_data)):
        raise ValueError(f"{path}: PLY vertex data contain non-finite values")
    vertex_data = vertex_data.astype(np.float64)
    return Mesh(vertices=vertex_data[:, 0:3], normals=vertex_data[:, 3:6],
                uvs=vertex_data[:, 6:8], faces=faces)
