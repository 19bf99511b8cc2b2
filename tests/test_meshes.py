"""Tests for freqbrdf.scene.meshes (procedural objects, UV atlases) and freqbrdf.scene.ply (PLY I/O)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.spatial import ConvexHull
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from freqbrdf.scene import meshes as M
from freqbrdf.scene.meshes import OBJECTS, Mesh, make_mesh
from freqbrdf.scene.ply import read_ply, write_ply

GENUS = {"sphere": 0, "torus": 1, "die": 0, "vase": 0, "knot": 1, "dented": 0}
CHARTS = {"sphere": 1, "torus": 1, "die": 6, "vase": 1, "knot": 4, "dented": 1}


@pytest.fixture(scope="module")
def meshes() -> dict[str, Mesh]:
    return {name: make_mesh(name) for name in OBJECTS}


# ------------------------------------------------------------------ helpers


def weld(vertices: np.ndarray) -> np.ndarray:
    """Group id per vertex for positions equal to 1e-8 (object radius is 1)."""
    _, inverse = np.unique(np.round(vertices * 1e8).astype(np.int64), axis=0, return_inverse=True)
    return inverse.ravel()


def face_cross(mesh: Mesh) -> np.ndarray:
    p0, p1, p2 = (mesh.vertices[mesh.faces[:, k]] for k in range(3))
    return np.cross(p1 - p0, p2 - p0)


def volume(mesh: Mesh) -> float:
    p0, p1, p2 = (mesh.vertices[mesh.faces[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->", p0, np.cross(p1, p2)) / 6.0)


def components(n_vertices: int, edges: np.ndarray) -> tuple[int, np.ndarray]:
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n_vertices,) * 2)
    return connected_components(graph, directed=False)


def face_edges(faces: np.ndarray) -> np.ndarray:
    return np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])


def texel_coverage(uvs: np.ndarray, faces: np.ndarray, res: int = 256) -> np.ndarray:
    """How many UV triangles strictly contain each texel centre, shape (res, res) [row=v]."""
    tri = uvs[faces] * res - 0.5  # texel centre (i, j) is at (x, y) = (j, i)
    lo = np.ceil(tri.min(axis=1)).astype(int)
    span = np.floor(tri.max(axis=1)).astype(int) - lo + 1
    count = np.zeros((res, res), dtype=int)
    for dy in range(max(span[:, 1].max(), 0)):
        for dx in range(max(span[:, 0].max(), 0)):
            sel = (dx < span[:, 0]) & (dy < span[:, 1])
            x, y, t = lo[sel, 0] + dx, lo[sel, 1] + dy, tri[sel]
            w = []
            for a, b in ((0, 1), (1, 2), (2, 0)):
                w.append((t[:, b, 0] - t[:, a, 0]) * (y - t[:, a, 1])
                         - (t[:, b, 1] - t[:, a, 1]) * (x - t[:, a, 0]))
            w = np.stack(w, axis=1)
            inside = np.all(w > 0, axis=1) | np.all(w < 0, axis=1)
            np.add.at(count, (y[inside], x[inside]), 1)
    return count


# --------------------------------------------------------------------- API


def test_unknown_name_and_bad_detail_raise() -> None:
    assert OBJECTS == ("sphere", "torus", "die", "vase", "knot", "dented")
    with pytest.raises(ValueError) as info:
        make_mesh("teapot")
    message = str(info.value)
    assert "teapot" in message and all(name in message for name in OBJECTS)
    for bad in (0, -1, 1.5):
        with pytest.raises(ValueError):
            make_mesh("sphere", bad)


def test_mesh_types_and_sizes(meshes: dict[str, Mesh]) -> None:
    for name, mesh in meshes.items():
        n = len(mesh.vertices)
        assert mesh.vertices.dtype == np.float64 and mesh.vertices.shape == (n, 3), name
        assert mesh.normals.dtype == np.float64 and mesh.normals.shape == (n, 3), name
        assert mesh.uvs.dtype == np.float64 and mesh.uvs.shape == (n, 2), name
        assert mesh.faces.dtype == np.int32 and mesh.faces.shape[1] == 3, name
        assert 10_000 <= len(mesh.faces) <= 50_000, (name, len(mesh.faces))
        assert np.unique(mesh.faces).size == n, f"{name}: unreferenced vertices"
        assert not mesh.vertices.flags.writeable


def test_detail_refines_tessellation() -> None:
    coarse, fine = make_mesh("torus", 1), make_mesh("torus", 2)
    assert len(fine.faces) == 4 * len(coarse.faces)
    exact = 2 * np.pi**2 * M._TORUS_MAJOR * M._TORUS_MINOR**2 / (M._TORUS_MAJOR + M._TORUS_MINOR) ** 3
    assert abs(volume(fine) - exact) < abs(volume(coarse) - exact) / 3


# ------------------------------------------------------------ geometry / topology


@pytest.mark.parametrize("name", OBJECTS)
def test_closed_oriented_manifold(meshes: dict[str, Mesh], name: str) -> None:
    mesh = meshes[name]
    ids = weld(mesh.vertices)
    faces = ids[mesh.faces]
    assert np.all((faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0]))
    assert np.linalg.norm(face_cross(mesh), axis=1).min() > 1e-9, "zero-area triangle"
    n_points = int(ids.max()) + 1
    directed = face_edges(faces)
    code = directed[:, 0].astype(np.int64) * n_points + directed[:, 1]
    # Each directed edge once and its reverse once: closed, 2-manifold, consistently oriented.
    assert np.unique(code).size == code.size
    assert np.all(np.isin(directed[:, 1].astype(np.int64) * n_points + directed[:, 0], code))
    euler = n_points - code.size // 2 + len(faces)
    assert euler == 2 - 2 * GENUS[name]
    assert components(n_points, directed)[0] == 1


@pytest.mark.parametrize("name", OBJECTS)
def test_volume_is_positive_and_matches_analytic(meshes: dict[str, Mesh], name: str) -> None:
    vol = volume(meshes[name])
    assert vol > 0.0
    if name == "sphere":
        exact = 4.0 / 3.0 * np.pi
    elif name == "torus":
        big, small = M._TORUS_MAJOR, M._TORUS_MINOR
        exact = 2 * np.pi**2 * big * small**2 / (big + small) ** 3
    elif name == "die":
        inner, rr = 1.0 - M._DIE_ROUNDING, M._DIE_ROUNDING
        side = 2 * inner  # Steiner formula for a cube of this side dilated by a ball of radius rr
        box = side**3 + 6 * side**2 * rr + 3 * np.pi * side * rr**2 + 4 / 3 * np.pi * rr**3
        pips = 21 * np.pi * M._DIE_PIP_DEPTH * M._DIE_PIP_RADIUS**2 / 3  # each: int (1-r^2/R^2)^2 dA
        exact = (box - pips) / (np.sqrt(3) * inner + rr) ** 3
    elif name == "knot":
        t = np.linspace(0.0, 2 * np.pi, 100_001)
        length = np.linalg.norm(np.diff(M._knot_curve(t), axis=0), axis=1).sum()
        tube = M._KNOT_TUBE * (M._KNOT_MAJOR + M._KNOT_MINOR)
        # Farthest surface point: outermost centre-line point (distance R + a) plus the tube.
        exact = np.pi * tube**2 * length / (M._KNOT_MAJOR + M._KNOT_MINOR + tube) ** 3
    elif name == "dented":
        # (1/3) integral of r^3 over directions, by a midpoint rule independent of the mesh's grid
        theta = (np.arange(2000) + 0.5) * np.pi / 2000
        phi = (np.arange(4000) + 0.5) * 2 * np.pi / 4000
        d = np.stack(np.broadcast_arrays(np.sin(theta)[:, None] * np.cos(phi), np.cos(theta)[:, None],
                                         -np.sin(theta)[:, None] * np.sin(phi)), -1)
        azimuth = np.radians([0.0, 120.0, 240.0])
        axes = np.stack([np.sqrt(2 / 3) * np.cos(azimuth), np.full(3, 3**-0.5), -np.sqrt(2 / 3) * np.sin(azimuth)], 1)
        radius = 1 - M._DENT_DEPTH * np.exp(-(1 - (d @ axes.T) ** 2) / M._DENT_WIDTH**2).sum(-1)
        area = np.sin(theta)[:, None] * (np.pi / 2000) * (2 * np.pi / 4000)
        exact = (radius**3 * area).sum() / 3 / radius.max() ** 3
    else:
        return
    tolerance = 0.002 if name == "die" else 0.01
    assert abs(vol - exact) <= tolerance * exact, (vol, exact)


def test_dents_are_pits_inside_the_convex_hull(meshes: dict[str, Mesh]) -> None:
    # pits, not saucers: a tenth of the surface lies well inside the hull, which a sphere's never does
    for name, deep in (("dented", True), ("sphere", False)):
        hull = ConvexHull(meshes[name].vertices).equations
        inside = -(meshes[name].vertices @ hull[:, :3].T + hull[:, 3]).max(axis=1)
        assert (inside.max() > 0.15 and (inside > 0.02).mean() > 0.1) == deep, name


@pytest.mark.parametrize("name", OBJECTS)
def test_normalised_to_unit_bounding_sphere(meshes: dict[str, Mesh], name: str) -> None:
    v = meshes[name].vertices
    radius = np.linalg.norm(v, axis=1)
    assert abs(radius.max() - 1.0) < 1e-9
    # The origin is the centre of the smallest enclosing sphere iff it lies in the
    # convex hull of the points at maximal distance (feasibility LP).  The knot is
    # symmetric about the origin only up to its tessellation, hence the looser band.
    far = v[radius >= 1.0 - (2e-3 if name == "knot" else 1e-9)]
    result = linprog(np.zeros(len(far)), A_eq=np.vstack([far.T, np.ones(len(far))]),
                     b_eq=[0.0, 0.0, 0.0, 1.0], bounds=(0, None), method="highs")
    assert result.status == 0, f"{name}: origin is not the bounding-sphere centre"


@pytest.mark.parametrize("name", OBJECTS)
def test_normals_unit_outward_and_welded(meshes: dict[str, Mesh], name: str) -> None:
    mesh = meshes[name]
    assert np.allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-12, rtol=0)
    cross = face_cross(mesh)
    unit = cross / np.linalg.norm(cross, axis=1, keepdims=True)
    dots = np.concatenate([np.einsum("ij,ij->i", unit, mesh.normals[mesh.faces[:, k]]) for k in range(3)])
    assert dots.mean() > 0.95 and dots.min() > 0.5
    ids = weld(mesh.vertices)
    first = np.zeros(ids.max() + 1, dtype=int)
    first[ids[::-1]] = np.arange(len(ids))[::-1]
    duplicated = np.bincount(ids)[ids] > 1
    assert duplicated.any(), "expected duplicated seam vertices"
    assert np.array_equal(mesh.normals, mesh.normals[first[ids]]), "normals differ across a seam"
    if name == "sphere":
        assert np.einsum("ij,ij->i", mesh.normals, mesh.vertices).min() > 0.999


# ----------------------------------------------------------------------- UVs


@pytest.mark.parametrize("name", OBJECTS)
def test_uv_charts_do_not_overlap(meshes: dict[str, Mesh], name: str) -> None:
    mesh = meshes[name]
    assert mesh.uvs.min() >= 0.0 and mesh.uvs.max() <= 1.0
    tri = mesh.uvs[mesh.faces]
    signed = 0.5 * ((tri[:, 1, 0] - tri[:, 0, 0]) * (tri[:, 2, 1] - tri[:, 0, 1])
                    - (tri[:, 1, 1] - tri[:, 0, 1]) * (tri[:, 2, 0] - tri[:, 0, 0]))
    # One orientation for every UV triangle: no folded or mirrored pieces.
    assert np.all(signed > 0) or np.all(signed < 0)
    area = np.abs(signed).sum()
    assert area <= 1.0 + 1e-12
    coverage = texel_coverage(mesh.uvs, mesh.faces)
    assert coverage.max() == 1, f"{name}: a texel centre is covered twice"
    covered = np.count_nonzero(coverage)
    assert abs(covered - area * 256**2) <= 0.02 * area * 256**2


@pytest.mark.parametrize("name", OBJECTS)
def test_uv_charts_and_gutters(meshes: dict[str, Mesh], name: str) -> None:
    mesh = meshes[name]
    n_charts, labels = components(len(mesh.uvs), face_edges(mesh.faces))
    assert n_charts == CHARTS[name]
    if n_charts == 1:
        return
    boxes = np.array([[mesh.uvs[labels == c].min(axis=0), mesh.uvs[labels == c].max(axis=0)]
                      for c in range(n_charts)])
    assert boxes[:, 0].min() >= 0.02 and boxes[:, 1].max() <= 0.98, "chart touches the border gutter"
    for a in range(n_charts):
        for b in range(a + 1, n_charts):
            gap = np.maximum(boxes[b, 0] - boxes[a, 1], boxes[a, 0] - boxes[b, 1]).max()
            assert gap >= 0.02, f"charts {a} and {b} are only {gap:.4f} apart"
    if name == "knot":
        extent = boxes[:, 1] - boxes[:, 0]
        assert np.all(extent[:, 0] > 3 * extent[:, 1]), "knot charts should be horizontal bands"


def test_sphere_uv_convention(meshes: dict[str, Mesh]) -> None:
    mesh = meshes["sphere"]
    x, y, z = mesh.vertices.T
    inner = (mesh.uvs[:, 1] > 0) & (mesh.uvs[:, 1] < 1)
    theta = np.arctan2(np.hypot(x, z), y)
    assert np.allclose(mesh.uvs[:, 1], theta / np.pi, atol=1e-12)
    phi = np.mod(np.arctan2(-z, x), 2 * np.pi)
    u = mesh.uvs[inner, 0]
    # The seam column sits at u = 1 where atan2 gives phi = 0.
    assert np.allclose(np.where(u > 1 - 1e-12, 0.0, u), phi[inner] / (2 * np.pi), atol=1e-9)
    assert np.any(inner & (mesh.uvs[:, 0] == 1.0))


# ------------------------------------------------------------------------- die


def test_die_has_21_pips_with_opposite_faces_summing_to_7(meshes: dict[str, Mesh]) -> None:
    mesh = meshes["die"]
    v = mesh.vertices
    half = np.abs(v).max()  # flat face regions lie exactly on |coordinate| = half
    inner, rr = (1.0 - M._DIE_ROUNDING) * half, M._DIE_ROUNDING * half
    q = np.abs(v) - inner
    sdf = np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0) - rr
    depth = M._DIE_PIP_DEPTH * half
    assert sdf.max() < 1e-9, "vertex outside the rounded cube"
    assert abs(-sdf.min() - depth) < 1e-6 * half, "deepest point should be the pip depth"
    in_pip = sdf < -0.25 * depth
    ids = weld(v)
    edges = ids[face_edges(mesh.faces)]
    pip_edge = in_pip[face_edges(mesh.faces)].all(axis=1)
    n_points = int(ids.max()) + 1
    labels = components(n_points, edges[pip_edge])[1]
    pip_points = np.unique(ids[in_pip])
    pip_labels = np.unique(labels[pip_points])
    assert len(pip_labels) == 21
    point_pos = np.zeros((n_points, 3))
    point_pos[ids] = v
    counts: dict[tuple[int, int], int] = {}
    for label in pip_labels:
        centre = point_pos[pip_points[labels[pip_points] == label]].mean(axis=0)
        axis = int(np.argmax(np.abs(centre)))
        key = (axis, int(np.sign(centre[axis])))
        counts[key] = counts.get(key, 0) + 1
    assert sorted(counts.values()) == [1, 2, 3, 4, 5, 6]
    for axis in range(3):
        assert counts[(axis, 1)] + counts[(axis, -1)] == 7


# ------------------------------------------------------------------------- PLY


@pytest.mark.parametrize("name", OBJECTS)
def test_ply_round_trip_is_exact(meshes: dict[str, Mesh], name: str, tmp_path: Path) -> None:
    mesh = meshes[name]
    path = tmp_path / f"{name}.ply"
    write_ply(path, mesh)
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name], "temporary file left behind"
    data = path.read_bytes()
    header = data[: data.index(b"end_header\n") + len(b"end_header\n")].decode()
    assert header.startswith("ply\nformat binary_little_endian 1.0\n")
    assert "property float x\nproperty float y\nproperty float z\nproperty float nx\n" in header
    assert "property float u\nproperty float v\n" in header
    assert "property list uchar int vertex_indices\n" in header
    back = read_ply(path)
    for field in ("vertices", "normals", "uvs"):
        expected = getattr(mesh, field).astype(np.float32).astype(np.float64)
        assert np.array_equal(getattr(back, field), expected), field
    assert np.array_equal(back.faces, mesh.faces)
    write_ply(tmp_path / "again.ply", back)
    assert (tmp_path / "again.ply").read_bytes() == data


def test_read_ply_rejects_bad_files(meshes: dict[str, Mesh], tmp_path: Path) -> None:
    good = tmp_path / "good.ply"
    write_ply(good, meshes["torus"])
    data = good.read_bytes()
    cases = {
        "truncated.ply": data[:-7],
        "trailing.ply": data + b"\0",
        "ascii.ply": data.replace(b"binary_little_endian", b"ascii", 1),
        "garbage.ply": b"\x89PNG\r\n\x1a\n" + bytes(100),
        "empty.ply": b"",
    }
    for file_name, content in cases.items():
        path = tmp_path / file_name
        path.write_bytes(content)
        with pytest.raises(ValueError, match=file_name) as info:
            read_ply(path)
        assert "\n" not in str(info.value)
    with pytest.raises(ValueError, match="missing.ply"):
        read_ply(tmp_path / "missing.ply")
    quad = bytearray(data)
    quad[len(data) - 13] = 4  # first byte of the last face record: vertex count
    (tmp_path / "quad.ply").write_bytes(bytes(quad))
    with pytest.raises(ValueError, match="quad.ply"):
        read_ply(tmp_path / "quad.ply")


def test_write_ply_replaces_existing_file(meshes: dict[str, Mesh], tmp_path: Path) -> None:
    path = tmp_path / "mesh.ply"
    path.write_bytes(b"old content")
    write_ply(path, meshes["sphere"])
    assert len(read_ply(path).faces) == len(meshes["sphere"].faces)


# --------------------------------------------------------------------- Mitsuba


def test_mitsuba_loads_ply_and_agrees_on_area_and_uv(mi, meshes: dict[str, Mesh], tmp_path: Path) -> None:
    for name, mesh in meshes.items():
        path = tmp_path / f"{name}.ply"
        write_ply(path, mesh)
        shape = mi.load_dict({"type": "ply", "filename": str(path)})
        assert shape.vertex_count() == len(mesh.vertices) and shape.face_count() == len(mesh.faces)
        v32 = mesh.vertices.astype(np.float32).astype(np.float64)
        p0, p1, p2 = (v32[mesh.faces[:, k]] for k in range(3))
        ours = 0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1).sum()
        # Mitsuba accumulates the area in float32.
        assert abs(float(shape.surface_area()[0]) - ours) <= 1e-4 * ours, name

    # Texture convention end to end: hit the sphere at known (theta, phi), look the
    # hit up in a bitmap built from tex[i, j] and expect row floor(v H), column floor(u W).
    scene = mi.load_dict({"type": "scene", "s": {"type": "ply", "filename": str(tmp_path / "sphere.ply")}})
    height, width = 8, 16
    tex = np.arange(height * width, dtype=np.float32).reshape(height, width, 1)
    bitmap = mi.load_dict({"type": "bitmap", "bitmap": mi.Bitmap(tex), "filter_type": "nearest", "raw": True})
    for u, v in ((0.15, 0.35), (0.72, 0.81)):
        theta, phi = np.pi * v, 2 * np.pi * u
        direction = [np.sin(theta) * np.cos(phi), np.cos(theta), -np.sin(theta) * np.sin(phi)]
        ray = mi.Ray3f(mi.Point3f(*[3.0 * float(c) for c in direction]), mi.Vector3f(*[-float(c) for c in direction]))
        si = scene.ray_intersect(ray)
        assert abs(float(si.uv.x[0]) - u) < 2e-3 and abs(float(si.uv.y[0]) - v) < 2e-3
        value = float(bitmap.eval_1(si)[0])
        assert value == tex[int(v * height), int(u * width), 0]
