"""NeRF-Blender / Stanford-ORB exchange layout: camera conventions and error messages."""

import json

import numpy as np
import pytest

from freqbrdf.capture.exchange import blender_transforms, cameras_from_blender, export_capture, import_capture
from freqbrdf.scene.cameras import Cameras, cameras_from_json, cameras_to_json, hemisphere_rig, intrinsics
from freqbrdf.util.io import read_exr, read_json, write_exr, write_json, write_png
from freqbrdf.scene.meshes import make_mesh
from freqbrdf.scene.ply import read_ply, write_ply
from synthetic import rewrite_z_up


def _cameras(n=3, width=40, height=30):
    return Cameras(K=np.repeat(intrinsics(width, height, 40.0)[None], n, 0), world_to_camera=hemisphere_rig(n, 4.0),
                   width=width, height=height, names=tuple(f"v{k}" for k in range(n)))


def test_blender_round_trip_and_opengl_axes():
    cams = _cameras()
    transforms = blender_transforms(cams, "train")
    assert transforms["camera_angle_x"] == pytest.approx(np.radians(40.0))
    c2w = np.array(transforms["frames"][0]["transform_matrix"])
    # an OpenGL camera looks down its -z axis: toward the origin here
    np.testing.assert_allclose(-c2w[:3, 2], -c2w[:3, 3] / np.linalg.norm(c2w[:3, 3]), atol=1e-12)
    back, paths = cameras_from_blender(transforms, 40, 30, "t.json")
    np.testing.assert_allclose(back.world_to_camera, cams.world_to_camera, atol=1e-12)
    np.testing.assert_allclose(back.K, cams.K, atol=1e-9)
    assert paths == ["./train/0000", "./train/0001", "./train/0002"]


def test_instant_ngp_intrinsics_are_honoured():
    transforms = blender_transforms(_cameras(), "train") | {"fl_x": 50.0, "fl_y": 52.0, "cx": 19.0, "cy": 16.0}
    cams, _ = cameras_from_blender(transforms, 40, 30, "t.json")
    np.testing.assert_allclose(cams.K[0], [[50, 0, 19], [0, 52, 16], [0, 0, 1]])


def _native_capture(root, cams):
    (root / "images").mkdir(parents=True)
    (root / "masks").mkdir()
    for k, name in enumerate(cams.names):
        write_exr(root / "images" / f"{name}.exr", np.full((cams.height, cams.width, 3), k, np.float32))
        write_png(root / "masks" / f"{name}.png", np.ones((cams.height, cams.width)))
    write_json(root / "cameras.json", cameras_to_json(cams))


def test_export_then_import_restores_the_capture(tmp_path):
    cams = _cameras()
    for split in ("train", "test"):
        _native_capture(tmp_path / "native" / split, cams)
    write_ply(tmp_path / "mesh.ply", make_mesh("sphere"))
    write_exr(tmp_path / "env.exr", np.ones((4, 8, 3)))
    export_capture({s: tmp_path / "native" / s for s in ("train", "test")}, tmp_path / "mesh.ply", tmp_path / "env.exr", tmp_path / "orb")
    counts = import_capture(tmp_path / "orb", {s: tmp_path / "back" / s for s in ("train", "test")},
                            tmp_path / "back/mesh.ply", tmp_path / "back/env.exr")
    assert counts == {"train": 3, "test": 3}
    back = cameras_from_json(read_json(tmp_path / "back/train/cameras.json"))
    np.testing.assert_allclose(back.world_to_camera, cams.world_to_camera, atol=1e-12)
    assert (tmp_path / "back/train/images/0002.exr").read_bytes() == (tmp_path / "native/train/images/v2.exr").read_bytes()


def test_import_errors_name_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="nowhere: capture directory not found"):
        import_capture(tmp_path / "nowhere", {"train": tmp_path / "t"}, tmp_path / "m", tmp_path / "e")
    orb = tmp_path / "orb"
    orb.mkdir()
    write_ply(orb / "mesh.ply", make_mesh("sphere"))
    write_exr(orb / "envmap.exr", np.ones((4, 8, 3)))
    with pytest.raises(FileNotFoundError, match="transforms_train.json"):
        import_capture(orb, {"train": tmp_path / "t"}, tmp_path / "m", tmp_path / "e")
    cams = _cameras(2)
    write_json(orb / "transforms_train.json", blender_transforms(cams, "train"))
    (orb / "train").mkdir()
    (orb / "train_mask").mkdir()
    write_exr(orb / "train/0000.exr", np.zeros((30, 40, 3)))
    write_png(orb / "train_mask/0000.png", np.ones((30, 40)))
    with pytest.raises(FileNotFoundError, match=r"0001.exr: frame './train/0001' of transforms_train.json is missing"):
        import_capture(orb, {"train": tmp_path / "t"}, tmp_path / "m", tmp_path / "e")
    write_exr(orb / "train/0001.exr", np.zeros((20, 40, 3)))
    write_png(orb / "train_mask/0001.png", np.ones((20, 40)))
    with pytest.raises(ValueError, match=r"0001.exr: image is \(20, 40\), the first view of its split is \(30, 40\)"):
        import_capture(orb, {"train": tmp_path / "t2"}, tmp_path / "m", tmp_path / "e")
    (orb / "transforms_train.json").write_text(json.dumps({"frames": [{"file_path": "./train/0000"}]}))
    with pytest.raises(ValueError, match="transforms_train.json: malformed transforms"):
        import_capture(orb, {"train": tmp_path / "t3"}, tmp_path / "m", tmp_path / "e")


def _orb(root, cams=None, mesh_file="mesh.ply"):
    """A valid two-split exchange-layout capture of the sphere."""
    cams = cams or _cameras()
    for split in ("train", "test"):
        (root / split).mkdir(parents=True)
        (root / f"{split}_mask").mkdir()
        for k in range(len(cams)):
            write_exr(root / split / f"{k:04d}.exr", np.full((cams.height, cams.width, 3), k + 1.0, np.float32))
            write_png(root / f"{split}_mask" / f"{k:04d}.png", np.ones((cams.height, cams.width)))
        write_json(root / f"transforms_{split}.json", blender_transforms(cams, split))
    write_ply(root / mesh_file, make_mesh("sphere"))
    write_exr(root / "envmap.exr", np.ones((4, 8, 3)))
    return root


def _import(orb, out, **options):
    return import_capture(orb, {s: out / s for s in ("train", "test")}, out / "mesh.ply", out / "env.exr", **options)


@pytest.mark.parametrize("broken, message", [
    ("train_mask/0001.png", r"train_mask/0001.png: not a readable PNG"),
    ("test_mask/0000.png", r"test_mask/0000.png: not a readable PNG"),
    ("envmap.exr", r"envmap.exr: not a readable OpenEXR file"),
    ("mesh.ply", r"mesh.ply: not a readable PLY file"),
    ("test/0002.exr", r"test/0002.exr: not a readable OpenEXR file"),
])
def test_every_source_file_is_read_at_import_and_named(tmp_path, broken, message):
    orb = _orb(tmp_path / "orb")
    (orb / broken).write_bytes(b"garbage")
    with pytest.raises(ValueError, match=message) as info:
        _import(orb, tmp_path / "out")
    assert str(orb) in str(info.value) and "\n" not in str(info.value)


def test_wrong_sized_mask_and_bad_environment_are_named(tmp_path):
    orb = _orb(tmp_path / "orb")
    write_png(orb / "train_mask/0001.png", np.ones((10, 10)))
    with pytest.raises(ValueError, match=r"orb/train_mask/0001.png: mask is \(10, 10\), its image is \(30, 40\)"):
        _import(orb, tmp_path / "a")
    orb = _orb(tmp_path / "orb2")
    write_exr(orb / "envmap.exr", np.ones((4, 4, 3)))
    with pytest.raises(ValueError, match=r"orb2/envmap.exr: environment map has shape \(4, 4, 3\)"):
        _import(orb, tmp_path / "b")
    write_exr(orb / "envmap.exr", -np.ones((4, 8, 3)))
    with pytest.raises(ValueError, match=r"orb2/envmap.exr: 32 of 32 texels are negative or non-finite \(more than 10%\)"):
        _import(orb, tmp_path / "c")


def test_a_lossy_environment_map_is_cleaned_with_a_warning_instead_of_refused(tmp_path, caplog):
    orb = _orb(tmp_path / "orb")
    env = np.ones((8, 16, 3), np.float32)
    env[3, 5] = [30.0, 30.0, 30.0]
    env[3, 6] = [-2.0, -2.0, -2.0]
    env[7, 14, 0] = np.nan  # outside the negative texel's region (radius 3)
    import OpenEXR  # write_exr refuses NaN, as it should for the project's own files

    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, {"RGB": env}).write(
        str(orb / "envmap.exr"))
    with caplog.at_level("WARNING"):
        _import(orb, tmp_path / "out")
    assert "envmap.exr: 1 negative and 1 non-finite texels cleaned (1 regions, power changed by +0.000%)" in caplog.text
    imported = read_exr(tmp_path / "out" / "env.exr")
    assert imported.min() >= 0 and imported[7, 14, 0] == 1.0 and imported[0, 0, 0] == 1.0


def test_a_mesh_without_uvs_is_unwrapped_at_import_or_stops_it_without_an_atlas(tmp_path, caplog):
    from freqbrdf.scene.scans import AtlasSettings

    orb = _orb(tmp_path / "orb")
    (orb / "mesh.ply").unlink()
    (orb / "mesh.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n")
    with pytest.raises(ValueError, match=r"orb/mesh.obj: mesh has no texture coordinates"):
        _import(orb, tmp_path / "out")
    with caplog.at_level("WARNING"):
        _import(orb, tmp_path / "unwrapped", atlas=AtlasSettings(resolution=32, padding=2))
    assert "orb/mesh.obj: mesh has no texture coordinates (UVs): unwrapped with xatlas (32 texels" in caplog.text
    mesh = read_ply(tmp_path / "unwrapped" / "mesh.ply")
    assert len(mesh.faces) == 2 and mesh.uvs.min() >= 0 and mesh.uvs.max() <= 1


def test_z_up_obj_and_opencv_cameras_give_the_y_up_capture(tmp_path):
    cams = _cameras()
    reference = _orb(tmp_path / "ref", cams)
    _import(reference, tmp_path / "ref_out")
    # The same capture written by a Z-up tool: mesh as OBJ, cameras in OpenCV axes.
    zup = _orb(tmp_path / "zup", cams)
    (zup / "mesh.ply").unlink()
    rewrite_z_up(zup, make_mesh("sphere"), camera_axes=np.diag([1.0, -1.0, -1.0, 1.0]))
    _import(zup, tmp_path / "zup_out", up_axis="z", camera="opencv")
    a, b = read_ply(tmp_path / "ref_out/mesh.ply"), read_ply(tmp_path / "zup_out/mesh.ply")
    np.testing.assert_allclose(b.vertices, a.vertices, atol=1e-6)
    np.testing.assert_allclose(b.normals, a.normals, atol=1e-5)
    for split in ("train", "test"):
        ca = cameras_from_json(read_json(tmp_path / f"ref_out/{split}/cameras.json"))
        cb = cameras_from_json(read_json(tmp_path / f"zup_out/{split}/cameras.json"))
        np.testing.assert_allclose(cb.world_to_camera, ca.world_to_camera, atol=1e-9)


def test_per_view_test_environments_are_imported(tmp_path):
    orb = _orb(tmp_path / "orb")
    (orb / "test_env").mkdir()
    for k in range(3):
        write_exr(orb / f"test_env/{k:04d}.exr", np.full((4, 8, 3), k + 1.0))
    _import(orb, tmp_path / "out")
    from freqbrdf.util.io import read_exr

    assert read_exr(tmp_path / "out/test/envmaps/0002.exr").max() == 3.0
    assert not (tmp_path / "out/train/envmaps").exists()
    (orb / "test_env/0001.exr").unlink()
    with pytest.raises(FileNotFoundError, match="test_env/0001.exr"):
        _import(orb, tmp_path / "out2")


def test_the_source_checksum_follows_file_contents(tmp_path):
    import os

    from freqbrdf.capture.exchange import source_checksum

    orb = _orb(tmp_path / "orb")
    before = source_checksum(orb)
    mask = orb / "train_mask/0001.png"
    stat = mask.stat()
    write_png(mask, np.zeros((30, 40)))  # a fixed mask, given back its old timestamp
    os.utime(mask, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    after = source_checksum(orb)
    assert after != before
    (orb / ".DS_Store").write_bytes(b"x")
    os.utime(orb / "envmap.exr")
    assert source_checksum(orb) == after  # hidden files and timestamps alone do not count
    assert source_checksum(tmp_path / "none") == "absent"


def test_ground_truth_textures_are_checked(tmp_path):
    from freqbrdf.capture.exchange import import_textures

    truth = tmp_path / "truth"
    truth.mkdir()
    write_exr(truth / "base_color.exr", np.full((8, 8, 3), 0.5))
    write_exr(truth / "roughness.exr", np.full((8, 8), 0.3))
    write_exr(truth / "metallic.exr", np.full((8, 8), 1.5))
    out = {name: tmp_path / f"out/{name}.exr" for name in ("base_color", "roughness", "metallic")}
    with pytest.raises(ValueError, match=r"truth/metallic.exr: metallic values span \[1.5, 1.5\]"):
        import_textures(truth, out, 8)
    write_exr(truth / "metallic.exr", np.zeros((8, 8)))
    with pytest.raises(ValueError, match=r"truth/base_color.exr: texture is \(8, 8\), the estimates are \(16, 16\)"):
        import_textures(truth, out, 16)
    import_textures(truth, out, 8)
    assert all(path.is_file() for path in out.values())


def test_turn_envmap_rolls_whole_columns_and_fov_needs_a_centred_pinhole():
    from freqbrdf.capture.exchange import pinhole_fov_deg
    from freqbrdf.scene.envmaps import turn_envmap

    env = np.arange(2 * 8 * 3, dtype=np.float32).reshape(2, 8, 3)
    np.testing.assert_array_equal(turn_envmap(env, 90.0), np.roll(env, 2, axis=1))
    np.testing.assert_array_equal(turn_envmap(turn_envmap(env, 90.0), 270.0), env)
    assert pinhole_fov_deg(_cameras(), "c.json") == pytest.approx(40.0)
    shifted = _cameras()
    K = shifted.K.copy()
    K[:, 0, 2] += 3.0
    off_centre = Cameras(K=K, world_to_camera=shifted.world_to_camera, width=40, height=30, names=shifted.names)
    with pytest.raises(ValueError, match="c.json: needs one square-pixel focal length and a centred principal point"):
        pinhole_fov_deg(off_centre, "c.json")


def _write_nan_view(path, height=30, width=40):
    """An all-NaN view (write_exr refuses NaN, so OpenEXR writes it)."""
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"RGB": np.full((height, width, 3), np.nan, np.float32)}) as f:
        f.write(str(path))


def _usable_views(out, min_usable=1):
    """What extract_observations reports of an imported capture (its steps without Mitsuba: nothing occludes)."""
    from freqbrdf.capture.exchange import capture_source
    from freqbrdf.capture.observations import observe, rasterise_uv
    from freqbrdf.capture.view_usability import check_views, nonfinite_views
    from freqbrdf.util.io import read_views

    cams = cameras_from_json(read_json(out / "train/cameras.json"))
    images, coverage, _ = read_views(out / "train", cams.names, cams.width, cams.height)
    obs = observe(rasterise_uv(read_ply(out / "mesh.ply"), 16), cams, images, coverage, np.ones((4, 8, 3), np.float32),
                  lambda origins, directions, lengths: np.zeros(len(origins), bool))
    source, labels = capture_source(out / "train", cams.names)
    lost = check_views(labels, (obs["weight"] > 0).sum(axis=0), images, coverage, obs["view_candidates"],
                       min_usable=min_usable, source=source)
    return lost, nonfinite_views(labels, images)


def test_a_camera_looking_away_and_an_all_nan_view_are_named_in_the_users_file(tmp_path):
    orb = _orb(tmp_path / "orb")
    transforms = read_json(orb / "transforms_train.json")
    c2w = np.array(transforms["frames"][1]["transform_matrix"])
    c2w[:3, 0] *= -1.0  # turned by 180 degrees about its own y axis: it looks away from the object
    c2w[:3, 2] *= -1.0
    transforms["frames"][1]["transform_matrix"] = c2w.tolist()
    write_json(orb / "transforms_train.json", transforms)
    _write_nan_view(orb / "train/0002.exr")
    _import(orb, tmp_path / "out")  # both views are readable: the import accepts them
    lost, nonfinite = _usable_views(tmp_path / "out")
    assert lost == (f"{orb}/transforms_train.json: 2 of 3 views give no observed (texel, view) pair and add "
                    "nothing to the estimates; the camera sees no part of the mesh (it looks away from the object, "
                    "or its pose is wrong): ./train/0001; every pixel is NaN/Inf: ./train/0002")
    assert nonfinite == "1 of 3 views: ./train/0002 (all 1200 pixels)"
    with pytest.raises(ValueError, match=r"transforms_train.json: only 1 of 3 views give an observed \(texel, view\) "
                                         r"pair, fewer than observations.min_usable_views = 2; the camera sees"):
        _usable_views(tmp_path / "out", min_usable=2)


def test_a_capture_without_a_usable_view_stops_naming_the_users_transforms(tmp_path):
    orb = _orb(tmp_path / "orb")
    for k in range(3):
        _write_nan_view(orb / f"train/{k:04d}.exr")
    _import(orb, tmp_path / "out")
    with pytest.raises(ValueError) as info:
        _usable_views(tmp_path / "out")
    assert str(info.value) == (f"{orb}/transforms_train.json: no (texel, view) pair is observed; "
                               "every pixel is NaN/Inf: ./train/0000, ./train/0001, ./train/0002")
    assert str(tmp_path / "out") not in str(info.value)
    assert read_json(tmp_path / "out/train/source.json")["frames"]["0001"] == "./train/0001"


@pytest.mark.parametrize("escape", ["dotdot", "absolute", "symlink", "mesh_symlink"])
def test_a_capture_that_names_a_file_outside_itself_is_refused_before_anything_is_written(tmp_path, escape):
    """A capture received from someone else reads only its own files: a frame's ``..``, an absolute
    path, a frame or mesh linked out of the capture directory each stop the import in one line."""
    orb = _orb(tmp_path / "orb")
    outside = tmp_path / "outside"
    (outside / "train_mask").mkdir(parents=True)
    write_exr(outside / "secret.exr", np.full((30, 40, 3), 9.0, np.float32))
    write_png(orb / "train_mask" / "secret.png", np.ones((30, 40)))
    transforms = read_json(orb / "transforms_train.json")
    if escape == "dotdot":
        transforms["frames"][1]["file_path"] = "../outside/secret"
    elif escape == "absolute":
        transforms["frames"][1]["file_path"] = str(outside / "secret")
    elif escape == "symlink":
        (orb / "train" / "0001.exr").unlink()
        (orb / "train" / "0001.exr").symlink_to(outside / "secret.exr")
    else:
        write_ply(outside / "mesh.ply", make_mesh("sphere"))
        (orb / "mesh.ply").unlink()
        (orb / "mesh.ply").symlink_to(outside / "mesh.ply")
    write_json(orb / "transforms_train.json", transforms)
    what = "the mesh" if escape == "mesh_symlink" else "frame .* of transforms_train.json"
    with pytest.raises(ValueError, match=f"{what} leads to .*outside.*, outside the capture's directory"):
        _import(orb, tmp_path / "out")
    assert not (tmp_path / "out").exists()
