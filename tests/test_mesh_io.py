"""A user's mesh (PLY or OBJ, any common layout) read through freqbrdf.capture.mesh_io."""

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from freqbrdf.capture.mesh_io import read_mesh, triangulate
from freqbrdf.scene.meshes import make_mesh, vertex_normals
from freqbrdf.scene.ply import read_ply, write_ply


def _write_ply(path, mesh, uv_names=("u", "v"), normals=True, extra_vertex=False, index_type="i4",
               text=False, quads=False, uvs=None):
    """A PLY in another tool's layout: float64 positions, the given uv names and index type (and
    ``uvs`` instead of the mesh's, which a Mesh keeps in [0, 1])."""
    vertices, uvs, normals_ = mesh.vertices, mesh.uvs if uvs is None else uvs, mesh.normals
    if extra_vertex:  # an unused vertex with no defined normal (Mitsuba renders such a mesh fine)
        vertices = np.vstack([vertices, [[9.0, 9.0, 9.0]]])
        uvs = np.vstack([uvs, [[0.5, 0.5]]])
        normals_ = np.vstack([normals_, [[np.nan, np.nan, np.nan]]])
    fields = [("x", "f8"), ("y", "f8"), ("z", "f8")] + ([("nx", "f4"), ("ny", "f4"), ("nz", "f4")] if normals else [])
    fields += [(uv_names[0], "f4"), (uv_names[1], "f4")] if uv_names else []
    vertex = np.empty(len(vertices), dtype=fields)
    for k, c in enumerate("xyz"):
        vertex[c] = vertices[:, k]
        if normals:
            vertex["n" + c] = normals_[:, k]
    if uv_names:
        vertex[uv_names[0]], vertex[uv_names[1]] = uvs[:, 0], uvs[:, 1]
    faces = mesh.faces
    if quads:  # two triangles sharing an edge written as one quad (a b c) + (a c d)
        faces = [list(f) for f in faces]
    face = np.empty(len(faces), dtype=[("vertex_indices", index_type, (3,))])
    face["vertex_indices"] = faces
    PlyData([PlyElement.describe(vertex, "vertex"), PlyElement.describe(face, "face")], text=text).write(str(path))


@pytest.fixture(scope="module")
def sphere():
    return make_mesh("sphere")


def _same(a, b, atol=1e-6):
    np.testing.assert_allclose(a.vertices, b.vertices, atol=atol)
    np.testing.assert_allclose(a.uvs, b.uvs, atol=atol)
    np.testing.assert_array_equal(a.faces, b.faces)


def test_the_pipelines_own_ply_reads_back_unchanged(tmp_path, sphere):
    write_ply(tmp_path / "m.ply", sphere)
    back = read_mesh(tmp_path / "m.ply")
    _same(back, read_ply(tmp_path / "m.ply"), atol=0)
    np.testing.assert_allclose(back.normals, sphere.normals, atol=1e-6)


def test_unused_vertex_with_nan_normal_and_uint_indices_are_accepted(tmp_path, sphere):
    path = tmp_path / "exported.ply"
    _write_ply(path, sphere, extra_vertex=True, index_type="u4")
    with pytest.raises(ValueError, match="header does not match"):
        read_ply(path)  # the pipeline's strict reader refuses it
    mesh = read_mesh(path)
    assert len(mesh.vertices) == len(sphere.vertices)  # the unused vertex is dropped
    _same(mesh, sphere)


@pytest.mark.parametrize("uv_names", [("s", "t"), ("texture_u", "texture_v")])
def test_other_tools_uv_names(tmp_path, sphere, uv_names):
    _write_ply(tmp_path / "m.ply", sphere, uv_names=uv_names, text=True)
    _same(read_mesh(tmp_path / "m.ply"), sphere)


def test_missing_normals_are_recomputed(tmp_path, sphere):
    _write_ply(tmp_path / "m.ply", sphere, normals=False)
    mesh = read_mesh(tmp_path / "m.ply")
    np.testing.assert_allclose(mesh.normals, sphere.normals, atol=1e-6)


def test_mesh_without_uvs_fails_naming_the_file(tmp_path, sphere):
    _write_ply(tmp_path / "bare.ply", sphere, uv_names=None)
    with pytest.raises(ValueError, match=r"bare.ply: mesh has no texture coordinates \(UVs\)") as info:
        read_mesh(tmp_path / "bare.ply")
    assert "\n" not in str(info.value)
    (tmp_path / "bare.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(ValueError, match="bare.obj: mesh has no texture coordinates"):
        read_mesh(tmp_path / "bare.obj")


def test_a_mesh_without_usable_uvs_is_unwrapped_by_xatlas_with_a_warning(tmp_path, sphere, caplog):
    from freqbrdf.scene.scans import AtlasSettings, overlapping_texels

    atlas = AtlasSettings(resolution=64, padding=2)
    mirrored = sphere.uvs.copy()
    mirrored[:, 0] = np.where(mirrored[:, 0] > 0.5, 1.0 - mirrored[:, 0], mirrored[:, 0])  # the halves share a chart
    cases = {"bare.ply": (None, "mesh has no texture coordinates (UVs)"),
             "mirrored.ply": (mirrored, "UV charts overlap on"),
             "tiled.ply": (sphere.uvs * 2.0, "UVs span [0, 2], outside the atlas [0, 1]")}
    for name, (uvs, reason) in cases.items():
        _write_ply(tmp_path / name, sphere, uv_names=None if uvs is None else ("u", "v"), uvs=uvs)
        caplog.clear()
        with caplog.at_level("WARNING"):
            unwrapped = read_mesh(tmp_path / name, atlas)
        assert f"{name}: {reason}" in caplog.text and "unwrapped with xatlas (64 texels, padding 2)" in caplog.text
        assert overlapping_texels(unwrapped.uvs, unwrapped.faces, 64)[0] == 0
        assert {tuple(v) for v in unwrapped.vertices.round(6)} == {tuple(v) for v in sphere.vertices.round(6)}
        # the file's normals (float32 there) travel with their vertices
        given = {tuple(v): n for v, n in zip(sphere.vertices.round(6), sphere.normals.astype(np.float32))}
        assert all(np.allclose(given[tuple(v)], n, atol=1e-6) for v, n in zip(unwrapped.vertices.round(6), unwrapped.normals))
    assert read_mesh(tmp_path / "mirrored.ply").uvs.max() <= 1  # without an atlas, overlaps are not checked
    with pytest.raises(ValueError, match=r"tiled\.ply: UVs span \[0, 2\], outside the atlas \[0, 1\]"):
        read_mesh(tmp_path / "tiled.ply")


def test_obj_with_quads_seams_groups_and_no_normals(tmp_path):
    # A unit square in z = 0 as one quad, plus a second group: a triangle whose
    # first corner reuses position 1 with another uv (a seam), and an unused vertex.
    (tmp_path / "m.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 7 7 7\n"
        "vt 0 0\nvt 0.5 0\nvt 0.5 0.5\nvt 0 0.5\nvt 0.9 0.9\n"
        "g a\nf 1/1 2/2 3/3 4/4\ng b\nf 1/5 2/2 3/3\n")
    mesh = read_mesh(tmp_path / "m.obj")
    assert len(mesh.faces) == 3
    assert 7.0 not in mesh.vertices
    corner_uvs = {tuple(np.round(mesh.uvs[i], 6)) for i in np.nonzero((mesh.vertices == 0).all(axis=1))[0]}
    assert corner_uvs == {(0.0, 0.0), (0.9, 0.9)}  # the seam keeps both uvs of position 1
    np.testing.assert_allclose(np.abs(mesh.normals[:, 2]), 1.0)


def test_obj_normals_from_the_file_are_kept(tmp_path):
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0.6 0.8\n"
                                    "f 1/1/1 2/2/1 3/3/1\n")
    np.testing.assert_allclose(read_mesh(tmp_path / "m.obj").normals, [[0, 0.6, 0.8]] * 3, atol=1e-12)


def test_bad_meshes_fail_in_one_line_naming_the_file(tmp_path):
    cases = {
        "garbage.ply": (b"not a ply", "garbage.ply: not a readable PLY file"),
        "tiles.obj": (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 2 0\nvt 0 1\nf 1/1 2/2 3/3\n", r"tiles.obj: UVs span \[0, 2\]"),
        "empty.obj": (b"# nothing\n", "empty.obj: OBJ file has no faces"),
        "mesh.stl": (b"solid", r"mesh.stl: unsupported mesh format '.stl'"),
    }
    for name, (content, message) in cases.items():
        (tmp_path / name).write_bytes(content)
        with pytest.raises(ValueError, match=message) as info:
            read_mesh(tmp_path / name)
        assert "\n" not in str(info.value)
    with pytest.raises(FileNotFoundError, match="nowhere.ply: mesh file not found"):
        read_mesh(tmp_path / "nowhere.ply")


def test_triangulate_fans_polygons():
    np.testing.assert_array_equal(triangulate([[0, 1, 2, 3], [4, 5, 6]]), [[0, 1, 2], [0, 2, 3], [4, 5, 6]])
    with pytest.raises(ValueError, match="2 corners"):
        triangulate([[0, 1]])


def test_vertex_normals_of_a_flat_patch():
    positions = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    np.testing.assert_allclose(vertex_normals(positions, np.array([[0, 1, 2], [0, 2, 3]])), [[0, 0, 1]] * 4)
