"""Procedural test objects: triangle meshes with UV atlases (stored as PLY by :mod:`freqbrdf.scene.ply`).

Six objects are available (see :data:`OBJECTS`): ``sphere``, ``torus``, ``die``,
``vase``, ``knot`` and ``dented``.  Every mesh returned by :func:`make_mesh` satisfies:

* **Frame.** World Y is up.  Azimuth ``phi`` on surfaces of revolution is a
  right-handed rotation about +Y starting at +X, i.e. ``x = cos(phi)``,
  ``z = -sin(phi)``.
* **Normalisation.** Positions are translated so that the centre of the bounding
  sphere is at the origin, then scaled so that ``max |vertex| == 1`` (to a few
  ulp).  The centre is exact by symmetry for sphere, torus, die, knot and dented (the
  origin of their construction is the only point fixed by their symmetry group;
  for the knot this holds up to tessellation, to well below 1e-3) and
  for the vase it is the exact minimiser along the rotation axis.  This is *not*
  the AABB centre.
* **Orientation.** Triangles are counter-clockwise seen from outside, so the
  geometric normal ``(v1 - v0) x (v2 - v0)`` points outward and the enclosed
  volume from the divergence theorem is positive.
* **Topology.** After welding coincident positions every surface is closed and
  2-manifold (genus 0 for sphere, die, vase and dented; genus 1 for torus and knot).
  Vertices are duplicated along UV seams and chart borders; duplicates are
  bitwise identical in position and normal.  Zero-area triangles (at poles) are
  removed.
* **Normals.** Smooth, unit, outward vertex normals: area-weighted averages of
  the face normals of all triangles touching a *position* (so they are welded
  across UV seams and chart borders).
* **UVs.** All in ``[0, 1]``; charts never overlap.  Atlases with several charts
  (die, knot) leave gutters of ``_GUTTER`` (3 % of the atlas width) between
  charts and around the border so bilinear lookups (and a few mip levels) never
  mix charts.

UV / texture convention
-----------------------
A texture array ``tex[i, j]`` of shape ``(H, W)`` covers ``uv`` in ``[0, 1]^2``;
the centre of texel row ``i``, column ``j`` sits at
``uv = ((j + 0.5) / W, (i + 0.5) / H)``.  Hence ``u`` selects the column, ``v``
the row, and **row 0 is at v near 0** (no vertical flip).  tests/test_meshes.py
checks this against Mitsuba 3 (3.9.1, ``llvm_ad_rgb``): the ``ply`` plugin keeps
``u``/``v`` unchanged, and a ``bitmap`` texture built from ``mi.Bitmap(tex)``
(``filter_type="nearest"``, ``raw=True``) returns ``tex[i, j]`` at that uv.  A
bitmap loaded from an image file should behave the same with row 0 = the first
(top) row stored in the file, but that path is not tested here.

The sign of the UV-space area of a triangle (``u`` right, ``v`` up) is the same for
every triangle of an object: negative for sphere, dented and knot, positive for torus,
die and vase.  Negative means a texture shown with row 0 on top appears
unmirrored when the surface is seen from outside.

Objects and their UV layouts (sizes before normalisation):

* ``sphere``: unit latitude-longitude sphere.  ``u = phi / 2pi``,
  ``v = theta / pi`` with ``theta`` the polar angle from +Y (``v = 0`` at the
  north pole).  Seam column duplicated at ``u = 0, 1``.
* ``torus``: major radius ``_TORUS_MAJOR`` = 1, tube radius ``_TORUS_MINOR`` = 0.4,
  in the XZ plane.  ``u = phi / 2pi`` along the major circle, ``v = psi / 2pi``
  around the tube (``psi = 0`` on the outer equator, increasing towards +Y).
  Both seams duplicated.
* ``die``: cube of half-size 1 with edges rounded by 0.15 and 21 pips, i.e.
  dimples of radius 0.18 and depth 0.07 with depth profile
  ``depth * (1 - r^2 / radius^2)^2`` (smooth at the rim, close to spherical at
  the bottom).  Six square charts in a 3 x 2 grid; the chart in column ``k % 3``
  and row ``k // 3`` (row 0 at small v) is the face showing ``k + 1`` pips.
  Faces with 1..6 pips point along +Z, +X, +Y, -Y, -X, -Z; on the four side
  faces ``v`` increases towards +Y.
* ``vase``: closed solid of revolution about +Y, height about 1.63: flat base,
  bulging body, narrow neck, rounded lip, closed by a shallow bowl inside the
  lip.  ``u = phi / 2pi``, ``v`` = normalised arc length along the profile
  (``v = 0`` at the centre of the base, ``v = 1`` at the centre of the top).
* ``knot``: tube of radius 0.18 around the (2, 3) torus knot (trefoil)
  ``((1 + 0.5 cos 3t) cos 2t, 0.5 sin 3t, -(1 + 0.5 cos 3t) sin 2t)``, with a
  rotation-minimising frame whose total twist is spread evenly so the tube
  closes without a seam.  The tube is cut into ``_KNOT_CHARTS`` = 4 pieces of
  equal length; piece ``k`` is a horizontal band (band 0 at small v) with ``u``
  proportional to arc length along the curve and ``v`` around the tube.
* ``dented``: the sphere's grid and UVs, each point's radius lowered by
  ``_DENT_DEPTH`` x exp(-sin^2(b) / ``_DENT_WIDTH``^2), summed over the six dents at
  angle ``b`` from the axes of a cube standing on a corner (none at a pole): concave
  pits that shadow and light themselves, which a convex object never does.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

OBJECTS: tuple[str, ...] = ("sphere", "torus", "die", "vase", "knot", "dented")

# Positions closer than this (relative to the largest coordinate) are one point.
_WELD_REL_TOL = 1e-9
# Gap between charts and around the atlas border, as a fraction of the atlas width.
_GUTTER = 0.03

_TORUS_MAJOR = 1.0
_TORUS_MINOR = 0.4

# Dent depth (radius lost at a dent's centre) and width (sine of its angular radius).
_DENT_DEPTH = 0.3
_DENT_WIDTH = 0.3

# Die dimensions are relative to the half edge length of the cube.
_DIE_ROUNDING = 0.15
_DIE_PIP_OFFSET = 0.5
_DIE_PIP_RADIUS = 0.18
_DIE_PIP_DEPTH = 0.07
# (outward normal, e_s, e_t) with e_s x e_t = normal, listed by pip count 1..6 so
# opposite faces (+Z/-Z, +X/-X, +Y/-Y) carry 1/6, 2/5, 3/4 pips.
_DIE_FACES: tuple[tuple[tuple[float, float, float], ...], ...] = (
    ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    ((1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
    ((0.0, 1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, -1.0)),
    ((0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    ((-1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    ((0.0, 0.0, -1.0), (-1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
)
# Pip centres in face coordinates (s, t), in units of _DIE_PIP_OFFSET.
_DIE_PIPS: tuple[tuple[tuple[int, int], ...], ...] = (
    ((0, 0),),
    ((-1, -1), (1, 1)),
    ((-1, -1), (0, 0), (1, 1)),
    ((-1, -1), (1, -1), (-1, 1), (1, 1)),
    ((-1, -1), (1, -1), (0, 0), (-1, 1), (1, 1)),
    ((-1, -1), (-1, 0), (-1, 1), (1, -1), (1, 0), (1, 1)),
)

# (2, 3) torus knot: centre line ((R + a cos 3t) cos 2t, a sin 3t, -(R + a cos 3t) sin 2t).
_KNOT_MAJOR = 1.0
_KNOT_MINOR = 0.5
# Tube radius relative to the curve scale R + a (the centre line's largest distance
# from the axis).  Strands are >= 0.83 apart and the curvature radius is >= 0.71,
# so a tube of radius 0.18 neither self-intersects nor folds.
_KNOT_TUBE = 0.12
_KNOT_CHARTS = 4


@dataclass(frozen=True, eq=False)
class Mesh:
    """Indexed triangle mesh with per-vertex normals and texture coordinates.

    Attributes
    ----------
    vertices : ndarray, shape (V, 3), float64
        Positions (normalised object units, see module docstring).
    normals : ndarray, shape (V, 3), float64
        Unit outward smooth shading normals.
    uvs : ndarray, shape (V, 2), float64
        Texture coordinates in ``[0, 1]``.
    faces : ndarray, shape (F, 3), int32
        Vertex indices, counter-clockwise seen from outside.

    Arrays are converted to the dtypes above and made read-only.  Instances
    compare by identity (``eq=False``) because element-wise array comparison has
    no single truth value.
    """

    vertices: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray
    faces: np.ndarray

    def __post_init__(self) -> None:
        specs = (("vertices", np.float64, 3), ("normals", np.float64, 3),
                 ("uvs", np.float64, 2), ("faces", np.int32, 3))
        for name, dtype, width in specs:
            arr = np.array(getattr(self, name), dtype=dtype, order="C", copy=True)
            if arr.ndim != 2 or arr.shape[1] != width:
                raise ValueError(f"Mesh.{name} must have shape (N, {width}), got {arr.shape}")
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)
        n_vert = len(self.vertices)
        if len(self.normals) != n_vert or len(self.uvs) != n_vert:
            raise ValueError("Mesh.vertices, normals and uvs must have the same length")
        if self.faces.size and (self.faces.min() < 0 or self.faces.max() >= n_vert):
            raise ValueError("Mesh.faces index out of range")


def make_mesh(name: str, detail: int = 1) -> Mesh:
    """Build one of the procedural test objects.

    Parameters
    ----------
    name : str
        One of :data:`OBJECTS`.
    detail : int, optional
        Tessellation multiplier (>= 1): the number of segments along each
        parametric direction is proportional to ``detail``, so the triangle count
        grows as ``detail**2``.

    Returns
    -------
    Mesh
        Normalised mesh (bounding sphere centred at the origin, radius 1,
        dimensionless units).

    Raises
    ------
    ValueError
        If ``name`` is unknown or ``detail`` is not a positive integer.
    """
    builders: dict[str, Callable[[int], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]] = {
        "sphere": _build_sphere,
        "torus": _build_torus,
        "die": _build_die,
        "vase": _build_vase,
        "knot": _build_knot,
        "dented": _build_dented,
    }
    if name not in builders:
        raise ValueError(f"unknown object {name!r}; valid objects are {', '.join(OBJECTS)}")
    if isinstance(detail, bool) or not isinstance(detail, (int, np.integer)) or detail < 1:
        raise ValueError(f"detail must be a positive integer, got {detail!r}")
    positions, uvs, faces, centre = builders[name](int(detail))
    positions, uvs, faces = _drop_degenerate(positions, uvs, faces)
    positions = normalise_positions(positions, centre)
    normals = vertex_normals(positions, faces)
    return Mesh(vertices=positions, normals=normals, uvs=uvs, faces=faces)


# ----------------------------------------------------------------- shared helpers


def _grid_faces(n_rows: int, n_cols: int, flip: bool = False) -> np.ndarray:
    """Triangulate a (n_rows + 1) x (n_cols + 1) vertex grid stored row-major.

    Unflipped triangles are counter-clockwise seen from the side that
    ``dP/d(row) x dP/d(col)`` points to.
    """
    i, j = np.meshgrid(np.arange(n_rows), np.arange(n_cols), indexing="ij")
    a = (i * (n_cols + 1) + j).ravel()
    b = a + n_cols + 1
    c = b + 1
    d = a + 1
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return faces[:, ::-1].copy() if flip else faces


def _weld_ids(positions: np.ndarray) -> np.ndarray:
    """Group id per vertex; equal ids mean the same position (within _WELD_REL_TOL).

    Rounding can split two points that straddle a rounding boundary, so builders
    make seam duplicates bitwise identical instead of relying on the tolerance.
    """
    scale = float(np.abs(positions).max()) or 1.0
    keys = np.round(positions / (scale * _WELD_REL_TOL)).astype(np.int64)
    _, inverse = np.unique(keys, axis=0, return_inverse=True)
    return inverse.ravel()


def _drop_degenerate(positions: np.ndarray, uvs: np.ndarray,
                     faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Remove triangles with two coincident corners, then unreferenced vertices."""
    ids = _weld_ids(positions)[faces]
    keep = (ids[:, 0] != ids[:, 1]) & (ids[:, 1] != ids[:, 2]) & (ids[:, 2] != ids[:, 0])
    faces = faces[keep]
    used = np.zeros(len(positions), dtype=bool)
    used[faces.ravel()] = True
    remap = np.cumsum(used) - 1
    return positions[used], uvs[used], remap[faces].astype(np.int32)


def normalise_positions(positions: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Translate ``centre`` to the origin and scale so that max |p| == 1."""
    shifted = positions - centre
    return shifted / np.sqrt(np.max(np.einsum("ij,ij->i", shifted, shifted)))


def vertex_normals(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit area-weighted vertex normals, shared by all vertices at one position.

    Parameters
    ----------
    positions : ndarray, shape (V, 3)
    faces : ndarray, shape (F, 3), int

    Returns
    -------
    ndarray, shape (V, 3)

    Raises
    ------
    ValueError
        If a vertex touches no face or its faces' normals cancel.
    """
    ids = _weld_ids(positions)
    p0, p1, p2 = (positions[faces[:, k]] for k in range(3))
    # The unnormalised cross product is twice the area times the unit normal.
    weighted = np.cross(p1 - p0, p2 - p0)
    n_groups = int(ids.max()) + 1
    acc = np.zeros((n_groups, 3))
    for corner in range(3):
        group = ids[faces[:, corner]]
        for axis in range(3):
            acc[:, axis] += np.bincount(group, weights=weighted[:, axis], minlength=n_groups)
    length = np.linalg.norm(acc, axis=1)
    if np.any(length <= 0.0):
        raise ValueError("vertex with no well-defined normal (isolated or cancelling faces)")
    return (acc / length[:, None])[ids]


def _revolve(radius: np.ndarray, height: np.ndarray, v: np.ndarray,
             n_azimuth: int) -> tuple[np.ndarray, np.ndarray]:
    """Surface of revolution about +Y from a profile (radius, height) sampled at v.

    Returns row-major grid positions (profile sample, azimuth) and uvs; the
    azimuth seam column is an exact copy of column 0.
    """
    phi = 2.0 * np.pi * np.arange(n_azimuth) / n_azimuth
    x = radius[:, None] * np.cos(phi)[None, :]
    z = -radius[:, None] * np.sin(phi)[None, :]
    y = np.broadcast_to(height[:, None], x.shape)
    grid = np.stack([x, y, z], axis=-1)
    grid = np.concatenate([grid, grid[:, :1]], axis=1)
    u = np.arange(n_azimuth + 1) / n_azimuth
    uv = np.stack(np.broadcast_arrays(u[None, :], v[:, None]), axis=-1)
    return grid.reshape(-1, 3), uv.reshape(-1, 2).astype(np.float64)


def _chart_rects(n_cols: int, n_rows: int,
                 aspect: float | None = None) -> list[tuple[float, float, float, float]]:
    """Chart rectangles (u0, v0, width, height) on an n_cols x n_rows atlas grid.

    Listed row by row (row 0 at small v).  Charts are as large as gutters of at
    least ``_GUTTER`` allow; with ``aspect`` they are shrunk to width/height ==
    aspect and the leftover space is spread evenly over the gaps.
    """
    width = (1.0 - (n_cols + 1) * _GUTTER) / n_cols
    height = (1.0 - (n_rows + 1) * _GUTTER) / n_rows
    if aspect is not None:
        width, height = min(width, height * aspect), min(height, width / aspect)
    gap_u = (1.0 - n_cols * width) / (n_cols + 1)
    gap_v = (1.0 - n_rows * height) / (n_rows + 1)
    return [(gap_u + c * (width + gap_u), gap_v + r * (height + gap_v), width, height)
            for r in range(n_rows) for c in range(n_cols)]


# --------------------------------------------------------------------- builders
# Each builder returns raw (positions, uvs, faces, bounding-sphere centre).


def _build_sphere(detail: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    n_theta, n_phi = 80 * detail, 160 * detail
    v = np.arange(n_theta + 1) / n_theta
    theta = np.pi * v
    radius, height = np.sin(theta), np.cos(theta)
    # sin(pi) is 1e-16, not 0: pin the poles so their ring collapses to one point.
    radius[[0, -1]] = 0.0
    positions, uvs = _revolve(radius, height, v, n_phi)
    faces = _grid_faces(n_theta, n_phi)
    return positions, uvs, faces, np.zeros(3)


def _build_dented(detail: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    positions, uvs, faces, centre = _build_sphere(detail)
    # The axes of a cube with its diagonal along +Y, 120 degrees apart in azimuth: the dents
    # sit 35 degrees above and below the equator, in opposite pairs, so the point symmetry
    # that centres the bounding sphere holds.
    azimuth = np.radians([0.0, 120.0, 240.0])
    axes = np.stack([np.sqrt(2 / 3) * np.cos(azimuth), np.full(3, np.sqrt(1 / 3)), -np.sqrt(2 / 3) * np.sin(azimuth)], 1)
    sin2 = 1.0 - (positions @ axes.T) ** 2
    radius = 1.0 - _DENT_DEPTH * np.exp(-sin2 / _DENT_WIDTH**2).sum(axis=1)
    return positions * radius[:, None], uvs, faces, centre


def _build_torus(detail: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    n_phi, n_psi = 160 * detail, 64 * detail
    v = np.arange(n_psi + 1) / n_psi
    psi = 2.0 * np.pi * v
    radius = _TORUS_MAJOR + _TORUS_MINOR * np.cos(psi)
    height = _TORUS_MINOR * np.sin(psi)
    # Close the tube seam exactly (cos/sin of 2pi are not exactly 1/0).
    radius[-1], height[-1] = radius[0], height[0]
    positions, uvs = _revolve(radius, height, v, n_phi)
    # Rows run around the tube, which makes d/drow x d/dcol point inward.
    faces = _grid_faces(n_psi, n_phi, flip=True)
    return positions, uvs, faces, np.zeros(3)


def _build_die(detail: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    n = 64 * detail
    # One shared coordinate array makes grid points on shared cube edges identical.
    coords = np.linspace(-1.0, 1.0, n + 1)
    s, t = np.meshgrid(coords, coords, indexing="xy")  # rows follow t, columns s
    inner = 1.0 - _DIE_ROUNDING
    rects = _chart_rects(3, 2, aspect=1.0)
    positions, uvs, faces = [], [], []
    for k, (normal, e_s, e_t) in enumerate(_DIE_FACES):
        normal, e_s, e_t = (np.asarray(x) for x in (normal, e_s, e_t))
        cube = normal + s[..., None] * e_s + t[..., None] * e_t
        core = np.clip(cube, -inner, inner)
        offset = cube - core
        dist = np.linalg.norm(offset, axis=-1, keepdims=True)
        surface = core + _DIE_ROUNDING * offset / dist
        depth = np.zeros_like(s)
        for ps, pt in _DIE_PIPS[k]:
            r2 = ((s - ps * _DIE_PIP_OFFSET) ** 2 + (t - pt * _DIE_PIP_OFFSET) ** 2) / _DIE_PIP_RADIUS**2
            # (1 - r^2)^2 has zero slope at the rim, so the dimple meets the face smoothly.
            depth += _DIE_PIP_DEPTH * np.where(r2 < 1.0, (1.0 - r2) ** 2, 0.0)
        surface = surface - depth[..., None] * normal
        u0, v0, width, height = rects[k]
        uv = np.stack([u0 + width * (s + 1.0) / 2.0, v0 + height * (t + 1.0) / 2.0], axis=-1)
        faces.append(_grid_faces(n, n, flip=True) + k * (n + 1) ** 2)
        positions.append(surface.reshape(-1, 3))
        uvs.append(uv.reshape(-1, 2))
    return np.concatenate(positions), np.concatenate(uvs), np.concatenate(faces), np.zeros(3)


def _resample_polyline(points: np.ndarray, n_segments: int) -> np.ndarray:
    """Points at n_segments + 1 equal arc-length steps along a polyline (end points kept)."""
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    target = np.linspace(0.0, arc[-1], n_segments + 1)
    return np.stack([np.interp(target, arc, points[:, k]) for k in range(points.shape[1])], axis=1)


def _vase_profile(n_segments: int) -> tuple[np.ndarray, np.ndarray]:
    """(radius, height) of the vase profile at n_segments + 1 equal arc-length steps.

    The profile runs from the centre of the flat base, up the outside, over a
    rounded lip and down into a shallow bowl that closes on the axis.
    """
    top, lip_radius, mouth_depth = 1.6, 0.03, 0.15
    step, fillet = 0.002, 0.012

    def side_radius(y: np.ndarray) -> np.ndarray:
        body = 0.27 + 0.33 * np.exp(-(((y - 0.55) / 0.40) ** 2))
        neck = -0.10 * np.exp(-(((y - 1.30) / 0.16) ** 2))
        lip = 0.06 / (1.0 + np.exp(-(y - 1.50) / 0.035))
        return body + neck + lip

    base_r = float(side_radius(np.array(0.0)))
    rim_r = float(side_radius(np.array(top)))
    mouth_r = rim_r - 2.0 * lip_radius
    side_y = np.linspace(0.0, top, 801)
    lip_angle = np.linspace(0.0, np.pi, 60)
    mouth_angle = np.linspace(0.0, np.pi / 2.0, 200)
    pieces = [
        np.stack([np.linspace(0.0, base_r, 200), np.zeros(200)], axis=1),
        np.stack([side_radius(side_y), side_y], axis=1),
        np.stack([rim_r - lip_radius + lip_radius * np.cos(lip_angle),
                  top + lip_radius * np.sin(lip_angle)], axis=1),
        np.stack([mouth_r * np.cos(mouth_angle), top - mouth_depth * np.sin(mouth_angle)], axis=1),
    ]
    # Consecutive pieces share their joint point; keep it once.
    pts = np.concatenate([pieces[0]] + [p[1:] for p in pieces[1:]])
    pts = _resample_polyline(pts, int(np.ceil(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)) / step)))
    # Gaussian smoothing along arc length turns the base edge and the lip joints
    # into small fillets.  Padding with the radius reflected oddly (and the height
    # evenly) about the axis keeps both ends on the axis with a horizontal tangent.
    sigma = fillet / step
    half = int(4 * sigma)
    kernel = np.exp(-0.5 * (np.arange(-half, half + 1) / sigma) ** 2)
    kernel /= kernel.sum()
    radius = np.convolve(np.pad(pts[:, 0], half, mode="reflect", reflect_type="odd"), kernel, "valid")
    height = np.convolve(np.pad(pts[:, 1], half, mode="reflect"), kernel, "valid")
    profile = _resample_polyline(np.stack([radius, height], axis=1), n_segments)
    radius, height = profile[:, 0], profile[:, 1]
    radius[[0, -1]] = 0.0
    return radius, height


def _build_vase(detail: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    n_profile, n_phi = 160 * detail, 120 * detail
    radius, height = _vase_profile(n_profile)
    v = np.arange(n_profile + 1) / n_profile
    positions, uvs = _revolve(radius, height, v, n_phi)
    # The profile runs upward, which makes d/drow x d/dcol point inward.
    faces = _grid_faces(n_profile, n_phi, flip=True)
    centre_y = _axis_centre(radius, height)
    return positions, uvs, faces, np.array([0.0, centre_y, 0.0])


def _axis_centre(radius: np.ndarray, height: np.ndarray) -> float:
    """Height on the axis minimising the largest distance to the profile points.

    The objective is a maximum of convex functions, hence convex, so golden-section
    search finds the minimiser of the exact bounding sphere of a solid of revolution.
    """
    r2 = radius**2

    def farthest(y: float) -> float:
        return float(np.max(r2 + (height - y) ** 2))

    lo, hi = float(height.min()), float(height.max())
    ratio = (np.sqrt(5.0) - 1.0) / 2.0
    a, b = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
    fa, fb = farthest(a), farthest(b)
    for _ in range(200):
        if hi - lo <= 1e-13 * max(1.0, abs(hi)):
            break
        if fa < fb:
            hi, b, fb = b, a, fa
            a = hi - ratio * (hi - lo)
            fa = farthest(a)
        else:
            lo, a, fa = a, b, fb
            b = lo + ratio * (hi - lo)
            fb = farthest(b)
    return 0.5 * (lo + hi)


def _knot_curve(t: np.ndarray) -> np.ndarray:
    """Centre line of the (2, 3) torus knot around +Y, shape (N, 3)."""
    radius = _KNOT_MAJOR + _KNOT_MINOR * np.cos(3.0 * t)
    return np.stack([radius * np.cos(2.0 * t), _KNOT_MINOR * np.sin(3.0 * t),
                     -radius * np.sin(2.0 * t)], axis=1)


def _knot_frame(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closed rotation-minimising frame (tangent, normal, binormal) along a loop.

    Uses the double-reflection rule to transport the normal, then spreads the
    holonomy angle evenly over the loop so the frame closes without a jump.
    """
    n = len(points)
    nxt = np.roll(points, -1, axis=0)
    tangent = nxt - np.roll(points, 1, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    normal = np.empty_like(points)
    seed = np.cross(tangent[0], [0.0, 1.0, 0.0])
    if np.linalg.norm(seed) < 1e-3:
        seed = np.cross(tangent[0], [1.0, 0.0, 0.0])
    normal[0] = seed / np.linalg.norm(seed)
    current = normal[0]
    for k in range(n):
        step = nxt[k] - points[k]
        t_next = tangent[(k + 1) % n]
        c1 = step @ step
        r_l = current - (2.0 / c1) * (step @ current) * step
        t_l = tangent[k] - (2.0 / c1) * (step @ tangent[k]) * step
        v2 = t_next - t_l
        c2 = v2 @ v2
        current = r_l - (2.0 / c2) * (v2 @ r_l) * v2 if c2 > 0 else r_l
        current = current - (current @ t_next) * t_next
        current /= np.linalg.norm(current)
        if k + 1 < n:
            normal[k + 1] = current
    # `current` is the transported normal[0] after one loop; measure its twist.
    binormal0 = np.cross(tangent[0], normal[0])
    holonomy = np.arctan2(current @ binormal0, current @ normal[0])
    angle = -holonomy * np.arange(n) / n
    binormal = np.cross(tangent, normal)
    normal, binormal = (np.cos(angle)[:, None] * normal + np.sin(angle)[:, None] * binormal,
                        -np.sin(angle)[:, None] * normal + np.cos(angle)[:, None] * binormal)
    return tangent, normal, binormal


def _build_knot(detail: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    n_along, n_around = 432 * detail, 36 * detail
    # Resample the curve at equal arc length so quads (and texels) are uniform.
    dense_t = np.linspace(0.0, 2.0 * np.pi, 64 * n_along + 1)
    dense = _knot_curve(dense_t)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    t = np.interp(np.arange(n_along) * arc[-1] / n_along, arc, dense_t)
    centre_line = _knot_curve(t)
    _, normal, binormal = _knot_frame(centre_line)
    tube = _KNOT_TUBE * (_KNOT_MAJOR + _KNOT_MINOR)
    psi = 2.0 * np.pi * np.arange(n_around) / n_around
    rings = centre_line[:, None, :] + tube * (np.cos(psi)[None, :, None] * normal[:, None, :]
                                             + np.sin(psi)[None, :, None] * binormal[:, None, :])
    per_chart = n_along // _KNOT_CHARTS
    rects = _chart_rects(1, _KNOT_CHARTS)
    positions, uvs, faces = [], [], []
    for k, (u0, v0, width, height) in enumerate(rects):
        # Chart k holds rings k*per_chart .. (k+1)*per_chart (the last wraps to ring 0)
        # and columns 0 .. n_around (the last repeats column 0), all exact copies.
        ring_idx = (k * per_chart + np.arange(per_chart + 1)) % n_along
        col_idx = np.arange(n_around + 1) % n_around
        block = rings[ring_idx][:, col_idx]  # (along, around, 3)
        block = block.transpose(1, 0, 2)     # rows around the tube, columns along the curve
        uu = u0 + width * np.arange(per_chart + 1) / per_chart
        vv = v0 + height * np.arange(n_around + 1) / n_around
        uv = np.stack(np.meshgrid(uu, vv, indexing="xy"), axis=-1)
        faces.append(_grid_faces(n_around, per_chart) + len(positions) * block.shape[0] * block.shape[1])
        positions.append(block.reshape(-1, 3))
        uvs.append(uv.reshape(-1, 2))
    return np.concatenate(positions), np.concatenate(uvs), np.concatenate(faces), np.zeros(3)
