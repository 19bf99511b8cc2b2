"""Ground-truth SVBRDF textures: ranges, determinism and the variety the benchmark needs."""

import numpy as np
import pytest

from freqbrdf.scene.textures import grain, svbrdf_textures


@pytest.fixture(scope="module")
def textures():
    return svbrdf_textures(128, seed=7)


def test_shapes_dtypes_and_unit_range(textures):
    assert textures["base_color"].shape == (128, 128, 3)
    assert textures["roughness"].shape == textures["metallic"].shape == (128, 128)
    for texture in textures.values():
        assert texture.dtype == np.float32
        assert texture.min() >= 0.0 and texture.max() <= 1.0


def test_deterministic_for_a_seed_and_different_across_seeds(textures):
    again = svbrdf_textures(128, seed=7)
    other = svbrdf_textures(128, seed=8)
    for name in textures:
        np.testing.assert_array_equal(textures[name], again[name])
        assert np.abs(textures[name] - other[name]).mean() > 0.02


@pytest.mark.parametrize("seed", range(5))
def test_every_material_regime_is_present(seed):
    t = svbrdf_textures(128, seed=seed)
    metal, rough = t["metallic"], t["roughness"]
    assert (metal < 0.05).mean() > 0.05 and (metal > 0.95).mean() > 0.05  # diffuse and metallic
    assert (rough < 0.35).mean() > 0.05 and (rough > 0.5).mean() > 0.05  # smooth and rough
    for regime in (metal > 0.95, metal < 0.05):
        assert rough[regime].min() < 0.35 and rough[regime].max() > 0.45


@pytest.mark.parametrize("seed", range(5))
def test_transitions_are_both_sharp_and_smooth(seed):
    metal = svbrdf_textures(256, seed=seed)["metallic"]
    step = np.abs(np.diff(metal, axis=1))
    assert step.max() > 0.9  # some edge goes from diffuse to metal within one texel
    blended = (metal > 0.1) & (metal < 0.9)
    assert blended.sum() > 100  # and some edges blend over several texels


def test_textures_wrap_around_in_u_and_v():
    # Sphere and torus atlases join u = 0 to u = 1: the texture must be continuous there.
    t = svbrdf_textures(256, seed=3)["base_color"]
    seam_u = np.abs(t[:, 0] - t[:, -1]).mean()
    seam_v = np.abs(t[0] - t[-1]).mean()
    typical = np.abs(np.diff(t, axis=1)).mean()
    assert seam_u < 3 * typical and seam_v < 3 * typical


def test_bad_arguments_name_the_value():
    with pytest.raises(ValueError, match="resolution"):
        svbrdf_textures(4, seed=0)
    with pytest.raises(ValueError, match="cells"):
        svbrdf_textures(64, seed=0, cells=2)


def test_scatter_to_atlas_keeps_known_values_and_fills_from_the_nearest():
    from freqbrdf.scene.textures import scatter_to_atlas

    texel = np.array([0 * 8 + 1, 5 * 8 + 6, 7 * 8 + 7])  # (0,1), (5,6), (7,7)
    values = np.array([[1.0, 0.0], [2.0, 0.5], [9.0, 9.0]])
    atlas = scatter_to_atlas(8, texel, values, known=np.array([True, True, False]))
    assert atlas.shape == (8, 8, 2) and atlas.dtype == np.float32
    np.testing.assert_array_equal(atlas[0, 1], [1.0, 0.0])
    np.testing.assert_array_equal(atlas[5, 6], [2.0, 0.5])
    np.testing.assert_array_equal(atlas[0, 0], [1.0, 0.0])  # nearest known texel
    np.testing.assert_array_equal(atlas[7, 7], [2.0, 0.5])  # an unknown value is not used
    assert not (atlas == 9.0).any()
    with pytest.raises(ValueError, match="no texel has a known value"):
        scatter_to_atlas(8, texel, values, known=np.zeros(3, bool))


def test_grain_adds_fine_detail_to_the_base_colour_only():
    plain = svbrdf_textures(128, seed=3)
    grained = svbrdf_textures(128, seed=3, grain_amplitude=0.8, grain_texels=2.0)
    for name in ("roughness", "metallic"):
        np.testing.assert_array_equal(plain[name], grained[name])
    ratio = grained["base_color"][..., 1] / np.maximum(plain["base_color"][..., 1], 1e-3)
    unclipped = (plain["base_color"][..., 1] > 0.05) & (grained["base_color"][..., 1] < 1.0)
    # The factor stays within [1 - a, 1 + a] and is about 2/3 a in spread.
    assert ratio[unclipped].min() >= 0.2 - 1e-5 and ratio[unclipped].max() <= 1.8 + 1e-5
    assert 0.35 < ratio[unclipped].std() < 0.6
    # Detail a few texels across: neighbouring texels differ far more than with no grain.
    def jitter(t):
        return np.abs(np.diff(t["base_color"], axis=1)).mean()
    assert jitter(grained) > 4 * jitter(plain)


def test_grain_is_periodic_and_validated():
    rng = np.random.default_rng(0)
    g = grain(64, rng, 2.0)
    assert g.shape == (64, 64) and g.min() >= -1 and g.max() <= 1
    # Periodic: the step across the wrap-around seam is no larger than a step inside.
    assert np.abs(g[:, 0] - g[:, -1]).mean() < 2 * np.abs(np.diff(g, axis=1)).mean()
    with pytest.raises(ValueError, match="grain size must be > 0 texels, got 0"):
        grain(64, rng, 0.0)
    with pytest.raises(ValueError, match="grain amplitude must be in \\[0, 1\\), got 1.2"):
        svbrdf_textures(32, seed=0, grain_amplitude=1.2)
