"""Stress captures: the occluder's blocked light, the region, pair and pose-effect tables, the
blurred environment of the ambiguity pair (rendering itself: tests/test_render.py)."""

import numpy as np
import pandas as pd
import pytest

from freqbrdf.scene import envmaps
from freqbrdf.sphere.sh import project_equirect, sh_degrees
from freqbrdf.studies.stress import (ambiguity_pairs, blocked_light, image_psnr, pair_table, pose_effect_table, region_table, stress_description,
                             stress_reference, stress_table)
from freqbrdf.report.tables.tidy import check_tidy


def test_a_disk_under_a_downward_point_blocks_the_cosine_weighted_share_of_its_cone():
    # Under uniform light a disk of radius R at distance d below a point facing down fills a
    # cone of half-angle atan(R / d) about the normal: a cosine-weighted share of sin^2.
    env = np.ones((64, 128, 3))
    point, normal = np.array([[0.0, -1.0, 0.0]]), np.array([[0.0, -1.0, 0.0]])
    for distance, radius in ((1.0, 1.0), (0.5, 2.0), (2.0, 0.5)):
        half = np.arctan(radius / distance)
        blocked = blocked_light(point, normal, env, -1.0 - distance, radius, directions=20000)
        assert blocked[0] == pytest.approx(np.sin(half) ** 2, abs=0.01)


def test_blocked_light_is_zero_above_the_horizon_and_follows_the_light():
    env = np.ones((64, 128, 3))
    up = blocked_light(np.array([[0.0, 1.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]), env, -1.05, 3.0)
    assert up[0] == 0.0  # a point facing up sees no direction below the horizon
    # With all the light in the upper hemisphere, a disk below blocks none of it.
    rows = np.arange(64)[:, None, None]
    upper_only = np.where(rows < 32, 1.0, 0.0) * np.ones((64, 128, 3))
    side = blocked_light(np.array([[1.0, 0.0, 0.0]]), np.array([[1.0, 0.0, 0.0]]), upper_only, -1.05, 3.0)
    assert side[0] == pytest.approx(0.0, abs=1e-3)
    with pytest.raises(ValueError, match="radius"):
        blocked_light(np.zeros((1, 3)), np.array([[0.0, 1.0, 0.0]]), env, -2.0, 0.0)


def test_region_table_averages_inside_and_outside():
    error = {"freq": np.array([1.0, 3.0, 10.0, 20.0])}
    maps = {"entropy": np.array([0.2, 0.4, 0.6, 0.8]), "posterior_freq": np.array([0.01, 0.03, 0.0, 0.02])}
    table = region_table(error, maps, np.array([True, True, False, False]))
    assert table.loc["shadowed", "mse_freq"] == 2.0 and table.loc["lit", "mse_freq"] == 15.0
    assert table.loc["shadowed", "mean_entropy"] == pytest.approx(0.3)
    assert table.loc["shadowed", "mean_posterior_freq"] == pytest.approx(0.02)
    assert table.loc["lit", "mean_posterior_freq"] == pytest.approx(0.01)
    assert table.loc["lit", "texels"] == 2
    assert np.isnan(region_table(error, maps, np.zeros(4, bool)).loc["shadowed", "mse_freq"])


def test_image_psnr_of_a_known_difference():
    a = [np.full((4, 4, 3), 2.0)]
    b = [np.full((4, 4, 3), 2.2)]
    masks = [np.ones((4, 4), bool)]
    assert image_psnr(a, b, masks) == pytest.approx(10 * np.log10(4.0 / 0.04))
    assert image_psnr(a, a, masks) == float("inf")
    with pytest.raises(ValueError, match="no pixel"):
        image_psnr(a, b, [np.zeros((4, 4), bool)])


def _tidy(rows):
    return check_tidy(pd.DataFrame(rows, columns=["object", "env", "poses", "method", "relight_env", "metric", "value"]))


def test_pose_effect_table_reports_the_change_of_each_method():
    rows = []
    for poses, mse, psnr in (("gt", 0.05, 20.0), ("colmap", 0.07, 18.5)):
        rows += [("sphere", "studio", poses, "freq", "", "mse_average", mse),
                 ("sphere", "studio", poses, "freq", "museum", "psnr_h", psnr),
                 ("sphere_beckmann", "studio", poses, "freq", "", "mse_average", 1.0)]  # not a benchmark capture
    table = pose_effect_table(_tidy(rows), "gt", "colmap", [("sphere", "studio")], ["freq"])
    row = table.iloc[0]
    assert row["MSE (gt)"] == "0.0500" and row["MSE (colmap)"] == "0.0700" and row["MSE change"] == "+0.0200"
    assert row["PSNR-H change"] == "-1.50 dB"


def test_stress_and_pair_tables_put_each_capture_beside_its_reference():
    rows = [("sphere_beckmann", "studio", "gt", "freq", "", "mse_average", 0.09),
            ("sphere", "studio", "gt", "freq", "", "mse_average", 0.06),
            ("sphere_beckmann", "studio", "gt", "freq", "", "mean_posterior_error", 0.012),
            ("sphere", "studio", "gt", "freq", "", "mean_posterior_error", 0.008),
            ("sphere_beckmann", "studio", "gt", "", "", "mean_entropy", 0.5),
            ("sphere", "studio", "gt", "", "", "mean_entropy", 0.4),
            ("sphere_rough", "studio", "gt", "freq", "", "mse_roughness", 0.2),
            ("sphere_rough", "studio", "gt", "", "", "mean_entropy", 0.9)]
    df = _tidy(rows)
    table = stress_table(df, {"sphere_beckmann": ("studio", "Beckmann")}, {"sphere_beckmann": ("sphere", "studio")},
                         "gt", ["freq"])
    assert table.iloc[0]["MSE"] == "0.0900 (0.0600)" and table.iloc[0]["Mean entropy"] == "0.500 (0.400)"
    assert table.iloc[0]["Mean posterior error"] == "0.0120 (0.0080)"
    pairs = pair_table(df, [(("sphere_rough", "studio"), ("sphere_shiny", "studio_blur"), 31.25)],
                       {"sphere_rough": ("sphere", "studio")}, "gt", ["freq"])
    assert list(pairs.Capture) == ["sphere_rough / studio", "sphere_shiny / studio_blur"]
    assert pairs.iloc[0]["Mean entropy"] == "0.900 (0.400)" and pairs.iloc[0]["Image PSNR to partner"] == "31.2 dB"
    assert pairs.iloc[0]["Roughness MSE Ours"] == "0.2000" and pairs.iloc[1]["Roughness MSE Ours"] == "-"


def test_stress_reference_prefers_a_control_capture_then_the_benchmark_capture():
    stress = {"ggx": {"object": "sphere", "env": "studio", "model": "ggx_blend"},
              "beck": {"object": "sphere", "env": "studio", "model": "beckmann_blend"},
              "blurred": {"object": "sphere", "env": "studio_blur", "roughness": 0.5},
              "occluded": {"object": "sphere", "env": "low", "occluder": {"height": -1.1, "radius": 2}},
              "low": {"object": "sphere", "env": "low"}}
    benchmark = [("sphere", "studio"), ("sphere", "sunny")]
    assert stress_reference("beck", stress, benchmark) == ("ggx", "studio")
    assert stress_reference("ggx", stress, benchmark) == ("sphere", "studio")
    assert stress_reference("blurred", stress, benchmark) is None
    assert stress_reference("occluded", stress, benchmark) == ("low", "low")
    assert stress_reference("low", stress, benchmark) is None
    assert stress_description(stress["low"]) == "nothing (a control)"
    assert "Beckmann" in stress_description(stress["beck"])
    assert stress_description({"object": "sphere", "env": "studio", "occluder": {"height": -1.1, "radius": 2},
                               "metallic": 1.0}) == "unseen occluder (disk r 2 at y -1.1); uniform metallic 1"


def test_blur_scales_each_sh_degree_by_the_lobe_of_its_width():
    env = envmaps.studio(64, seed=1)
    width, lmax = 0.3, 6
    before, after = project_equirect(env, lmax), project_equirect(envmaps.blur(env, width), lmax)
    gains = np.exp(-((width * sh_degrees(lmax)) ** 2))
    np.testing.assert_allclose(after, before * gains[:, None], rtol=0.02, atol=1e-3 * np.abs(before).max())
    assert envmaps.blur(env, width).min() >= 0.0
    np.testing.assert_array_equal(envmaps.blur(env, 0.0), env)
    with pytest.raises(ValueError, match="blur width"):
        envmaps.blur(env, -0.1)


def test_studio_lights_go_below_the_horizon_when_asked():
    low = envmaps.studio(64, seed=1, light_elevation_deg=(-60.0, -20.0))
    high = envmaps.studio(64, seed=1)
    def below_over_above(env):  # rows 32.. lie below the horizon; the grid is symmetric about it
        return env[32:].sum() / env[:32].sum()

    assert below_over_above(low) > 2.0 > 0.5 > below_over_above(high)


def test_ambiguity_pairs_are_listed_once_whichever_side_names_them():
    stress = {"a": {"pair": "c"}, "b": {}, "c": {"pair": "a"}, "d": {}, "e": {"pair": "d"}}
    assert ambiguity_pairs(stress) == [("a", "c"), ("d", "e")]
    assert ambiguity_pairs({"x": {}, "y": {"pair": "x"}}) == [("x", "y")]
