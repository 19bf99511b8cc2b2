"""Rendering against analytic values: radiometry, camera and texture conventions."""

import numpy as np
import pytest

from freqbrdf.scene.cameras import Cameras, hemisphere_rig, intrinsics, look_at, mitsuba_to_world, project
from freqbrdf.scene.meshes import make_mesh
from freqbrdf.scene.ply import write_ply
from freqbrdf.scene.render import (
    capture_bsdf,
    eval_environment,
    capture_scene,
    occluder_disk,
    mask_scene,
    principled_bsdf,
    relit_views,
    render_views,
    sunsky,
)
from freqbrdf.sphere.sampling import equirect_directions

SIZE = 64
FOV = 35.0


@pytest.fixture(scope="module")
def sphere_ply(tmp_path_factory):
    path = tmp_path_factory.mktemp("mesh") / "sphere.ply"
    write_ply(path, make_mesh("sphere"))
    return path


def _render(mi, scene, w2c, seed=0):
    return next(render_views(mi, scene, mitsuba_to_world(w2c)[None], seed=seed))


def test_white_lambertian_sphere_under_unit_environment_renders_one(mi, sphere_ply):
    # A convex white Lambertian surface under uniform radiance 1 reflects exactly 1.
    white = {"type": "diffuse", "reflectance": {"type": "rgb", "value": 1.0}}
    env = np.ones((32, 64, 3), np.float32)
    w2c = look_at(np.array([0.5, 1.5, 3.5]))
    scene = capture_scene(mi, sphere_ply, white, env, width=SIZE, height=SIZE, fov_x_deg=FOV, spp=256, max_depth=8)
    image = _render(mi, scene, w2c)
    coverage = _render(mi, mask_scene(mi, sphere_ply, width=SIZE, height=SIZE, fov_x_deg=FOV, spp=16), w2c)[..., 0]
    inside = coverage > 0.999
    assert inside.sum() > 500
    assert abs(image[inside].mean() - 1.0) < 0.02
    assert np.percentile(np.abs(image[inside] - 1.0), 90) < 0.05


def test_mask_area_matches_projected_sphere(mi, sphere_ply):
    # A unit sphere seen head-on from distance d projects to a disc of radius f tan(asin(1/d)).
    d = 4.0
    w2c = look_at(np.array([0.0, 0.0, d]))
    coverage = _render(mi, mask_scene(mi, sphere_ply, width=128, height=128, fov_x_deg=FOV, spp=64), w2c)[..., 0]
    f = intrinsics(128, 128, FOV)[0, 0]
    expected = np.pi * (f * np.tan(np.arcsin(1.0 / d))) ** 2
    assert coverage.sum() == pytest.approx(expected, rel=0.02)
    assert coverage.min() >= 0.0 and coverage.max() <= 1.0


def test_projection_matches_mitsuba_for_off_centre_point(mi):
    # Mitsuba's depth AOV marks where a small off-centre ball is; our OpenCV
    # projection of its centre must land there (tests axis signs and K).
    centre = np.array([0.6, 0.25, -0.2])
    scene = mi.load_dict(
        {
            "type": "scene",
            "ball": {"type": "sphere", "center": centre.tolist(), "radius": 0.05},
            "sensor": {
                "type": "perspective",
                "fov": FOV,
                "fov_axis": "x",
                "to_world": mi.ScalarTransform4f(),
                "film": {"type": "hdrfilm", "width": 128, "height": 96, "rfilter": {"type": "box"}},
                "sampler": {"type": "independent", "sample_count": 16},
            },
        }
    )
    aov = mi.load_dict({"type": "aov", "aovs": "dd:depth"})
    w2c = look_at(np.array([0.5, 1.2, 3.0]), target=np.array([0.1, 0.0, 0.0]))
    params = mi.traverse(scene)
    params["sensor.to_world"] = mi.ScalarTransform4f(mitsuba_to_world(w2c))
    params.update()
    depth = np.array(mi.render(scene, params=params, integrator=aov))[..., 0]
    rows, cols = np.nonzero(depth > 0)
    pixels, _ = project(centre[None], intrinsics(128, 96, FOV), w2c)
    px, py = pixels[0]
    # The centroid of a small ball's silhouette is its projected centre to well under a pixel.
    assert abs(cols.mean() + 0.5 - px) < 0.3
    assert abs(rows.mean() + 0.5 - py) < 0.3
    assert abs(px - 64) > 10 and abs(py - 48) > 5  # genuinely off-centre


def test_object_centre_projects_to_image_centre_in_every_view():
    K = intrinsics(256, 256, FOV)
    for w2c in hemisphere_rig(24, 4.0):
        pixels, depth = project(np.zeros((1, 3)), K, w2c)
        np.testing.assert_allclose(pixels[0], [128.0, 128.0], atol=1e-9)
        assert depth[0] == pytest.approx(4.0)


def test_texture_lookup_follows_documented_uv_convention(mi, sphere_ply):
    # Under uniform radiance 1 a convex diffuse surface shows its albedo, so the
    # rendered colour at a pixel must equal our bilinear lookup of the texture
    # at the uv Mitsuba reports for that pixel.
    res = 64
    jj, ii = np.meshgrid(np.arange(res), np.arange(res))
    u, v = (jj + 0.5) / res, (ii + 0.5) / res
    base = np.stack([0.2 + 0.6 * u, 0.2 + 0.6 * v, 0.5 + 0.3 * np.sin(2 * np.pi * u)], axis=-1)
    bsdf = {"type": "diffuse", "reflectance": principled_bsdf(mi, base, base[..., 0], base[..., 0])["base_color"]}
    env = np.ones((32, 64, 3), np.float32)
    w2c = look_at(np.array([1.0, 2.0, 3.0]))
    scene = capture_scene(mi, sphere_ply, bsdf, env, width=SIZE, height=SIZE, fov_x_deg=FOV, spp=256, max_depth=2)
    image = _render(mi, scene, w2c)
    params = mi.traverse(scene)
    aov = mi.load_dict({"type": "aov", "aovs": "uv:uv"})
    uv_img = np.array(mi.render(scene, params=params, integrator=aov, spp=64))
    coverage = _render(mi, mask_scene(mi, sphere_ply, width=SIZE, height=SIZE, fov_x_deg=FOV, spp=16), w2c)[..., 0]
    inside = coverage > 0.999
    uu, vv = uv_img[inside][:, 0], uv_img[inside][:, 1]
    expected = np.stack([0.2 + 0.6 * uu, 0.2 + 0.6 * vv], axis=-1)
    error = np.abs(image[inside][:, :2] - expected)
    assert inside.sum() > 1000
    # Pixels straddling the u seam average uv across it, hence percentiles; a
    # flipped or half-texel-shifted convention fails by far more than this.
    assert np.median(error) < 0.01
    assert np.percentile(error, 95) < 0.03


def test_equirect_grid_matches_mitsuba_envmap(mi):
    # At our pixel directions, Mitsuba's envmap returns exactly the pixel values.
    rng = np.random.default_rng(1)
    env = rng.uniform(0.1, 1.0, size=(16, 32, 3)).astype(np.float32)
    scene = mi.load_dict({"type": "scene", "env": {"type": "envmap", "bitmap": mi.Bitmap(env)}})
    dirs = equirect_directions(16, 32)[1:-1].reshape(-1, 3)  # the pole rows are single points
    np.testing.assert_allclose(eval_environment(mi, scene, dirs), env[1:-1].reshape(-1, 3), rtol=1e-4)


def test_sunsky_puts_the_sun_where_asked(mi):
    from freqbrdf.scene.envmaps import direction_from_angles

    sun = direction_from_angles(30.0, 120.0)
    sky = sunsky(mi, 64, sun, turbidity=3.0)
    grid = equirect_directions(64, 128)
    brightest = grid.reshape(-1, 3)[sky[..., 1].argmax()]
    assert np.degrees(np.arccos(brightest @ sun)) < 2.0 * 180.0 / 63
    assert sky[grid[..., 1] < -0.05].max() == 0.0  # nothing below the horizon before the ground is added


def test_relit_views_reproduce_the_reference_render_of_the_same_textures_and_seed(mi, sphere_ply):
    # Relighting scores rest on this: true textures relit with the reference's
    # seed give the reference image exactly, and another seed does not.
    rng = np.random.default_rng(3)
    textures = {"base_color": rng.uniform(size=(16, 16, 3)).astype(np.float32),
                "roughness": rng.uniform(0.2, 1.0, size=(16, 16)).astype(np.float32),
                "metallic": rng.uniform(size=(16, 16)).astype(np.float32)}
    env = np.random.default_rng(4).uniform(0.2, 2.0, size=(16, 32, 3)).astype(np.float32)
    w2c = hemisphere_rig(2, 3.5)
    cameras = Cameras(K=np.stack([intrinsics(SIZE, SIZE, FOV)] * 2), world_to_camera=w2c, width=SIZE, height=SIZE,
                      names=("a", "b"))
    scene = capture_scene(mi, sphere_ply, principled_bsdf(mi, **textures), env, width=SIZE, height=SIZE,
                          fov_x_deg=FOV, spp=4, max_depth=3)
    reference = list(render_views(mi, scene, np.stack([mitsuba_to_world(m) for m in w2c]), seed=7))
    settings = dict(fov_x_deg=FOV, spp=4, max_depth=3)
    relit = list(relit_views(mi, sphere_ply, textures, env, cameras, seed=7, **settings))
    other = list(relit_views(mi, sphere_ply, textures, env, cameras, seed=8, **settings))
    assert len(relit) == 2 and relit[0].shape == (SIZE, SIZE, 3)
    for ref, same, noisy in zip(reference, relit, other):
        np.testing.assert_array_equal(same, ref)
        assert np.abs(noisy - ref).max() > 1e-3


def _eval_bsdf(mi, bsdf_dict, wo):
    """Mitsuba's BSDF value (times cos theta_o) for light from ``wo`` seen along the normal, at uv (0.5, 0.5)."""
    import drjit as dr

    bsdf = mi.load_dict(bsdf_dict)
    si = dr.zeros(mi.SurfaceInteraction3f)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    si.wi = mi.Vector3f(0, 0, 1)
    si.uv = mi.Point2f(0.5, 0.5)
    return np.array(bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(*map(float, wo)))).ravel()


@pytest.mark.parametrize("distribution", ["ggx", "beckmann"])
def test_blend_metal_peak_matches_the_microfacet_normalisation(mi, distribution):
    # At normal incidence and reflection the half vector is the normal, where both
    # distributions have D = 1 / (pi alpha^2); G = 1 and F = 1 (no Fresnel), so f cos = base / (4 pi alpha^2).
    roughness, base = 0.5, np.array([0.9, 0.5, 0.2])
    textures = dict(base_color=np.broadcast_to(base, (4, 4, 3)).copy(), roughness=np.full((4, 4), roughness),
                    metallic=np.ones((4, 4)))
    value = _eval_bsdf(mi, capture_bsdf(mi, textures, f"{distribution}_blend"), (0.0, 0.0, 1.0))
    np.testing.assert_allclose(value, base / (4 * np.pi * roughness**4), rtol=1e-3)


def test_beckmann_and_ggx_blends_differ_as_their_distributions_do(mi):
    # Off the peak (half vector 15 degrees from the normal) the two lobes differ by the
    # ratio of their normal distributions; shadowing is within 1% of 1 at these angles.
    alpha, theta_h = 0.3, np.radians(15.0)
    textures = dict(base_color=np.ones((4, 4, 3)), roughness=np.full((4, 4), np.sqrt(alpha)), metallic=np.ones((4, 4)))
    wo = (np.sin(2 * theta_h), 0.0, np.cos(2 * theta_h))
    ggx = _eval_bsdf(mi, capture_bsdf(mi, textures, "ggx_blend"), wo)[0]
    beckmann = _eval_bsdf(mi, capture_bsdf(mi, textures, "beckmann_blend"), wo)[0]
    t2, c4 = np.tan(theta_h) ** 2, np.cos(theta_h) ** 4
    d_ggx = alpha**2 / (np.pi * c4 * (alpha**2 + t2) ** 2)
    d_beckmann = np.exp(-t2 / alpha**2) / (np.pi * alpha**2 * c4)
    assert beckmann / ggx == pytest.approx(d_beckmann / d_ggx, rel=0.02)
    assert d_beckmann / d_ggx > 1.3  # a visible mismatch, not a rounding difference


def test_capture_bsdf_rejects_unknown_models_and_a_clear_coat_on_a_blend(mi):
    textures = dict(base_color=np.ones((4, 4, 3)), roughness=np.full((4, 4), 0.5), metallic=np.zeros((4, 4)))
    with pytest.raises(ValueError, match="phong"):
        capture_bsdf(mi, textures, "phong")
    with pytest.raises(ValueError, match="clear coat"):
        capture_bsdf(mi, textures, "beckmann_blend", clearcoat=0.5)
    assert capture_bsdf(mi, textures, "principled", clearcoat=0.5)["clearcoat"] == 0.5


def test_occluder_disk_darkens_a_white_sphere_by_the_light_it_blocks(mi, sphere_ply):
    # Under unit radiance a convex white Lambertian point reflects 1 minus the cosine-weighted
    # share of its sky the disk hides: blocked_light, computed independently of Mitsuba.
    from freqbrdf.studies.stress import blocked_light

    white = {"type": "diffuse", "reflectance": {"type": "rgb", "value": 1.0}}
    env = np.ones((32, 64, 3), np.float32)
    height, radius = -1.3, 1.5
    eye = np.array([0.0, -0.5, 4.0])
    w2c = look_at(eye)
    scene = capture_scene(mi, sphere_ply, white, env, width=SIZE, height=SIZE, fov_x_deg=FOV, spp=256, max_depth=8,
                          occluders=[occluder_disk(mi, height, radius)])
    image = _render(mi, scene, w2c)[..., 0]
    coverage = _render(mi, mask_scene(mi, sphere_ply, width=SIZE, height=SIZE, fov_x_deg=FOV, spp=16), w2c)[..., 0]
    # Where each pixel centre's ray meets the unit sphere (its normal too).
    rows, cols = np.nonzero(coverage > 0.999)
    rays = np.linalg.inv(intrinsics(SIZE, SIZE, FOV)) @ np.stack([cols + 0.5, rows + 0.5, np.ones(len(rows))])
    dirs = (w2c[:3, :3].T @ rays).T
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    b = dirs @ eye
    points = eye + (-b - np.sqrt(b**2 - (eye @ eye - 1.0)))[:, None] * dirs
    expected = 1.0 - blocked_light(points, points, env, height, radius, directions=8192)
    assert expected.min() < 0.6  # the disk shadows part of what the camera sees
    assert np.median(np.abs(image[rows, cols] - expected)) < 0.02
    assert np.percentile(np.abs(image[rows, cols] - expected), 90) < 0.06
