"""Per-texel observations against Mitsuba and analytic values."""

import functools

import numpy as np
import pytest

from freqbrdf.scene.cameras import Cameras, hemisphere_rig, intrinsics, look_at, mitsuba_to_world, project
from freqbrdf.scene.meshes import make_mesh
from freqbrdf.scene.ply import write_ply
from freqbrdf.capture.observations import (
    band_limit_parameter,
    band_limited_envmap,
    bilinear_views,
    edge_free_distances,
    observe,
    rasterise_uv,
    sample_equirect,
    tangent_frame,
    view_geometry,
)
from freqbrdf.scene.raycast import distance_maps, mesh_scene, occlusion_test
from freqbrdf.scene.render import eval_environment, mask_scene, render_views
from freqbrdf.sphere.sh import eval_sh, sh_degrees
from freqbrdf.sphere.sampling import equirect_directions, fibonacci_sphere

SIZE, FOV = 128, 35.0


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    root = tmp_path_factory.mktemp("obs")
    out = {}
    for name in ("sphere", "torus", "die"):
        mesh = make_mesh(name)
        write_ply(root / f"{name}.ply", mesh)
        out[name] = (mesh, root / f"{name}.ply")
    return out


def _cameras(w2c: np.ndarray) -> Cameras:
    return Cameras(K=np.repeat(intrinsics(SIZE, SIZE, FOV)[None], len(w2c), 0), world_to_camera=w2c,
                   width=SIZE, height=SIZE, names=tuple(f"{k:03d}" for k in range(len(w2c))))


def _aov(mi, ply, w2c, aovs, spp=16):
    scene = mi.load_dict({
        "type": "scene", "object": {"type": "ply", "filename": str(ply)},
        "sensor": {"type": "perspective", "fov": FOV, "fov_axis": "x", "to_world": mi.ScalarTransform4f(mitsuba_to_world(w2c)),
                   "film": {"type": "hdrfilm", "width": SIZE, "height": SIZE, "rfilter": {"type": "box"}},
                   "sampler": {"type": "independent", "sample_count": spp}},
    })
    return np.array(mi.render(scene, integrator=mi.load_dict({"type": "aov", "aovs": aovs})))


def _observe_linear(mi, mesh, ply, cameras, resolution=128):
    """Observe with images whose channels are the pixel coordinates (exact under bilinear)."""
    texels = rasterise_uv(mesh, resolution)
    jj, ii = np.meshgrid(np.arange(SIZE) + 0.5, np.arange(SIZE) + 0.5)
    images = np.repeat(np.stack([jj, ii, np.zeros_like(jj)], -1)[None], len(cameras), 0).astype(np.float32)
    coverage = np.stack([
        _render_single(mi, mask_scene(mi, ply, width=SIZE, height=SIZE, fov_x_deg=FOV, spp=16), w2c)[..., 0]
        for w2c in cameras.world_to_camera
    ])
    scene = mesh_scene(mi, ply)
    occluded = functools.partial(occlusion_test, mi, scene)
    distances = edge_free_distances(distance_maps(mi, scene, cameras.K, cameras.world_to_camera, SIZE, SIZE))
    obs = observe(texels, cameras, images, coverage, np.ones((8, 16, 3), np.float32), occluded, distances=distances)
    return texels, obs, coverage


def _render_single(mi, scene, w2c):
    return next(render_views(mi, scene, mitsuba_to_world(w2c)[None], seed=0))


def test_observed_texels_land_on_mitsubas_surface_points(mi, meshes):
    # Mitsuba's position AOV at the pixel where a texel projects must be that
    # texel's own surface point, so re-projecting it lands within half a pixel.
    mesh, ply = meshes["torus"]
    w2c = look_at(np.array([2.2, 1.2, 3.0]))
    texels, obs, _ = _observe_linear(mi, mesh, ply, _cameras(w2c[None]))
    seen = obs["weight"][:, 0] > 0
    assert seen.sum() > 2000
    positions = _aov(mi, ply, w2c, "p:position")
    pix, _ = project(texels.position[seen], intrinsics(SIZE, SIZE, FOV), w2c)
    aov_points, _ = bilinear_views(positions[None], np.zeros(seen.sum(), int), pix[:, 0], pix[:, 1])
    reproj, _ = project(aov_points, intrinsics(SIZE, SIZE, FOV), w2c)
    error = np.linalg.norm(reproj - pix, axis=1)
    assert np.median(error) < 0.5
    assert np.percentile(error, 90) < 1.0


def test_radiance_is_the_bilinear_pixel_at_the_texel_projection(mi, meshes):
    mesh, ply = meshes["sphere"]
    cams = _cameras(hemisphere_rig(3, 4.0))
    texels, obs, _ = _observe_linear(mi, mesh, ply, cams)
    for k in range(len(cams)):
        seen = obs["weight"][:, k] > 0
        pix, _ = project(texels.position[seen], cams.K[k], cams.world_to_camera[k])
        np.testing.assert_allclose(obs["radiance"][seen, k, :2], pix, atol=1e-3)
        assert (obs["radiance"][~seen, k] == 0).all()


def test_hidden_texels_are_never_observed(mi, meshes):
    for name, eye in (("sphere", [0.0, 0.5, 4.0]), ("torus", [0.3, 1.0, 3.9])):
        mesh, ply = meshes[name]
        w2c = look_at(np.array(eye))
        cams = _cameras(w2c[None])
        texels, obs, _ = _observe_linear(mi, mesh, ply, cams)
        seen = obs["weight"][:, 0] > 0
        centre = cams.centres[0]
        back = np.einsum("tc,tc->t", texels.normal, centre - texels.position) < 0
        assert back.sum() > 1000 and not (seen & back).any()  # the far side
        # Front-facing texels with another surface between them and the camera,
        # according to Mitsuba's hit points at their pixel (the inside of the torus behind its tube).
        hits = _aov(mi, ply, w2c, "p:position", spp=64)
        pix, _ = project(texels.position, cams.K[0], w2c)
        inside = (pix >= 0).all(1) & (pix < SIZE).all(1)
        px, py = np.clip(pix.astype(int), 0, SIZE - 1).T
        seen_distance = np.linalg.norm(hits[py, px] - centre, axis=1)
        own_distance = np.linalg.norm(texels.position - centre, axis=1)
        covered = np.abs(hits[py, px]).sum(axis=1) > 0
        hidden = inside & ~back & covered & (seen_distance < own_distance - 0.1)
        if name == "torus":
            assert hidden.sum() > 500
        assert (seen & hidden).sum() == 0


def test_nonfinite_pixels_are_masked_and_counted(mi, meshes):
    mesh, ply = meshes["sphere"]
    cams = _cameras(hemisphere_rig(1, 4.0))
    texels = rasterise_uv(mesh, 64)
    images = np.ones((1, SIZE, SIZE, 3), np.float32)
    images[0, 60:64, 60:64] = np.nan
    coverage = np.ones((1, SIZE, SIZE), np.float32)
    occluded = functools.partial(occlusion_test, mi, mesh_scene(mi, ply))
    obs = observe(texels, cams, images, coverage, np.ones((8, 16, 3), np.float32), occluded)
    assert obs["nonfinite"] > 0
    assert np.isfinite(obs["radiance"]).all()
    pix, _ = project(texels.position, cams.K[0], cams.world_to_camera[0])
    near_nan = (np.abs(pix - 62).max(axis=1) < 2.5) & (obs["weight"][:, 0] >= 0)
    assert near_nan.sum() > 0 and (obs["weight"][near_nan, 0] == 0).all()


def test_observation_arrays_are_consistent(mi, meshes):
    mesh, ply = meshes["torus"]
    cams = _cameras(hemisphere_rig(4, 4.0))
    texels, obs, _ = _observe_linear(mi, mesh, ply, cams, resolution=64)
    wo = obs["wo_local"]
    np.testing.assert_allclose(np.linalg.norm(wo, axis=-1), 1.0, atol=1e-5)
    seen = obs["weight"] > 0
    np.testing.assert_allclose(obs["weight"][seen], wo[..., 2][seen], atol=1e-5)  # weight is cos(theta_o)
    assert (wo[..., 2][seen] > 0).all()


def test_rasterised_sphere_texels_lie_on_the_sphere_at_their_uv(meshes):
    mesh, _ = meshes["sphere"]
    texels = rasterise_uv(mesh, 128)
    assert len(texels) > 0.97 * 128 * 128
    np.testing.assert_allclose(np.linalg.norm(texels.position, axis=1), 1.0, atol=2e-3)
    np.testing.assert_allclose(np.linalg.norm(texels.normal, axis=1), 1.0, atol=1e-9)
    assert np.einsum("tc,tc->t", texels.normal, texels.position).min() > 0.99
    # polar angle of the point follows v of the texel (sphere atlas: v = theta / pi)
    i = texels.texel // 128
    theta = np.arccos(np.clip(texels.position[:, 1], -1, 1))
    interior = ~texels.dilated
    np.testing.assert_allclose(theta[interior] / np.pi, (i[interior] + 0.5) / 128, atol=1.5 / 128)


def test_dilation_adds_a_ring_around_charts(meshes):
    mesh, _ = meshes["die"]
    plain = rasterise_uv(mesh, 128, dilate_texels=0.0)
    dilated = rasterise_uv(mesh, 128, dilate_texels=1.0)
    assert not plain.dilated.any()
    assert set(plain.texel) < set(dilated.texel)
    ring = dilated.dilated
    assert ring.sum() > 6 * 4 * 30  # each of the six square charts gains a border
    # border texels take points on the surface, next to their chart's edge
    from scipy.spatial import cKDTree

    gap, _ = cKDTree(mesh.vertices).query(dilated.position[ring])
    assert gap.max() < 0.05


@pytest.mark.parametrize("name, dilate", [("die", 1.0), ("torus", 1.0), ("sphere", 0.0), ("die", 2.5)])
def test_compiled_rasterisation_equals_the_numpy_reference(meshes, name, dilate):
    mesh, _ = meshes[name]
    fast = rasterise_uv(mesh, 96, dilate)
    ref = rasterise_uv(mesh, 96, dilate, chunk_faces=1000, compiled=False)  # several chunks: ties across them
    for field in ("texel", "position", "normal", "tangent", "bitangent", "dilated"):
        np.testing.assert_array_equal(getattr(fast, field), getattr(ref, field), err_msg=field)
    assert fast.dilated.any() == (name == "die")  # the torus atlas fills the square: nothing to dilate


def test_compiled_view_geometry_equals_the_numpy_reference(meshes):
    """The fused kernel against the NumPy reference, on a mesh with sharp edges and a rig
    with a camera close enough that part of the object lies behind it or outside the image."""
    mesh, _ = meshes["die"]
    texels = rasterise_uv(mesh, 48)
    w2c = np.concatenate([hemisphere_rig(5, 4.0), look_at(np.array([0.3, 0.2, 1.3]))[None]])
    cameras = _cameras(w2c)
    env = np.random.default_rng(3).uniform(0.0, 5.0, size=(17, 34, 3)).astype(np.float32)
    fast = view_geometry(texels, cameras, env)
    ref = view_geometry(texels, cameras, env, compiled=False)
    assert 0 < ref["candidate"].sum() < ref["candidate"].size and not ref["candidate"][:, -1].all()
    for name in ("candidate", "dist", "wo", "cos_o", "x", "y", "wo_local"):  # the same sums in the same order
        assert fast[name].dtype == ref[name].dtype
        np.testing.assert_array_equal(fast[name], ref[name], err_msg=name)
    # acos/atan2 of libm and NumPy's vectorised ones may differ in an angle's last bit
    assert fast["incoming"].dtype == np.float32
    np.testing.assert_allclose(fast["incoming"], ref["incoming"], rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize("with_distances, dtype", [(True, np.float32), (False, np.float32), (True, np.float64)])
def test_compiled_observe_equals_the_numpy_reference(meshes, with_distances, dtype):
    """Both paths of `observe` on synthetic views with NaN/Inf pixels, a partial mask, depth
    maps with NaN edges and a stand-in occlusion test: the same observations and count."""
    mesh, _ = meshes["die"]
    texels = rasterise_uv(mesh, 48)
    cameras = _cameras(np.concatenate([hemisphere_rig(5, 4.0), look_at(np.array([0.3, 0.2, 1.3]))[None]]))
    rng = np.random.default_rng(4)
    images = rng.uniform(0.0, 2.0, size=(len(cameras), SIZE, SIZE, 3)).astype(dtype)
    images[rng.uniform(size=images.shape) < 0.01] = np.nan
    images[rng.uniform(size=images.shape) < 0.01] = np.inf
    coverage = np.clip(rng.uniform(0.9, 1.3, size=(len(cameras), SIZE, SIZE)), 0, 1).astype(dtype)
    _, depth = project(texels.position, cameras.K, cameras.world_to_camera)  # plausible distances
    distances = np.full((len(cameras), SIZE, SIZE), np.median(depth), dtype)
    distances += rng.normal(0.0, 0.05, size=distances.shape).astype(dtype)
    distances[rng.uniform(size=distances.shape) < 0.05] = np.nan
    occluded = lambda origins, directions, lengths: origins[:, 0] + 0.5 * directions[:, 1] > 0.4  # noqa: E731
    env = rng.uniform(0.0, 5.0, size=(9, 18, 3)).astype(dtype)
    kwargs = {"distances": distances if with_distances else None, "min_coverage": 0.95, "footprint_slack": 40.0}
    fast = observe(texels, cameras, images, coverage, env, occluded, **kwargs)
    ref = observe(texels, cameras, images, coverage, env, occluded, **kwargs, compiled=False)
    assert ref["nonfinite"] > 0 and (ref["weight"] > 0).sum() > 100
    assert fast["nonfinite"] == ref["nonfinite"]
    np.testing.assert_array_equal(fast["view_candidates"], ref["view_candidates"])
    for name in ("radiance", "weight"):
        np.testing.assert_array_equal(fast[name], ref[name], err_msg=name)
    for name in ("wo_local", "incoming"):
        np.testing.assert_allclose(fast[name], ref[name], rtol=1e-6, atol=1e-7, err_msg=name)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_compiled_edge_free_distances_equal_the_numpy_reference(dtype):
    rng = np.random.default_rng(5)
    d = (3.0 + rng.normal(0.0, 0.03, size=(3, 40, 50))).astype(dtype)  # steps near the 0.1 jump
    d[rng.uniform(size=d.shape) < 0.02] = np.inf
    d[0, :, :7] = np.inf  # background touching the border
    d[1, 0, 0], d[2, -1, -1] = np.nan, np.nan
    fast = edge_free_distances(d, 0.1)
    ref = edge_free_distances(d, 0.1, compiled=False)
    assert fast.dtype == ref.dtype == np.float32
    assert 0.1 < np.isnan(ref).mean() < 0.9
    np.testing.assert_array_equal(fast, ref)


def test_tangent_frame_is_orthonormal_and_right_handed():
    n = fibonacci_sphere(1000)
    t, b = tangent_frame(n)
    for u, v in ((t, b), (t, n), (b, n)):
        np.testing.assert_allclose(np.einsum("nc,nc->n", u, v), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.cross(t, b), n, atol=1e-12)


def test_sample_equirect_matches_mitsuba_envmap(mi):
    rng = np.random.default_rng(0)
    env = rng.uniform(0.1, 2.0, size=(32, 64, 3)).astype(np.float32)
    scene = mi.load_dict({"type": "scene", "env": {"type": "envmap", "bitmap": mi.Bitmap(env)}})
    dirs = fibonacci_sphere(500)
    np.testing.assert_allclose(sample_equirect(env, dirs), eval_environment(mi, scene, dirs), rtol=2e-4)


def test_band_limit_filters_each_degree_by_the_gaussian():
    coeffs = np.zeros((49, 1))
    coeffs[0], coeffs[6 * 6 + 2] = 1.0, 1.0  # Y_00 + Y_6,-4
    env = np.repeat(eval_sh(coeffs, equirect_directions(256, 512)), 3, axis=-1)
    a = 0.2
    filtered = band_limited_envmap(env, a)
    expected = eval_sh(coeffs * np.exp(-((a * sh_degrees(6)) ** 2))[:, None], equirect_directions(256, 512))
    np.testing.assert_allclose(filtered[..., :1], expected, atol=2e-3)


@pytest.mark.parametrize("views, rule, expected", [(24, "paper", 24**-0.5), (24, "reference", 0.25), (100, "reference", 0.1)])
def test_band_limit_parameter(views, rule, expected):
    assert band_limit_parameter(views, rule) == pytest.approx(expected)


def test_distance_maps_match_mitsubas_hit_points(mi, meshes):
    _, ply = meshes["torus"]
    w2c = look_at(np.array([1.0, 2.0, 3.0]))
    dist = distance_maps(mi, mesh_scene(mi, ply), intrinsics(SIZE, SIZE, FOV)[None], w2c[None], SIZE, SIZE)[0]
    hit = np.isfinite(dist)
    mask = _render_single(mi, mask_scene(mi, ply, width=SIZE, height=SIZE, fov_x_deg=FOV, spp=16), w2c)[..., 0]
    assert ((mask > 0.999) <= hit).all() and ((mask < 0.001) <= ~hit).all()
    clean = np.isfinite(edge_free_distances(dist[None])[0])
    assert clean.sum() > 0.8 * (mask > 0.999).sum() and (clean <= hit).all()
    hits = _aov(mi, ply, w2c, "p:position", spp=64)
    centre = -w2c[:3, :3].T @ w2c[:3, 3]
    # away from edges the mean hit point over a pixel is its centre's hit point
    # (up to curvature and the noise of 64 samples on slanted surfaces)
    gap = np.abs(np.linalg.norm(hits - centre, axis=-1)[clean] - dist[clean])
    assert np.median(gap) < 1e-3 and gap.max() < 0.02


def test_a_chunk_that_no_view_sees_gives_empty_observations(mi, meshes):
    mesh, ply = meshes["sphere"]
    texels = rasterise_uv(mesh, 64)
    # every camera is above the horizon; from 4 units away none sees below y = -0.99
    below = texels.subset(np.nonzero(texels.position[:, 1] < -0.99)[0])
    cams = _cameras(hemisphere_rig(4, 4.0))
    images = np.ones((4, SIZE, SIZE, 3), np.float32)
    occluded = functools.partial(occlusion_test, mi, mesh_scene(mi, ply))
    obs = observe(below, cams, images, np.ones((4, SIZE, SIZE), np.float32), np.ones((8, 16, 3), np.float32), occluded)
    assert len(below) > 10 and obs["radiance"].shape == (len(below), 4, 3)
    assert (obs["weight"] == 0).all() and obs["nonfinite"] == 0


def test_bilinear_views_on_no_samples():
    values, finite = bilinear_views(np.ones((2, 4, 4, 3)), np.zeros(0, int), np.zeros(0), np.zeros(0))
    assert values.shape == (0, 3) and finite.shape == (0,)


def test_unusable_views_are_named_with_their_reason():
    from freqbrdf.capture.view_usability import nonfinite_views, unusable_views

    images = np.ones((4, 5, 6, 3), np.float32)
    coverage = np.ones((4, 5, 6), np.float32)
    images[0] = np.nan
    coverage[1] = 0.0
    images[2, :, :3] = np.inf
    coverage[2, :, 3:] = 0.0
    assert unusable_views(["a", "b", "c", "d"], images, coverage) == (
        "every pixel is NaN/Inf: a; mask is empty: b; no finite pixel inside the mask: c; "
        "no texel seen inside the mask (poses, mesh and mask disagree): d")
    assert nonfinite_views(["a", "b", "c", "d"], images) == "2 of 4 views: a (all 30 pixels), c (15 of 30 pixels)"
    # With the texels each camera has in view: one that sees none looks away from the object.
    assert unusable_views(["a", "b", "c", "d"], images, coverage, np.array([0, 5, 5, 0])).endswith(
        "no finite pixel inside the mask: c; "
        "the camera sees no part of the mesh (it looks away from the object, or its pose is wrong): d")


def test_observe_counts_the_texels_each_camera_has_in_view():
    mesh = make_mesh("sphere")
    toward, away = look_at(np.array([0.0, 1.0, 4.0])), look_at(np.array([0.0, 1.0, 4.0]), np.array([0.0, 2.0, 8.0]))
    cameras = _cameras(np.stack([toward, away]))
    images = np.ones((2, SIZE, SIZE, 3), np.float32)
    obs = observe(rasterise_uv(mesh, 16), cameras, images, np.ones((2, SIZE, SIZE), np.float32),
                  np.ones((4, 8, 3), np.float32), lambda origins, directions, lengths: np.zeros(len(origins), bool))
    assert obs["view_candidates"][0] > 0 and obs["view_candidates"][1] == 0
    assert (obs["weight"][:, 0] > 0).any() and not (obs["weight"][:, 1] > 0).any()
