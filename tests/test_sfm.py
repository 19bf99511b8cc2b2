"""Structure from motion: pose errors and alignment on known transforms, COLMAP on a small rendered capture."""

import dataclasses
import json
import logging
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.ndimage import gaussian_filter
from scipy.spatial.transform import Rotation

from freqbrdf.capture import sfm, sfm_alignment, sfm_options
from freqbrdf.scene.cameras import Cameras, cameras_to_json, hemisphere_rig, intrinsics, mitsuba_to_world, project
from freqbrdf.util.io import read_png, write_exr, write_json, write_png
from freqbrdf.util.colour import tonemap


def make_rig(n: int = 12, size: int = 64) -> Cameras:
    return Cameras(
        K=np.repeat(intrinsics(size, size, 35.0)[None], n, axis=0),
        world_to_camera=hemisphere_rig(n, 4.0),
        width=size,
        height=size,
        names=tuple(f"{k:03d}" for k in range(n)),
    )


def similarity(scale: float, rotvec, t) -> np.ndarray:
    S = np.eye(4)
    S[:3, :3] = scale * Rotation.from_rotvec(rotvec).as_matrix()
    S[:3, 3] = t
    return S


# --------------------------------------------------------------------------- pure pieces


def test_pose_errors_of_identical_cameras_are_zero():
    ref = make_rig()
    errors = sfm_alignment.pose_errors(ref, ref)
    assert list(errors["name"]) == list(ref.names)
    np.testing.assert_allclose(errors["rotation_error_deg"], 0.0, atol=1e-5)
    np.testing.assert_allclose(errors["centre_error_rel"], 0.0, atol=1e-12)
    assert "reprojection_error_px" not in errors


def test_pose_errors_measure_one_camera_turned_by_two_degrees():
    ref = make_rig()
    w2c = ref.world_to_camera.copy()
    turn = Rotation.from_rotvec(np.radians(2.0) * np.array([0.6, 0.0, 0.8])).as_matrix()
    w2c[3, :3, :] = turn @ w2c[3, :3, :]  # rotates the camera about its own centre
    est = dataclasses.replace(ref, world_to_camera=w2c)
    errors = sfm_alignment.pose_errors(est, ref, reprojection={"003": 0.25})
    assert errors["rotation_error_deg"][3] == pytest.approx(2.0, abs=1e-6)
    assert np.delete(errors["rotation_error_deg"].to_numpy(), 3) == pytest.approx(0.0, abs=1e-5)
    np.testing.assert_allclose(errors["centre_error_rel"], 0.0, atol=1e-12)
    assert errors["reprojection_error_px"][3] == 0.25 and np.isnan(errors["reprojection_error_px"][0])


def test_pose_errors_measure_centre_offsets_relative_to_the_camera_distance():
    ref = make_rig()
    w2c = ref.world_to_camera.copy()
    shift = np.array([0.0, 0.12, -0.16])  # 0.2 = 5% of the camera distance 4
    w2c[5, :3, 3] -= w2c[5, :3, :3] @ shift  # centre moves by +shift, axes unchanged
    errors = sfm_alignment.pose_errors(dataclasses.replace(ref, world_to_camera=w2c), ref)
    assert errors["centre_error_rel"][5] == pytest.approx(0.05)
    assert errors["rotation_error_deg"][5] == pytest.approx(0.0, abs=1e-5)


def test_relative_rotation_errors_ignore_the_world_frame_and_find_the_turned_view():
    ref = make_rig()
    turn = Rotation.from_rotvec([0.0, np.radians(2.0), 0.0]).as_matrix()
    # the whole rig turned and shifted, as an unaligned reconstruction would be: no relative error
    moved = sfm_alignment.transform_world_to_camera(ref.world_to_camera, similarity(0.7, [0.2, 0.9, -0.4], [1.0, 2.0, 3.0]))
    errors = sfm_alignment.pose_errors(dataclasses.replace(ref, world_to_camera=moved), ref)
    assert errors["relative_rotation_error_deg"].max() < 1e-5 and errors["rotation_error_deg"].min() > 10.0
    # one camera turned by 2 degrees about its own centre: 2 degrees against every other view
    w2c = ref.world_to_camera.copy()
    w2c[3, :3, :] = turn @ w2c[3, :3, :]
    angles = sfm_alignment.relative_rotation_errors(w2c[:, :3, :3], ref.world_to_camera[:, :3, :3])
    assert angles.shape == (12, 11)
    np.testing.assert_allclose(angles[3], 2.0, atol=1e-6)
    others = np.delete(angles, 3, axis=0)  # each other view: 2 degrees against view 3, 0 against the rest
    np.testing.assert_allclose(np.sort(others, axis=1)[:, -1], 2.0, atol=1e-6)
    assert np.sort(others, axis=1)[:, -2].max() < 1e-5
    errors = sfm_alignment.pose_errors(dataclasses.replace(ref, world_to_camera=w2c), ref)
    assert errors["relative_rotation_error_deg"][3] == pytest.approx(2.0, abs=1e-6)
    assert errors["relative_rotation_error_deg"].drop(3).max() < 1e-5


def test_pose_errors_accept_a_subset_and_reject_unknown_views():
    ref = make_rig()
    subset = Cameras(ref.K[[2, 7]], ref.world_to_camera[[2, 7]], ref.width, ref.height, ("002", "007"))
    assert list(sfm_alignment.pose_errors(subset, ref)["name"]) == ["002", "007"]
    stranger = dataclasses.replace(subset, names=("002", "999"))
    with pytest.raises(ValueError, match="'999'"):
        sfm_alignment.pose_errors(stranger, ref)


def test_transform_world_to_camera_undoes_a_similarity_and_keeps_projections():
    ref = make_rig()
    S = similarity(0.37, [0.3, -1.1, 0.4], [0.5, -2.0, 1.5])
    est = sfm_alignment.transform_world_to_camera(ref.world_to_camera, np.linalg.inv(S))  # a "reconstruction" frame
    # The same points, expressed in that frame, project to the same pixels.
    points = np.random.default_rng(0).uniform(-0.7, 0.7, size=(20, 3))
    points_est = points @ np.linalg.inv(S)[:3, :3].T + np.linalg.inv(S)[:3, 3]
    for k in (0, 6, 11):
        a, _ = project(points, ref.K[k], ref.world_to_camera[k])
        b, _ = project(points_est, ref.K[k], est[k])
        np.testing.assert_allclose(a, b, atol=1e-9)
    np.testing.assert_allclose(est[:, :3, :3] @ np.swapaxes(est[:, :3, :3], 1, 2), np.repeat(np.eye(3)[None], 12, 0), atol=1e-12)
    back = sfm_alignment.transform_world_to_camera(est, S)
    np.testing.assert_allclose(back, ref.world_to_camera, atol=1e-12)
    errors = sfm_alignment.pose_errors(dataclasses.replace(ref, world_to_camera=back), ref)
    assert errors["rotation_error_deg"].max() < 1e-5 and errors["centre_error_rel"].max() < 1e-12


def test_summarise_medians_and_fraction():
    errors = pd.DataFrame(
        {
            "name": ["a", "b", "c"],
            "rotation_error_deg": [0.1, 0.5, 3.0],
            "centre_error_rel": [0.002, 0.001, 0.05],
            "relative_rotation_error_deg": [0.3, 0.2, 0.9],
            "reprojection_error_px": [0.4, 0.6, np.nan],
        }
    )
    s = sfm_alignment.summarise(errors, 4)
    assert s["registered"] == 3 and s["registered_fraction"] == 0.75
    assert s["median_rotation_error_deg"] == pytest.approx(0.5)
    assert s["median_centre_error_rel"] == pytest.approx(0.002)
    assert s["median_relative_rotation_error_deg"] == pytest.approx(0.3)
    assert s["mean_reprojection_error_px"] == pytest.approx(0.5)
    assert np.isnan(sfm_alignment.summarise(errors.drop(columns="reprojection_error_px"), 3)["mean_reprojection_error_px"])
    with pytest.raises(ValueError, match="3 registered views but only 2"):
        sfm_alignment.summarise(errors, 2)


def test_check_registration_names_counts_and_config_keys():
    sfm.check_registration(23, 24, 0.95)  # 95.8%: enough
    with pytest.raises(sfm.TooFewRegisteredError) as info:
        sfm.check_registration(11, 24, 0.95)
    message = str(info.value)
    assert "11 of 24" in message
    keys = {k.removeprefix("poses.colmap.") for k in message.replace(",", " ").split() if k.startswith("poses.colmap.")}
    assert {"max_num_features", "peak_threshold", "init_min_num_inliers", "abs_pose_min_num_inliers"} <= keys
    assert keys <= {f.name for f in dataclasses.fields(sfm_options.SfmOptions)}
    with pytest.raises(ValueError, match="n_registered 25"):
        sfm.check_registration(25, 24, 0.5)


def test_check_accuracy_gates_on_median_errors_and_names_the_options():
    good = {"median_rotation_error_deg": 0.6, "median_centre_error_rel": 0.008}
    sfm_alignment.check_accuracy(good, 1.0, 0.01)
    for bad in ({**good, "median_rotation_error_deg": 75.0}, {**good, "median_centre_error_rel": 0.2},
                {**good, "median_rotation_error_deg": float("nan")}):
        with pytest.raises(sfm_alignment.InaccuratePosesError) as info:
            sfm_alignment.check_accuracy(bad, 1.0, 0.01)
        message = str(info.value)
        assert "\n" not in message and "poses.colmap.two_view_max_error" in message
        assert "poses.max_median_rotation_deg" in message
    assert "75.00 deg" in str(pytest.raises(sfm_alignment.InaccuratePosesError, sfm_alignment.check_accuracy,
                                           {**good, "median_rotation_error_deg": 75.0}, 1.0, 0.01).value)


def test_poses_no_estimate_uses_are_kept_with_a_warning_when_off(caplog):
    log = logging.getLogger("test_sfm")
    good = {"median_rotation_error_deg": 0.6, "median_centre_error_rel": 0.008}
    assert sfm_alignment.check_accuracy(good, 1.0, 0.01, log=log)
    with caplog.at_level(logging.WARNING, logger="test_sfm"):
        assert not sfm_alignment.check_accuracy({**good, "median_centre_error_rel": 0.0157}, 1.0, 0.01, log=log)
    assert "median centre error 1.57%" in caplog.text and "no estimate uses" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="test_sfm"):
        assert not sfm.check_registration(22, 24, 0.95, log=log) and sfm.check_registration(24, 24, 0.95, log=log)
    assert "registered only 22 of 24" in caplog.text
    with pytest.raises(sfm.TooFewRegisteredError):  # too few to align to the reference, whatever the use
        sfm.check_registration(2, 24, 0.95, log=log)


def test_options_validation_names_the_config_key():
    with pytest.raises(ValueError, match=r"poses\.colmap\.peak_threshold: -0\.1"):
        sfm_options.SfmOptions(peak_threshold=-0.1)
    with pytest.raises(ValueError, match=r"poses\.colmap\.max_num_features: 100\.5 must be an integer"):
        sfm_options.SfmOptions(max_num_features=100.5)
    with pytest.raises(ValueError, match=r"poses\.colmap\.camera_model"):
        sfm_options.SfmOptions(camera_model="FISHEYE")
    with pytest.raises(ValueError, match=r"poses\.colmap\.max_features: unknown option"):
        sfm_options.SfmOptions.from_config({"max_features": 10})
    assert sfm_options.SfmOptions.from_config({"seed": 3}).seed == 3


def test_colmap_defaults_are_pycolmaps_own():
    import pycolmap

    default = sfm_options.SfmOptions.colmap_defaults()
    assert default.init_min_num_inliers == pycolmap.IncrementalMapperOptions().init_min_num_inliers
    assert default.peak_threshold == pytest.approx(pycolmap.SiftExtractionOptions().peak_threshold)
    assert default.max_ratio == pytest.approx(pycolmap.SiftMatchingOptions().max_ratio)
    tuned = sfm_options.SfmOptions()
    assert tuned.peak_threshold < default.peak_threshold
    assert tuned.init_min_num_inliers < default.init_min_num_inliers


# Where each option COLMAP takes unchanged must land ("{pycolmap class}.{attribute path}"),
# written out here independently of sfm_options.COLMAP_ATTRIBUTES, with a value other
# than the tuned default (numbers all distinct, so a swap shows; dyadic, so a
# float32 attribute would hold them exactly).
MAPPED = {
    "max_num_features": (5000, "FeatureExtractionOptions.sift.max_num_features"),
    "first_octave": (1, "FeatureExtractionOptions.sift.first_octave"),
    "num_octaves": (5, "FeatureExtractionOptions.sift.num_octaves"),
    "octave_resolution": (6, "FeatureExtractionOptions.sift.octave_resolution"),
    "peak_threshold": (0.0078125, "FeatureExtractionOptions.sift.peak_threshold"),
    "edge_threshold": (12.5, "FeatureExtractionOptions.sift.edge_threshold"),
    "estimate_affine_shape": (False, "FeatureExtractionOptions.sift.estimate_affine_shape"),
    "domain_size_pooling": (True, "FeatureExtractionOptions.sift.domain_size_pooling"),
    "max_ratio": (0.625, "FeatureMatchingOptions.sift.max_ratio"),
    "max_distance": (0.375, "FeatureMatchingOptions.sift.max_distance"),
    "cross_check": (False, "FeatureMatchingOptions.sift.cross_check"),
    "guided_matching": (True, "FeatureMatchingOptions.guided_matching"),
    "two_view_min_num_inliers": (21, "TwoViewGeometryOptions.min_num_inliers"),
    "two_view_max_error": (2.25, "TwoViewGeometryOptions.ransac.max_error"),
    "two_view_max_num_trials": (3000, "TwoViewGeometryOptions.ransac.max_num_trials"),
    "min_num_matches": (17, "IncrementalPipelineOptions.min_num_matches"),
    "init_min_num_inliers": (40, "IncrementalPipelineOptions.mapper.init_min_num_inliers"),
    "init_min_tri_angle": (9.5, "IncrementalPipelineOptions.mapper.init_min_tri_angle"),
    "abs_pose_min_num_inliers": (13, "IncrementalPipelineOptions.mapper.abs_pose_min_num_inliers"),
    "abs_pose_min_inlier_ratio": (0.4375, "IncrementalPipelineOptions.mapper.abs_pose_min_inlier_ratio"),
    "abs_pose_max_error": (6.75, "IncrementalPipelineOptions.mapper.abs_pose_max_error"),
    "filter_max_reproj_error": (3.5, "IncrementalPipelineOptions.mapper.filter_max_reproj_error"),
    "max_reg_trials": (7, "IncrementalPipelineOptions.mapper.max_reg_trials"),
    "multiple_models": (False, "IncrementalPipelineOptions.multiple_models"),
}


def colmap_settings(options: sfm_options.SfmOptions) -> dict:
    """Every attribute of the pycolmap option objects built from ``options``, "{class}.{path}" -> value."""
    matching, verification = sfm_options.matching_options(options)
    objects = [sfm_options.extraction_options(options), matching, verification, sfm_options.mapping_options(options, Path("images"))]
    settings = {}

    def walk(prefix: str, values: dict) -> None:
        for key, value in values.items():
            if isinstance(value, dict):
                walk(f"{prefix}.{key}", value)
            else:
                settings[f"{prefix}.{key}"] = value

    for obj in objects:
        walk(type(obj).__name__, obj.todict())
    return settings


def changed_settings(options: sfm_options.SfmOptions) -> dict:
    """The pycolmap settings of ``options`` that differ from those of the tuned defaults."""
    before, after = colmap_settings(sfm_options.SfmOptions()), colmap_settings(options)
    assert before.keys() == after.keys()
    return {key: value for key, value in after.items() if value != before[key]}


def pycolmap_default(path: str):
    """COLMAP's default of "{class}.{attribute path}"."""
    import pycolmap

    owner, *steps = path.split(".")
    value = getattr(pycolmap, owner)()
    for step in steps:
        value = getattr(value, step)
    return value


def test_every_option_field_reaches_colmap_or_is_set_explicitly():
    names = [f.name for f in dataclasses.fields(sfm_options.SfmOptions)]
    mapped, explicit = set(sfm_options.COLMAP_ATTRIBUTES), set(sfm_options.SET_EXPLICITLY)
    assert mapped.isdisjoint(explicit) and sorted(mapped | explicit) == sorted(names)
    assert set(MAPPED) == mapped  # this file's own list covers every mapped field
    numbers = [value for value, _ in MAPPED.values() if not isinstance(value, bool)]
    assert len(set(numbers)) == len(numbers)


def test_non_default_options_land_on_their_pycolmap_attributes_and_nowhere_else():
    options = sfm_options.SfmOptions(**{name: value for name, (value, _) in MAPPED.items()})
    assert all(getattr(options, name) != getattr(sfm_options.SfmOptions(), name) for name in MAPPED)
    assert changed_settings(options) == {path: value for value, path in MAPPED.values()}


@pytest.mark.parametrize("name", sorted(MAPPED))
def test_each_mapped_option_changes_only_its_own_pycolmap_attribute(name):
    value, path = MAPPED[name]  # one at a time, so two booleans swapped in the table show too
    assert changed_settings(sfm_options.SfmOptions(**{name: value})) == {path: value}


def test_options_set_explicitly_reach_colmap():
    options = sfm_options.SfmOptions(seed=7, num_threads=3, known_intrinsics=False, two_view_max_num_trials=40)
    settings = colmap_settings(options)
    for owner in ("FeatureExtractionOptions", "FeatureMatchingOptions", "IncrementalPipelineOptions"):
        assert settings[f"{owner}.num_threads"] == 3
    assert settings["TwoViewGeometryOptions.ransac.random_seed"] == settings["IncrementalPipelineOptions.random_seed"] == 7
    assert settings["TwoViewGeometryOptions.ransac.min_num_trials"] == 40  # capped by max_num_trials
    refine = [f"IncrementalPipelineOptions.ba_refine_{what}" for what in ("focal_length", "extra_params")]
    assert all(settings[key] for key in refine)
    fixed = colmap_settings(sfm_options.SfmOptions())
    assert not any(fixed[key] for key in refine) and not fixed["IncrementalPipelineOptions.ba_refine_principal_point"]
    floor = "TwoViewGeometryOptions.ransac.min_num_trials"
    assert fixed[floor] == pycolmap_default(floor)  # the cap 2000 is above COLMAP's floor
    assert not fixed["FeatureExtractionOptions.use_gpu"] and not fixed["FeatureMatchingOptions.use_gpu"]


def test_a_pycolmap_attribute_that_is_missing_is_named_with_its_field(monkeypatch):
    monkeypatch.setitem(sfm_options.COLMAP_ATTRIBUTES, "peak_threshold", "FeatureExtractionOptions.sift.peak_treshold")
    named = r"poses\.colmap\.peak_threshold maps onto pycolmap\.FeatureExtractionOptions\.sift\.peak_treshold"
    with pytest.raises(AttributeError, match=named):
        sfm_options.extraction_options(sfm_options.SfmOptions())
    monkeypatch.undo()
    monkeypatch.setitem(sfm_options.COLMAP_ATTRIBUTES, "max_reg_trials", "IncrementalPipelineOptions.mappr.max_reg_trials")
    named = r"poses\.colmap\.max_reg_trials .* no attribute 'mappr' on IncrementalPipelineOptions"
    with pytest.raises(AttributeError, match=named):
        sfm_options.SfmOptions.colmap_defaults()


def write_random_capture(capture, n: int, size: int, seed: int = 1):
    """A capture of unrelated random views with an 8 x 7 object block (plus one partly covered pixel)."""
    cams = make_rig(n=n, size=size)
    rng = np.random.default_rng(seed)
    images, coverages = [], []
    for name in cams.names:
        hdr = rng.uniform(0.0, 3.0, size=(size, size, 3)).astype(np.float32)
        coverage = np.zeros((size, size), np.uint8)
        coverage[4:12, 3:10] = 255
        coverage[4, 10] = 17
        write_exr(capture / "images" / f"{name}.exr", hdr)
        write_png(capture / "masks" / f"{name}.png", coverage)
        images.append(hdr)
        coverages.append(coverage)
    write_json(capture / "cameras.json", cameras_to_json(cams))
    return cams, images, coverages


def test_sfm_images_writes_tone_mapped_views_and_colmap_masks(tmp_path):
    capture = tmp_path / "capture"
    _, images, coverages = write_random_capture(capture, n=2, size=16)

    out = tmp_path / "colmap"
    names = sfm.sfm_images(capture, out, mask_background=True)
    assert names == ["000.png", "001.png"]
    for name, hdr, coverage in zip(names, images, coverages):
        png = read_png(out / "images" / name)
        np.testing.assert_array_equal(png, np.round(tonemap(hdr) * 255).astype(np.uint8))
        mask = read_png(out / "masks" / f"{name}.png")  # COLMAP's layout: image name + ".png"
        np.testing.assert_array_equal(mask, np.where(coverage > 0, 255, 0))
    sfm.sfm_images(capture, tmp_path / "eroded", mask_background=True, mask_erosion_px=1)
    eroded = read_png(tmp_path / "eroded" / "masks" / "000.png.png")
    assert (eroded > 0).sum() == 6 * 5  # the 8 x 7 block loses one pixel on each side

    sfm.sfm_images(capture, tmp_path / "nomask", mask_background=False, denoise_sigma=1.0)
    assert not (tmp_path / "nomask" / "masks").exists()
    blurred = read_png(tmp_path / "nomask" / "images" / "000.png").astype(float)
    assert blurred.std() < read_png(out / "images" / "000.png").astype(float).std()


def test_reconstruct_without_matches_raises_too_few_registered(tmp_path):
    capture = tmp_path / "capture"
    cams, _, _ = write_random_capture(capture, n=3, size=64)
    with pytest.raises(sfm.TooFewRegisteredError, match="registered 0 of 3 views") as info:
        sfm.reconstruct(capture, tmp_path / "work", cams, sfm_options.SfmOptions())
    assert "colmap.log" in str(info.value) and "poses.colmap.peak_threshold" in str(info.value)
    # With use_mask, COLMAP extracts features inside the object mask only.
    import pycolmap

    with pytest.raises(sfm.TooFewRegisteredError):
        sfm.reconstruct(capture, tmp_path / "masked", cams, sfm_options.SfmOptions(use_mask=True))
    db = pycolmap.Database.open(tmp_path / "masked" / "database.db")
    try:
        xy = np.concatenate([db.read_keypoints(image.image_id)[:, :2] for image in db.read_all_images()])
    finally:
        db.close()
    assert len(xy) > 0
    assert np.all((xy[:, 0] >= 3) & (xy[:, 0] <= 11) & (xy[:, 1] >= 4) & (xy[:, 1] <= 12))
    with pytest.raises(ValueError, match="is the capture directory"):
        sfm.reconstruct(capture, capture, cams, sfm_options.SfmOptions())
    assert (capture / "images" / "000.exr").is_file()


# --------------------------------------------------------------------------- COLMAP on a rendered capture

VIEWS, SIZE, SPP = 20, 256, 32


@pytest.fixture(scope="module")
def capture(mi, tmp_path_factory):
    """A sphere with a fine diffuse texture (SIFT needs one) in the studio, 20 views."""
    from freqbrdf.scene.envmaps import studio
    from freqbrdf.scene.meshes import make_mesh
    from freqbrdf.scene.ply import write_ply
    from freqbrdf.scene.render import capture_scene, mask_scene, principled_bsdf, render_views

    out = tmp_path_factory.mktemp("capture")
    mesh = out / "sphere.ply"
    write_ply(mesh, make_mesh("sphere"))
    rng = np.random.default_rng(3)
    pattern = gaussian_filter(rng.random((256, 256, 3)), (1.5, 1.5, 0), mode="wrap")
    pattern = (pattern - pattern.min()) / (pattern.max() - pattern.min())
    bsdf = principled_bsdf(
        mi,
        base_color=(0.1 + 0.8 * pattern).astype(np.float32),
        roughness=np.full((256, 256), 0.7, np.float32),
        metallic=np.zeros((256, 256), np.float32),
    )
    cams = make_rig(VIEWS, SIZE)
    to_world = np.stack([mitsuba_to_world(m) for m in cams.world_to_camera])
    frame = dict(width=SIZE, height=SIZE, fov_x_deg=35.0)
    scene = capture_scene(mi, mesh, bsdf, studio(64, seed=1), spp=SPP, max_depth=3, **frame)
    for name, image in zip(cams.names, render_views(mi, scene, to_world, seed=0)):
        write_exr(out / "images" / f"{name}.exr", image)
    for name, coverage in zip(cams.names, render_views(mi, mask_scene(mi, mesh, spp=4, **frame), to_world, seed=0)):
        write_png(out / "masks" / f"{name}.png", coverage[..., 0])
    write_json(out / "cameras.json", cameras_to_json(cams))
    return out, cams


@pytest.fixture(scope="module")
def reconstruction(capture, tmp_path_factory):
    path, cams = capture
    work = tmp_path_factory.mktemp("sfm")
    return sfm.reconstruct(path, work, cams, sfm_options.SfmOptions()), work


def test_sfm_registers_the_capture_accurately(capture, reconstruction):
    _, ref = capture
    rec, work = reconstruction
    estimated, S = sfm_alignment.aligned_cameras(rec, ref)
    errors = sfm_alignment.pose_errors(estimated, ref, sfm_alignment.reprojection_errors(rec))
    summary = sfm_alignment.summarise(errors, len(ref))
    assert summary["registered_fraction"] >= 0.9, summary
    assert summary["median_rotation_error_deg"] < 1.0, summary
    assert summary["median_centre_error_rel"] < 0.015, summary
    assert 0.0 < summary["mean_reprojection_error_px"] < 1.0, summary
    # Known intrinsics are held fixed.
    np.testing.assert_allclose(estimated.K, ref.K[[ref.names.index(n) for n in estimated.names]], rtol=1e-12)
    assert np.linalg.det(S[:3, :3]) > 0 and S[3].tolist() == [0, 0, 0, 1]
    sfm.check_registration(summary["registered"], len(ref), 0.9)
    # COLMAP's own log went to the file.
    assert "Feature extraction" in (work / "colmap.log").read_text()


def test_alignment_undoes_a_known_similarity_of_the_reconstruction(capture, reconstruction):
    import pycolmap

    _, ref = capture
    rec, _ = reconstruction
    cams, S = sfm_alignment.aligned_cameras(rec, ref)
    T = similarity(2.5, [0.2, 0.9, -0.4], [3.0, -1.0, 0.5])
    moved = pycolmap.Reconstruction(rec)
    moved.transform(pycolmap.Sim3d(T[:3, :]))
    cams2, S2 = sfm_alignment.aligned_cameras(moved, ref)
    assert cams2.names == cams.names
    np.testing.assert_allclose(cams2.world_to_camera, cams.world_to_camera, atol=1e-6)
    np.testing.assert_allclose(S2 @ T, S, atol=1e-6)


def test_reconstruct_is_repeatable_quiet_and_logs_phases(capture, reconstruction, tmp_path, capfd, caplog):
    path, ref = capture
    rec, _ = reconstruction
    log = logging.getLogger("test_sfm")
    with caplog.at_level(logging.INFO, logger="test_sfm"):
        again = sfm.reconstruct(path, tmp_path, ref, sfm_options.SfmOptions(), log=log)
    assert sorted(sfm_alignment.registered_poses(rec)) == sorted(sfm_alignment.registered_poses(again))
    # Usually bit-identical; COLMAP's thread scheduling has moved an entry of the
    # unaligned pose by up to 2.4e-2 (sfm module docstring), partly a change of the
    # reconstruction's gauge. So compare what the pipeline uses, the cameras aligned
    # to the reference: a wrong registration turns a view by order 1 and moves its
    # centre by the order of the camera distance.
    first, second = sfm_alignment.aligned_cameras(rec, ref)[0], sfm_alignment.aligned_cameras(again, ref)[0]
    assert first.names == second.names
    np.testing.assert_allclose(first.world_to_camera[:, :3, :3], second.world_to_camera[:, :3, :3], rtol=0, atol=0.02)
    distance = np.median(np.linalg.norm(ref.centres, axis=1))
    assert np.linalg.norm(first.centres - second.centres, axis=1).max() < 0.02 * distance
    out, err = capfd.readouterr()
    assert "feature_extraction" not in out + err and "incremental" not in out + err
    messages = " | ".join(r.getMessage() for r in caplog.records)
    for phase in ("tone-mapped", "SIFT", "matching", "incremental mapping"):
        assert phase in messages
    json.dumps(sfm_alignment.summarise(sfm_alignment.pose_errors(sfm_alignment.aligned_cameras(again, ref)[0], ref), len(ref)))  # JSON-ready
