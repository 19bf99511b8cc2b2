"""Camera conventions: OpenCV extrinsics, rigs and the JSON format."""

import numpy as np
import pytest

from freqbrdf.scene.cameras import (Cameras, cameras_from_json, cameras_to_json, hemisphere_rig, intrinsics, look_at,
                                    mitsuba_to_world, project, rig_cameras)


def test_look_at_is_rigid_and_opencv_oriented():
    eye = np.array([1.0, 2.0, 3.0])
    w2c = look_at(eye)
    R = w2c[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(w2c @ np.append(eye, 1.0), [0, 0, 0, 1], atol=1e-12)
    # world up appears upward in the image, i.e. toward negative pixel y
    K = intrinsics(100, 100, 40.0)
    (above, centre), _ = project(np.array([[0.0, 0.3, 0.0], [0.0, 0.0, 0.0]]), K, w2c)
    assert above[1] < centre[1]


def test_look_at_handles_a_camera_straight_above():
    w2c = look_at(np.array([0.0, 3.0, 0.0]))
    assert np.isfinite(w2c).all()
    np.testing.assert_allclose(w2c[:3, :3] @ w2c[:3, :3].T, np.eye(3), atol=1e-12)


def test_intrinsics_field_of_view():
    K = intrinsics(200, 100, 90.0)
    assert K[0, 0] == pytest.approx(100.0) and K[1, 1] == pytest.approx(100.0)
    assert (K[0, 2], K[1, 2]) == (100.0, 50.0)
    with pytest.raises(ValueError, match="fov_x_deg"):
        intrinsics(10, 10, 180.0)


def test_hemisphere_rig_distances_and_spread():
    w2c = hemisphere_rig(24, 4.0, azimuth_deg=17.0)
    cams = Cameras(K=np.repeat(intrinsics(8, 8, 40.0)[None], 24, 0), world_to_camera=w2c, width=8, height=8, names=tuple(map(str, range(24))))
    centres = cams.centres
    np.testing.assert_allclose(np.linalg.norm(centres, axis=1), 4.0)
    assert (centres[:, 1] > 0).all()
    assert abs(centres[:, 1].mean() / 4.0 - 0.5) < 0.02  # uniform on the hemisphere
    other = hemisphere_rig(24, 4.0)
    assert not np.allclose(other, w2c)  # the test rig is rotated away from the training rig


def test_mitsuba_to_world_flips_x_and_y_only():
    w2c = look_at(np.array([2.0, 1.0, -3.0]))
    c2w = mitsuba_to_world(w2c)
    cv = np.linalg.inv(w2c)
    np.testing.assert_allclose(c2w[:3, 0], -cv[:3, 0])
    np.testing.assert_allclose(c2w[:3, 1], -cv[:3, 1])
    np.testing.assert_allclose(c2w[:3, 2:], cv[:3, 2:])


def test_json_round_trip_and_errors():
    w2c = hemisphere_rig(3, 3.0)
    cams = Cameras(K=np.repeat(intrinsics(32, 24, 40.0)[None], 3, 0), world_to_camera=w2c, width=32, height=24, names=("a", "b", "c"))
    back = cameras_from_json(cameras_to_json(cams))
    np.testing.assert_array_equal(back.K, cams.K)
    np.testing.assert_array_equal(back.world_to_camera, cams.world_to_camera)
    assert (back.width, back.height, back.names) == (32, 24, ("a", "b", "c"))
    with pytest.raises(ValueError, match="cams.json: format"):
        cameras_from_json({"format": "other"}, source="cams.json")
    broken = cameras_to_json(cams)
    del broken["frames"][1]["K"]
    with pytest.raises(ValueError, match="cams.json: malformed"):
        cameras_from_json(broken, source="cams.json")


def test_a_rig_of_cameras_is_the_hemisphere_rig_with_shared_intrinsics_and_numbered_names():
    cameras = rig_cameras(5, 64, 35.0, 4.0, azimuth_deg=17.0, prefix="candidate_")
    np.testing.assert_array_equal(cameras.world_to_camera, hemisphere_rig(5, 4.0, azimuth_deg=17.0))
    np.testing.assert_array_equal(cameras.K, np.repeat(intrinsics(64, 64, 35.0)[None], 5, axis=0))
    assert (cameras.width, cameras.height) == (64, 64)
    assert cameras.names == ("candidate_000", "candidate_001", "candidate_002", "candidate_003", "candidate_004")
    assert rig_cameras(2, 8, 35.0, 4.0).names == ("000", "001")
