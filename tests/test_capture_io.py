"""NeRF-Blender / Stanford-ORB exchange layout: camera conventions and error messages."""

import json

import numpy as np
import pytest

from freqbrdf.capture_io import blender_transforms, cameras_from_blender, export_capture, import_capture
from freqbrdf.cameras import Cameras, cameras_from_json, cameras_to_json, hemisphere_rig, intrinsics
from freqbrdf.io import read_json, write_exr, write_json, write_png


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
    (tmp_path / "mesh.ply").write_bytes(b"ply")
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
    with pytest.raises(ValueError, match=r"0001.exr: image is \(20, 40\), the first train view is \(30, 40\)"):
        import_capture(orb, {"train": tmp_path / "t2"}, tmp_path / "m", tmp_path / "e")
    (orb / "transforms_train.json").write_text(json.dumps({"frames": [{"file_path": "./train/0000"}]}))
    with pytest.raises(ValueError, match="transforms_train.json: malformed transforms"):
        import_capture(orb, {"train": tmp_path / "t3"}, tmp_path / "m", tmp_path / "e")
