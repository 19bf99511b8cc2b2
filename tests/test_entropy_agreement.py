"""Entropy agreement (paper Table 3): grid, likelihood, and the two renderers of the grid."""

import numpy as np
import pytest

from freqbrdf.studies import entropy_agreement as ea
from freqbrdf.artefacts import Observations
from freqbrdf.util.colour import LUMINANCE
from freqbrdf.estimate.light import irradiance, light_quadrature
from freqbrdf.scene.meshes import make_mesh
from freqbrdf.scene.ply import write_ply
from freqbrdf.artefacts import SurfaceTexels
from freqbrdf.capture.observations import tangent_frame
from freqbrdf.estimate.spectrum import grid_entropy

L0 = np.array([0.5, 0.7, 0.9])  # the constant environment of the renderer tests


def test_material_grid_holds_every_combination_with_roughness_slowest() -> None:
    grid = ea.material_grid(3)
    assert grid.shape == (27, 3)
    assert len({tuple(g) for g in grid}) == 27
    assert set(np.unique(grid)) == {0.0, 0.5, 1.0}
    # roughness changes only every 9 points: one shadowed-light fit per value
    assert np.count_nonzero(np.diff(grid[:, 0])) == 2
    with pytest.raises(ValueError, match="grid"):
        ea.material_grid(1)


def _observations(radiance, weight, incoming) -> Observations:
    n_tex, n_views = np.shape(weight)
    wo = np.broadcast_to([0.0, 0.0, 1.0], (n_tex, n_views, 3)).copy()
    frame = np.broadcast_to(np.eye(3), (n_tex, 3, 3))
    obs = Observations.from_arrays(np.asarray(radiance, float), np.asarray(weight, float), wo, frame,
                                   np.arange(n_tex), 4)
    return Observations(obs.texels, obs.radiance, obs.weight, obs.wo_local, np.asarray(incoming, float), obs.meta)


def test_pairs_and_the_light_normalised_objective_by_hand() -> None:
    weight = np.array([[1.0, 0.5, 0.0], [0.0, 0.0, 0.0]])  # texel 1 is not observed
    light = np.zeros((2, 3, 3))
    light[0, 0], light[0, 1] = 2.0, 4.0
    observed = np.zeros((2, 3, 3))
    observed[0, 0], observed[0, 1] = 1.0, 3.0
    pairs = ea.Pairs.of(_observations(observed, weight, light))
    np.testing.assert_array_equal(pairs.texel, [0, 0])
    np.testing.assert_array_equal(pairs.view, [0, 1])
    np.testing.assert_allclose(pairs.light_power[0], (1.0 * 4 + 0.5 * 16) / 1.5)  # weighted mean square
    np.testing.assert_array_equal(pairs.light_power[1], 0.0)

    model = [np.full((2, 3), 1.0), np.array([[1.0] * 3, [3.0] * 3])]
    d = ea.grid_objective(model, pairs)
    assert d.shape == (2, 2, 3)
    np.testing.assert_allclose(d[0, 0], 0.5 * 4.0 / 8.0)  # w (1 - 3)^2 / Lbar^2
    np.testing.assert_allclose(d[0, 1], 0.0)
    assert np.isinf(d[1]).all()  # no light: no scale
    # the scale of the scene does not matter: sigma means the same for bright and dark texels
    brighter = ea.Pairs.of(_observations(10 * observed, weight, 10 * light))
    np.testing.assert_allclose(ea.grid_objective([10 * m for m in model], brighter)[0], d[0])


def test_likelihood_entropy_of_two_grid_points_is_the_binary_entropy() -> None:
    sigma, gap = 0.1, 0.013
    d = np.zeros((1, 2, 3))
    d[0, 1] = gap
    p = 1.0 / (1.0 + np.exp(-gap / (2 * sigma**2)))
    expected = -(p * np.log(p) + (1 - p) * np.log(1 - p)) / np.log(2)
    np.testing.assert_allclose(ea.likelihood_entropy(d, sigma), [expected], rtol=1e-6)
    # an equal objective everywhere carries no information; a dark channel (inf) counts as uninformed
    np.testing.assert_allclose(ea.likelihood_entropy(np.zeros((1, 8, 3)), sigma), [1.0])
    dark = np.full((1, 8, 3), np.inf)
    dark[..., 0] = np.arange(8.0)
    np.testing.assert_allclose(ea.likelihood_entropy(dark, 1e-3), [0.0], atol=1e-12)
    # green and blue uninformed (1), red certain (0)
    np.testing.assert_allclose(ea.likelihood_entropy(dark, 1e-3, combine="luminance"), [1.0 - LUMINANCE[0]])
    # the same likelihood as the spectrum entropy's (paper Eq. 23-25)
    rng = np.random.default_rng(0)
    d = rng.random((5, 16, 3)) * 0.01
    np.testing.assert_allclose(ea.likelihood_entropy(d, 0.03), grid_entropy(d[:, :, None, :], 0.03).min(axis=1))


# ---------------------------------------------------------------------------
# the two renderers of the grid, on a sphere under a constant environment
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    """A mesh file and observations of 40 points on it from 6 directions each (radiance 0)."""
    mesh = make_mesh("sphere")
    path = tmp_path_factory.mktemp("agreement") / "sphere.ply"
    write_ply(path, mesh)
    rng = np.random.default_rng(3)
    # triangle centroids: texel positions lie inside triangles (a ray aimed at a vertex may slip through)
    position = mesh.vertices[mesh.faces[rng.choice(len(mesh.faces), 40, replace=False)]].mean(axis=1)
    normal = position / np.linalg.norm(position, axis=1, keepdims=True)
    tangent, bitangent = tangent_frame(normal)
    theta = rng.uniform(0.1, 1.2, (40, 6))
    phi = rng.uniform(0, 2 * np.pi, (40, 6))
    wo = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=-1)
    texels = SurfaceTexels(8, np.arange(40), position, normal, tangent, bitangent, np.zeros(40, bool))
    obs = Observations(texels, np.zeros((40, 6, 3)), np.cos(theta), wo, np.broadcast_to(L0, (40, 6, 3)).copy(),
                       {"views": [str(k) for k in range(6)], "band_limit": {"a_prime": 0.0}})
    return path, obs


def test_mitsuba_grid_sees_a_mirror_return_the_environment(mi, sphere) -> None:
    """A smooth conductor with base colour 1 (Fresnel 1) on a convex object under a constant
    environment L0 reflects L0 in every direction; a black dielectric far less."""
    path, obs = sphere
    env = np.broadcast_to(L0, (32, 64, 3)).astype(np.float32)
    scene = ea.uniform_material_scene(mi, path, env, max_depth=8)
    grid = np.array([[0.0, 1.0, 1.0], [0.5, 0.0, 0.0]])
    first, second = ea.mitsuba_radiance(mi, scene, obs, grid, spp=4, seeds=(1, 2))
    assert first.shape == (2, 240, 3)
    relative = np.abs(first / L0 - 1.0)
    # shading normals interpolated across flat triangles put a few grazing views off by up to 12%
    assert np.median(relative) < 1e-3 and np.quantile(relative, 0.95) < 0.02
    assert np.all(second.mean(axis=(0, 1)) < 0.2 * L0)
    again = next(ea.mitsuba_radiance(mi, scene, obs, grid[1:], spp=4, seeds=(1, 2)))
    np.testing.assert_array_equal(again, second)  # seeded: the same paths
    assert not np.array_equal(second[0], second[1])  # two seeds: two independent estimates


def test_angular_grid_agrees_with_mitsuba_on_the_mirror_and_finds_its_own_material(sphere) -> None:
    path, obs = sphere
    env = np.broadcast_to(L0, (64, 128, 3)).copy()
    light, e = light_quadrature(env, 12), irradiance(env, obs.texels.normal)
    grid = ea.material_grid(3)
    radiance = list(ea.angular_radiance(obs, e, light, grid))
    mirror = next(i for i, g in enumerate(grid) if tuple(g) == (0.0, 1.0, 1.0))
    # the model's horizon and alpha floor dim grazing views slightly; Mitsuba's mirror gives L0 (above)
    np.testing.assert_allclose(np.median(radiance[mirror], axis=0), L0, rtol=0.03)
    # observations made by grid point 13 are scored best, and exactly, at grid point 13
    truth = np.zeros((40, 6, 3))
    pairs = ea.Pairs.of(obs)
    truth[pairs.texel, pairs.view] = radiance[13]
    seen = Observations(obs.texels, truth, obs.weight, obs.wo_local, obs.incoming, obs.meta)
    d = ea.grid_objective(radiance, ea.Pairs.of(seen))
    np.testing.assert_allclose(d[:, 13], 0.0, atol=1e-20)
    assert np.all(np.argmin(d[..., 1], axis=1) == 13)
