"""Scanned shapes: the package's meshes decoded, normalised and atlased by xatlas."""

import numpy as np
import pytest

from freqbrdf.scene import assets, scans
from freqbrdf.scene.meshes import OBJECTS, make_mesh


@pytest.fixture(scope="module")
def package(tmp_path_factory):
    return assets.fetch_package(tmp_path_factory.mktemp("resources"))


@pytest.fixture(scope="module")
def meshes(package):
    return {name: scans.scanned_mesh(package, name, scans.AtlasSettings(resolution=256, padding=4)) for name in scans.SCANS}


def surface_area(vertices, faces):
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()


def uv_area(uvs, faces):
    a, b, c = (uvs[faces[:, k]] for k in range(3))
    (ux, uy), (vx, vy) = (b - a).T, (c - a).T
    return 0.5 * np.abs(ux * vy - uy * vx).sum()


def texels_covered_twice(uvs, faces, resolution):
    """Oracle: texel centres inside more than one UV triangle (barycentric test, triangle by triangle)."""
    count = np.zeros((resolution, resolution), np.int32)
    for tri in uvs[faces] * resolution - 0.5:
        lo, hi = np.floor(tri.min(axis=0)).astype(int), np.ceil(tri.max(axis=0)).astype(int)
        x, y = np.meshgrid(np.arange(max(lo[0], 0), min(hi[0], resolution - 1) + 1),
                           np.arange(max(lo[1], 0), min(hi[1], resolution - 1) + 1))
        (x0, y0), (x1, y1), (x2, y2) = tri
        det = (y1 - y2) * (x0 - x2) + (x2 - x1) * (y0 - y2)
        if abs(det) < 1e-12:
            continue
        l0 = ((y1 - y2) * (x - x2) + (x2 - x1) * (y - y2)) / det
        l1 = ((y2 - y0) * (x - x2) + (x0 - x2) * (y - y2)) / det
        inside = (l0 > 1e-9) & (l1 > 1e-9) & (1 - l0 - l1 > 1e-9)
        count[y[inside], x[inside]] += 1
    return int((count > 1).sum()), int((count > 0).sum())


def test_the_scans_decode_with_the_packages_vertex_counts(package):
    for name, vertices in (("bunny", 2826), ("suzi", 7503)):
        positions, faces = scans.read_scan(package, name)
        assert positions.shape == (vertices, 3) and faces.shape[1] == 3
        assert faces.min() == 0 and faces.max() == vertices - 1
    with pytest.raises(ValueError, match=r"scan 'teapot' is not one of the package's scans the project uses: bunny, suzi"):
        scans.read_scan(package, "teapot")


def test_a_scan_is_centred_of_radius_one_outward_and_atlased_without_overlap(meshes):
    for name, mesh in meshes.items():
        radius = np.sqrt((mesh.vertices ** 2).sum(axis=1))
        assert radius.max() == pytest.approx(1.0, abs=1e-12), name
        assert np.allclose(0.5 * (mesh.vertices.min(axis=0) + mesh.vertices.max(axis=0)), 0.0, atol=1e-12), name
        a, b, c = (mesh.vertices[mesh.faces[:, k]] for k in range(3))
        assert np.einsum("ij,ij->", a, np.cross(b, c)) > 0, name  # divergence theorem: outward triangles
        assert np.allclose(np.linalg.norm(mesh.normals, axis=1), 1.0)
        assert mesh.uvs.min() >= 0 and mesh.uvs.max() <= 1
        twice, covered = texels_covered_twice(mesh.uvs, mesh.faces, 256)
        assert covered > 0.3 * 256 ** 2 and twice == 0, (name, twice)


def test_duplicates_along_chart_borders_are_bitwise_copies_with_welded_normals(meshes, package):
    positions, _ = scans.read_scan(package, "bunny")
    mesh = meshes["bunny"]
    assert len(mesh.vertices) > len(positions)  # chart borders split vertices
    keys = {}
    for vertex, normal in zip(map(tuple, mesh.vertices), map(tuple, mesh.normals)):
        assert keys.setdefault(vertex, normal) == normal
    assert len(keys) == len(positions)


def test_the_atlas_texel_density_lies_within_the_procedural_objects(meshes):
    """Texels per unit of surface (of the radius-1 object), the padding chosen for this (config meshes.atlas_padding)."""
    procedural = [uv_area(m.uvs, m.faces) / surface_area(m.vertices, m.faces) for m in map(make_mesh, OBJECTS)]
    for name, mesh in meshes.items():
        density = uv_area(mesh.uvs, mesh.faces) / surface_area(mesh.vertices, mesh.faces)
        assert min(procedural) < density < max(procedural), (name, density, procedural)


def test_the_glb_reader_returns_a_known_draco_mesh(tmp_path):
    """Oracle: a tetrahedron Draco-encoded into a glTF binary inside a package-like tarball."""
    import json
    import struct

    import DracoPy

    from synthetic import fake_package

    points = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    draco = DracoPy.encode(points, faces, quantization_bits=16, preserve_order=True)
    gltf = {"asset": {"version": "2.0"}, "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(draco)}],
            "meshes": [{"primitives": [{"attributes": {}, "extensions": {
                "KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}}}]}]}
    text = json.dumps(gltf).encode()
    text += b" " * (-len(text) % 4)
    binary = draco + b"\0" * (-len(draco) % 4)
    glb = (struct.pack("<III", 0x46546C67, 2, 12 + 8 + len(text) + 8 + len(binary))
           + struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(binary), 0x004E4942) + binary)
    fake_package(tmp_path / "fake.tgz", {scans.SCANS["suzi"].member: glb})
    positions, read_faces = scans.read_scan(tmp_path / "fake.tgz", "suzi")
    np.testing.assert_allclose(positions, points, atol=1e-4)  # 16-bit quantisation
    assert {tuple(sorted(f)) for f in read_faces} == {tuple(sorted(f)) for f in faces}
    fake_package(tmp_path / "bad.tgz", {scans.SCANS["suzi"].member: b"not a glb at all"})
    with pytest.raises(ValueError, match=r"bad\.tgz:package/models/suzi\.glb\.js: not a glTF binary"):
        scans.read_scan(tmp_path / "bad.tgz", "suzi")
