"""Metrics against known values."""

import numpy as np
import pytest

from freqbrdf.report.metrics import PARAMETER_COLUMNS, pearson, texel_parameter_columns
from freqbrdf.sphere.brdf import parameter_mse


def _svbrdf(value: float, r: int = 4):
    return {"base_color": np.full((r, r, 3), value), "roughness": np.full((r, r), value), "metallic": np.full((r, r), value)}


def test_identical_textures_score_zero():
    scores = parameter_mse(_svbrdf(0.3), _svbrdf(0.3), np.arange(16))
    assert scores == {"base_color": 0.0, "roughness": 0.0, "metallic": 0.0, "average": 0.0}


def test_known_offsets_and_the_texel_mask():
    truth, est = _svbrdf(0.5), _svbrdf(0.5)
    est["roughness"][0, 0] = 0.9  # texel 0: error 0.4 -> squared 0.16
    est["metallic"][:] = 0.2  # everywhere: 0.09
    est["base_color"][3, 3, 0] = 1.5  # texel 15, one channel, outside the mask
    scores = parameter_mse(truth, est, np.array([0, 1]))
    assert scores["roughness"] == pytest.approx(0.08)
    assert scores["metallic"] == pytest.approx(0.09)
    assert scores["base_color"] == 0.0
    assert scores["average"] == pytest.approx((0.08 + 0.09) / 3)


def test_mismatched_sizes_and_empty_masks_are_refused():
    with pytest.raises(ValueError, match=r"roughness is \(2, 2\), ground truth \(4, 4\)"):
        parameter_mse(_svbrdf(0.5), _svbrdf(0.5) | {"roughness": np.zeros((2, 2))}, np.arange(4))
    with pytest.raises(ValueError, match="no texels"):
        parameter_mse(_svbrdf(0.5), _svbrdf(0.5), np.array([], int))


def test_texel_parameter_columns_hold_each_texels_five_parameters_in_optimiser_order() -> None:
    """Distinct values everywhere: each column of each selected texel is its atlas value, and
    PARAMETER_COLUMNS names each texture's columns."""
    rng = np.random.default_rng(5)
    textures = {"base_color": rng.random((3, 3, 3)), "roughness": rng.random((3, 3)), "metallic": rng.random((3, 3))}
    texels = np.array([7, 0, 4])
    columns = texel_parameter_columns(textures, texels)
    assert columns.shape == (3, 5) and columns.dtype == np.float64
    rows, cols = np.divmod(texels, 3)
    np.testing.assert_array_equal(columns[:, PARAMETER_COLUMNS["base_color"]], textures["base_color"][rows, cols])
    np.testing.assert_array_equal(columns[:, 3], textures["roughness"][rows, cols])
    np.testing.assert_array_equal(columns[:, PARAMETER_COLUMNS["metallic"]][:, 0], textures["metallic"][rows, cols])


# --------------------------------------------------------------------------
# relighting metrics
# --------------------------------------------------------------------------
from freqbrdf.util.colour import to_srgb  # noqa: E402
from freqbrdf.report.metrics import parameter_error_map  # noqa: E402
from freqbrdf.report.relight_metrics import (  # noqa: E402
    channel_scale,
    HdrScoring,
    hdr_pair,
    image_mse,
    relight_scores,
    relight_view_scores,
    scored_pixels,
    psnr_h,
    psnr_l,
    ssim,
)

RAW = HdrScoring(normalise=False)  # Stanford-ORB's PSNR-H without its exposure normalisation


def _scene(size: int = 64, seed: int = 0):
    """A smooth positive HDR image and a disc mask that leaves a background ring."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:size, 0:size] / size
    base = 0.3 + 0.2 * np.sin(6 * x)[..., None] * np.cos(4 * y)[..., None] * np.array([1.0, 0.7, 0.4])
    image = base + 0.05 * rng.random((size, size, 3))
    mask = (x - 0.5) ** 2 + (y - 0.5) ** 2 < 0.35**2
    return image, mask


def test_identical_images_give_infinite_psnr_and_unit_ssim():
    ref, mask = _scene()
    assert psnr_h(ref, ref, mask) == np.inf
    assert psnr_l(ref, ref, mask) == np.inf
    assert ssim(ref, ref, mask) == pytest.approx(1.0, abs=1e-12)
    assert image_mse(ref, ref, mask) == 0.0


def test_psnr_matches_the_analytic_value_of_a_known_noise_level():
    ref, mask = _scene(256)
    sigma = 0.01
    noisy = ref + np.random.default_rng(1).normal(0.0, sigma, ref.shape)
    expected = -10 * np.log10(sigma**2)  # 40 dB at peak 1
    assert image_mse(noisy, ref, mask) == pytest.approx(sigma**2, rel=0.02)
    # reference values stay inside [0, 1] and [0, 4]: the clips do not act
    assert psnr_h(noisy, ref, mask, RAW) == pytest.approx(expected, abs=0.1)
    # normalisation multiplies both images by g = sum(srgb(ref)) / sum(ref), the MSE by g^2
    gain = to_srgb(ref[mask]).sum() / ref[mask].sum()
    assert psnr_h(noisy, ref, mask) == pytest.approx(expected - 20 * np.log10(gain), abs=0.1)
    # PSNR-L: the noise passes through the sRGB curve, whose slope scales it
    slope = 1.055 / 2.4 * ref[mask] ** (1 / 2.4 - 1)
    expected_l = -10 * np.log10(np.mean((sigma * slope) ** 2))
    assert psnr_l(noisy, ref, mask) == pytest.approx(expected_l, abs=0.1)
    assert 0.5 < ssim(noisy, ref, mask) < 0.999


def test_psnr_h_clips_both_images_at_the_clip_value():
    ref, mask = _scene()
    pred = ref.copy()
    bright = mask & (np.arange(mask.shape[1]) > mask.shape[1] // 2)  # half the object: a highlight of 10
    ref[bright] = 10.0
    # the prediction misses it by -5 on every other pixel and by +5 + sqrt(50) on the rest,
    # which keeps the least-squares scale at exactly 1 (10 (a + b) = a^2 + b^2)
    low = np.arange(bright.sum()) % 2 == 0
    assert low.sum() == (~low).sum()
    pred[bright] = np.where(low[:, None], 5.0, 5.0 + np.sqrt(50.0))
    np.testing.assert_allclose(channel_scale(pred, ref, mask), 1.0, rtol=1e-12)
    assert psnr_h(pred, ref, mask, RAW) > 60  # every difference is above 4: clipped away
    assert psnr_h(pred, ref, mask, HdrScoring(clip=20.0, normalise=False)) < 20


def test_psnr_and_ssim_are_invariant_to_a_per_channel_scale_of_the_prediction():
    ref, mask = _scene()
    pred = ref + 0.02 * np.random.default_rng(2).normal(size=ref.shape)
    scaled = pred * np.array([0.3, 2.0, 7.0])
    assert psnr_h(scaled, ref, mask) == pytest.approx(psnr_h(pred, ref, mask), abs=1e-9)
    assert psnr_l(scaled, ref, mask) == pytest.approx(psnr_l(pred, ref, mask), abs=1e-9)
    assert ssim(scaled, ref, mask) == pytest.approx(ssim(pred, ref, mask), abs=1e-9)
    np.testing.assert_allclose(channel_scale(ref * np.array([0.5, 2.0, 4.0]), ref, mask), [2.0, 0.5, 0.25])
    # the absolute MSE is not scale invariant: it is the metric that sees a wrong exposure
    assert image_mse(scaled, ref, mask) > 100 * image_mse(pred, ref, mask)


def test_pixels_outside_the_mask_do_not_matter():
    ref, mask = _scene()
    pred = ref + 0.02 * np.random.default_rng(3).normal(size=ref.shape)
    garbage = pred.copy()
    garbage[~mask] = np.random.default_rng(4).uniform(0.0, 50.0, ((~mask).sum(), 3))
    for metric in (psnr_h, psnr_l, ssim, image_mse):
        assert metric(garbage, ref, mask) == pytest.approx(metric(pred, ref, mask), abs=1e-12), metric.__name__
    # and an error inside the mask does
    worse = pred.copy()
    worse[mask] += 0.1 * np.random.default_rng(5).normal(size=(mask.sum(), 3))
    assert psnr_h(worse, ref, mask, RAW) < psnr_h(pred, ref, mask, RAW)
    assert ssim(worse, ref, mask) < ssim(pred, ref, mask)


def test_image_metrics_refuse_bad_shapes_and_empty_masks():
    ref, mask = _scene(16)
    with pytest.raises(ValueError, match=r"psnr_h: prediction is \(16, 16\), reference \(16, 16, 3\)"):
        psnr_h(ref[..., 0], ref, mask)
    with pytest.raises(ValueError, match=r"psnr_l: mask is \(16, 15\) bool, expected bool \(16, 16\)"):
        psnr_l(ref, ref, mask[:, :15])
    with pytest.raises(ValueError, match="mask is .* float64"):
        image_mse(ref, ref, mask.astype(float))
    with pytest.raises(ValueError, match="selects no pixels"):
        ssim(ref, ref, np.zeros_like(mask))
    with pytest.raises(ValueError, match="NaN/Inf"):
        psnr_h(ref * np.nan, ref, mask)
    with pytest.raises(ValueError, match=r"ssim: images are \(8, 8\), need at least 11x11"):
        ssim(ref[:8, :8], ref[:8, :8], mask[:8, :8] | True)


def test_error_map_averages_to_the_parameter_mse():
    rng = np.random.default_rng(6)
    truth = {"base_color": rng.random((8, 8, 3)), "roughness": rng.random((8, 8)), "metallic": rng.random((8, 8))}
    estimate = {name: rng.random(values.shape) for name, values in truth.items()}
    error = parameter_error_map(truth, estimate)
    assert error.shape == (8, 8)
    texels = np.array([0, 5, 17, 63])
    assert error.ravel()[texels].mean() == pytest.approx(parameter_mse(truth, estimate, texels)["average"])
    expected_00 = np.mean([np.mean((truth["base_color"][0, 0] - estimate["base_color"][0, 0]) ** 2),
                           (truth["roughness"][0, 0] - estimate["roughness"][0, 0]) ** 2,
                           (truth["metallic"][0, 0] - estimate["metallic"][0, 0]) ** 2])
    assert error[0, 0] == pytest.approx(expected_00)


def test_relight_scores_average_the_views():
    ref, mask = _scene()
    rng = np.random.default_rng(7)
    preds = [ref + sigma * rng.normal(size=ref.shape) for sigma in (0.01, 0.03)]
    scores = relight_scores(preds, [ref, ref], [mask, mask], RAW)
    assert set(scores) == {"psnr_h", "psnr_l", "ssim", "mse"}
    assert scores["psnr_h"] == pytest.approx(np.mean([psnr_h(p, ref, mask, RAW) for p in preds]))
    assert scores["ssim"] == pytest.approx(np.mean([ssim(p, ref, mask) for p in preds]))
    assert scores["mse"] == pytest.approx((0.01**2 + 0.03**2) / 2, rel=0.05)
    with pytest.raises(ValueError, match="2 predictions, 1 references, 1 masks"):
        relight_scores(preds, [ref], [mask])


def test_time_to_reach_interpolates_and_says_never():
    from freqbrdf.report.metrics import time_to_reach

    t, mse = np.array([0.0, 10.0, 20.0, 30.0]), np.array([0.20, 0.10, 0.06, 0.05])
    assert time_to_reach(t, mse, 0.08) == pytest.approx(15.0)  # halfway from 0.10 to 0.06
    assert time_to_reach(t, mse, 0.10) == pytest.approx(10.0)
    assert time_to_reach(t, mse, 0.30) == 0.0  # the start is already there
    assert np.isnan(time_to_reach(t, mse, 0.01))  # never within the budget
    # a curve that dips below and rises again is timed at its first crossing
    assert time_to_reach(t, np.array([0.2, 0.05, 0.2, 0.2]), 0.1) == pytest.approx(10 * (0.1 / 0.15))
    with pytest.raises(ValueError, match="must not decrease"):
        time_to_reach(t[::-1], mse, 0.1)


def test_a_run_converges_when_its_last_epoch_falls_less_than_one_percent_at_a_constant_rate():
    from freqbrdf.report.metrics import is_converged, last_epoch_change

    falling, settled, rising = [0.2, 0.1, 0.09], [0.2, 0.1, 0.0995], [0.2, 0.1, 0.11]
    assert last_epoch_change(falling) == pytest.approx(0.1)
    assert last_epoch_change(rising) == pytest.approx(-0.1)
    assert not is_converged(falling, "none")
    assert is_converged(settled, "none") and is_converged(rising, "none")
    assert not is_converged(settled, "cosine")  # the decay makes the last steps small by construction
    with pytest.raises(ValueError, match="at least two epochs"):
        last_epoch_change([0.1])


# --------------------------------------------------------------------------
# the principled BRDF that brdf_log_rmse scores
# --------------------------------------------------------------------------
import oracles  # noqa: E402
from freqbrdf.sphere.reference import smith_g1  # noqa: E402
from freqbrdf.report.metrics import ggx_ndf, principled_brdf  # noqa: E402


def test_ggx_ndf_is_normalised_over_projected_half_vectors() -> None:
    # int D(h) cos(theta_h) d(omega_h) = 1 for every width: a wrong exponent or factor breaks it
    theta = np.linspace(0.0, np.pi / 2, 400_001)
    for alpha in (0.03, 0.2, 0.7, 1.0):
        integrand = ggx_ndf(np.cos(theta), alpha) * np.cos(theta) * np.sin(theta) * 2 * np.pi
        assert np.trapezoid(integrand, theta) == pytest.approx(1.0, abs=2e-4)
    assert ggx_ndf(1.0, 0.1) == pytest.approx(1 / (np.pi * 0.01), rel=1e-14)


def test_principled_brdf_matches_an_evaluation_from_direction_vectors() -> None:
    rng = np.random.default_rng(3)
    n_texels, n_pairs = 5, 40
    base = rng.uniform(0, 1, (n_texels, 3))
    roughness = rng.uniform(0.1, 1, n_texels)  # above the alpha clamp, which the oracle lacks
    metallic = np.array([0.0, 1.0, *rng.uniform(0, 1, n_texels - 2)])
    wi, wo = rng.normal(size=(2, n_pairs, 3))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]) + 0.05, np.abs(wo[:, 2]) + 0.05  # above the surface
    wi, wo = wi / np.linalg.norm(wi, axis=1, keepdims=True), wo / np.linalg.norm(wo, axis=1, keepdims=True)
    h = (wi + wo) / np.linalg.norm(wi + wo, axis=1, keepdims=True)
    cos_d = np.sum(wi * h, axis=1)
    f = principled_brdf(base, roughness, metallic, wi[:, 2], wo[:, 2], h[:, 2], cos_d)
    assert f.shape == (n_texels, n_pairs, 3)
    kd, ks, alpha = oracles.lobes_from_principled(base, roughness, metallic)
    a = alpha[:, None]
    # D from the half vector's slope: alpha^2 / (pi cos^4 (alpha^2 + tan^2)^2)
    tan2_h = (h[:, 0] ** 2 + h[:, 1] ** 2) / h[:, 2] ** 2
    d = a**2 / (np.pi * h[:, 2] ** 4 * (a**2 + tan2_h) ** 2)
    g = smith_g1(wi[:, 2], a) * smith_g1(wo[:, 2], a)
    fresnel = oracles.schlick_fresnel(ks[:, None, :], cos_d[None, :, None])
    expected = kd[:, None, :] / np.pi + (d * g / (4 * wi[:, 2] * wo[:, 2]))[..., None] * fresnel
    np.testing.assert_allclose(f, expected, rtol=1e-10)
    # reciprocal: swapping the directions keeps the half vector and the angle to it
    np.testing.assert_allclose(principled_brdf(base, roughness, metallic, wo[:, 2], wi[:, 2], h[:, 2], cos_d), f)
    # the float type follows the cosines'
    assert principled_brdf(base, roughness, metallic, *(c.astype(np.float32) for c in
                                (wi[:, 2], wo[:, 2], h[:, 2], cos_d))).dtype == np.float32


def test_principled_brdf_refuses_directions_below_the_surface() -> None:
    ones = np.ones(2)
    with pytest.raises(ValueError, match=r"cos_o must be positive \(above the surface\), got -0.5"):
        principled_brdf(np.full((1, 3), 0.5), [0.5], [0.0], ones, np.array([1.0, -0.5]), ones, ones)
    with pytest.raises(ValueError, match=r"base_color must have shape \(\*, 3\)"):
        principled_brdf(np.full((1, 4), 0.5), [0.5], [0.0], ones, ones, ones, ones)


# --------------------------------------------------------------------------
# BRDF-space error and the scale-invariant base colour
# --------------------------------------------------------------------------
from freqbrdf.report.metrics import base_color_si_scores, brdf_directions, brdf_log_rmse  # noqa: E402


def _textures(base, roughness, metallic, r: int = 4):
    """Constant textures of one material."""
    return {"base_color": np.broadcast_to(np.asarray(base, float), (r, r, 3)).copy(),
            "roughness": np.full((r, r), float(roughness)), "metallic": np.full((r, r), float(metallic))}


def test_brdf_directions_are_real_reciprocal_pairs_above_the_surface():
    cos_i, cos_o, cos_h, cos_d = brdf_directions()
    assert len(cos_i) == 646
    for c in (cos_i, cos_o, cos_h, cos_d):
        assert np.all((c > 0) & (c <= 1))
    # the outgoing direction is the incoming one mirrored about the half vector: o = 2 (i.h) h - i
    np.testing.assert_allclose(cos_i + cos_o, 2 * cos_d * cos_h, rtol=1e-12)
    # and i lies on the cone of angle theta_d about h
    sin_h, sin_d = np.sqrt(1 - cos_h**2), np.sqrt(1 - cos_d**2)
    assert np.all(np.abs(cos_i - cos_h * cos_d) <= sin_h * sin_d + 1e-12)
    # every pair's reverse is in the set
    pairs = np.round(np.stack([cos_i, cos_o, cos_h, cos_d], axis=1), 12)
    swapped = pairs[:, [1, 0, 2, 3]]
    assert sorted(map(tuple, pairs)) == sorted(map(tuple, swapped))
    # the first half-angle sample, (pi / 2) (1/24)^2, resolves the sharpest lobe (alpha = 0.003, 0.17 degrees)
    assert np.degrees(np.arccos(cos_h.max())) == pytest.approx(0.15625)


def test_brdf_error_is_zero_for_identical_textures_symmetric_and_positive_otherwise():
    rng = np.random.default_rng(11)
    a = {"base_color": rng.random((8, 8, 3)), "roughness": rng.random((8, 8)), "metallic": rng.random((8, 8))}
    b = {name: rng.random(v.shape) for name, v in a.items()}
    texels = np.arange(64)
    assert brdf_log_rmse(a, {k: v.copy() for k, v in a.items()}, texels) == 0.0
    assert brdf_log_rmse(a, b, texels) == brdf_log_rmse(b, a, texels) > 0.1


def test_brdf_error_of_a_rough_dielectric_has_a_closed_form():
    # alpha = 1: D = 1 / pi and G1 = 2 cos / (1 + cos), so with metallic 0
    # f = base / pi + F(theta_d) / (pi (1 + cos_i) (1 + cos_o)), F = 0.04 + 0.96 (1 - cos_d)^5
    cos_i, cos_o, _, cos_d = brdf_directions()
    specular = (0.04 + 0.96 * (1 - cos_d) ** 5) / (np.pi * (1 + cos_i) * (1 + cos_o))
    true_base, estimated_base = np.array([0.2, 0.5, 0.8]), np.array([0.3, 0.45, 0.1])
    log = [np.log1p((b[None, :] / np.pi + specular[:, None]) * cos_i[:, None]) for b in (true_base, estimated_base)]
    expected = np.sqrt(np.mean((log[1] - log[0]) ** 2))
    value = brdf_log_rmse(_textures(true_base, 1.0, 0.0), _textures(estimated_base, 1.0, 0.0), np.arange(16))
    assert value == pytest.approx(expected, rel=1e-5)  # float32 evaluation


def test_brdf_error_averages_squares_over_texels_like_the_parameter_mse():
    rng = np.random.default_rng(12)
    a = {"base_color": rng.random((8, 8, 3)), "roughness": rng.random((8, 8)), "metallic": rng.random((8, 8))}
    b = {name: rng.random(v.shape) for name, v in a.items()}
    first, second = np.arange(0, 40), np.arange(40, 50)
    both = brdf_log_rmse(a, b, np.concatenate([first, second]))
    parts = [brdf_log_rmse(a, b, t) ** 2 * len(t) for t in (first, second)]
    assert both == pytest.approx(np.sqrt(sum(parts) / 50), rel=1e-6)
    # texels outside the selection do not count
    b["roughness"].ravel()[60:] = 1 - b["roughness"].ravel()[60:]
    assert brdf_log_rmse(a, b, first) ** 2 * 40 == pytest.approx(parts[0], rel=1e-9)


def test_a_metallic_flip_on_a_dark_base_is_cheap_in_brdf_space_and_a_roughness_step_is_not():
    texels = np.arange(16)
    # base 0.04 is a dielectric's own R0: metallic 0 -> 1 only removes a diffuse lobe of 0.04 / pi
    dielectric, metal = _textures(0.04, 0.5, 0.0), _textures(0.04, 0.5, 1.0)
    shiny, less_shiny = _textures(0.5, 0.05, 0.0), _textures(0.5, 0.15, 0.0)
    flip = parameter_mse(dielectric, metal, texels)["average"], brdf_log_rmse(dielectric, metal, texels)
    step = parameter_mse(shiny, less_shiny, texels)["average"], brdf_log_rmse(shiny, less_shiny, texels)
    # measured: flip (0.333, 0.0083), step (0.0033, 1.11): parameter MSE and BRDF error disagree 100x each way
    assert flip[0] > 50 * step[0]
    assert step[1] > 50 * flip[1]
    assert flip[1] < 0.02


def test_brdf_error_refuses_bad_inputs():
    a = _textures(0.5, 0.5, 0.5)
    with pytest.raises(ValueError, match="no texels"):
        brdf_log_rmse(a, a, np.array([], int))
    with pytest.raises(ValueError, match="texel 16 outside the 16 texels"):
        brdf_log_rmse(a, a, np.array([0, 16]))
    with pytest.raises(ValueError, match=r"metallic is \(2, 2\), ground truth \(4, 4\)"):
        brdf_log_rmse(a, a | {"metallic": np.zeros((2, 2))}, np.arange(4))


def _checker_base(size: int = 16):
    """Grey 0.5 truth, an estimate 0.3 times as bright with a +-10% checkerboard, and a
    scored block (balanced signs) with garbage outside it."""
    y, x = np.mgrid[0:size, 0:size]
    sign = np.where((x + y) % 2 == 0, 1.0, -1.0)[..., None]
    truth = np.full((size, size, 3), 0.5)
    estimate = 0.3 * truth * (1 + 0.1 * sign)
    inside = (y >= 2) & (y < 14) & (x >= 2) & (x < 14)
    truth[~inside], estimate[~inside] = 0.0, 1.0
    return truth, estimate, np.flatnonzero(inside)


def test_scale_invariant_base_colour_psnr_matches_the_analytic_value():
    truth, estimate, texels = _checker_base()
    # least-squares scale over the block: 1 / (0.3 (1 + 0.01)); then sRGB, peak 1
    scaled = 0.5 * (1 + 0.1 * np.array([1.0, -1.0])) / 1.01
    mse = np.mean((to_srgb(scaled) - to_srgb(0.5)) ** 2)
    scores = base_color_si_scores(truth, estimate, texels)
    assert scores["psnr"] == pytest.approx(-10 * np.log10(mse), rel=1e-12)
    assert 0 < scores["ssim"] < 1


def test_scale_invariant_base_colour_ignores_a_per_channel_scale_and_unscored_texels():
    rng = np.random.default_rng(13)
    truth = rng.uniform(0.1, 0.9, (16, 16, 3))
    texels = np.arange(40, 200)
    scaled = truth * np.array([0.5, 0.8, 0.6])
    assert np.mean((scaled - truth).reshape(-1, 3)[texels] ** 2) > 0.01  # what parameter MSE would see
    scores = base_color_si_scores(truth, scaled, texels)
    assert scores["psnr"] > 100 and scores["ssim"] == pytest.approx(1.0, abs=1e-9)
    noisy = scaled + 0.05 * rng.normal(size=scaled.shape)
    reference = base_color_si_scores(truth, noisy, texels)
    noisy.reshape(-1, 3)[:40] = rng.random((40, 3))  # outside the scored texels
    assert base_color_si_scores(truth, noisy, texels) == reference


def test_hdr_pair_is_what_psnr_h_averages():
    rng = np.random.default_rng(7)
    pred, ref = 3 * rng.random((12, 10, 3)), 3 * rng.random((12, 10, 3))
    mask = rng.random((12, 10)) > 0.3
    for normalise in (True, False):
        scoring = HdrScoring(clip=1.5, normalise=normalise)
        p, r = hdr_pair(pred, ref, mask, scoring)
        assert p.max() <= 1.5 and r.max() <= 1.5
        mse = ((p - r) ** 2).mean(axis=2)[mask].mean()
        assert -10 * np.log10(mse) == pytest.approx(psnr_h(pred, ref, mask, scoring))


def test_the_scale_fitted_on_clipped_values_is_not_set_by_a_highlight():
    """A sun's highlight, far above the clip, drags Stanford-ORB's scale (fitted before clipping) and
    darkens every pixel; the scale fitted on the clipped images does not see it; none fits nothing."""
    ref, mask = _scene()
    hot = mask & (np.arange(mask.shape[0])[:, None] < mask.shape[0] // 2 - 4) & (np.arange(mask.shape[1]) < 18)
    assert 0 < hot.sum() < 0.05 * mask.sum()
    ref = ref.copy()
    ref[hot] = 200.0
    pred = ref.copy()
    pred[hot] = 120.0  # the highlight a little dim, every other pixel exact
    orb = channel_scale(pred, ref, mask)
    assert np.all(orb > 1.5)  # the highlight's ratio
    assert psnr_h(pred, ref, mask, HdrScoring(normalise=False, scale="clipped")) == np.inf  # clipped alike: exact
    assert psnr_h(pred, ref, mask, HdrScoring(normalise=False, scale="none")) == np.inf
    assert psnr_h(pred, ref, mask, RAW) < 30  # every pixel brightened by the highlight's scale
    # a uniformly dim prediction: the clipped fit recovers the factor, none leaves it
    dim = 0.5 * _scene()[0]
    clipped = HdrScoring(normalise=False, scale="clipped")
    assert psnr_h(dim, _scene()[0], mask, clipped) > 100
    assert psnr_h(dim, _scene()[0], mask, HdrScoring(normalise=False, scale="none")) < 30
    with pytest.raises(ValueError, match="hdr_scale must be one of"):
        HdrScoring(scale="median")
    with pytest.raises(ValueError, match="hdr_clip must be positive"):
        HdrScoring(clip=0.0)
    assert HdrScoring.from_config({"hdr_clip": 2, "hdr_normalise": False, "hdr_scale": "none"}) == HdrScoring(
        2.0, False, "none")


def test_relight_view_scores_are_what_relight_scores_averages():
    ref, mask = _scene()
    rng = np.random.default_rng(11)
    preds = [ref + 0.01 * k * rng.normal(size=ref.shape) for k in (1, 3)]
    views = relight_view_scores(preds, [ref, ref], [mask, mask], RAW)
    assert len(views) == 2 and views[0]["psnr_h"] > views[1]["psnr_h"]
    mean = relight_scores(preds, [ref, ref], [mask, mask], RAW)
    for name in mean:
        assert mean[name] == pytest.approx((views[0][name] + views[1][name]) / 2)


def test_scored_pixels_keeps_full_coverage_read_from_a_png():
    coverage = np.array([[255, 254], [0, 128]]) / 255.0
    assert scored_pixels(coverage, 1.0).tolist() == [[True, False], [False, False]]
    assert scored_pixels(coverage, 0.5).tolist() == [[True, True], [False, True]]


def test_pearson_matches_numpy_and_names_a_length_mismatch() -> None:
    rng = np.random.default_rng(1)
    a, b = rng.random(50), rng.random(50)
    np.testing.assert_allclose(pearson(a, 2 * a + b), np.corrcoef(a, 2 * a + b)[0, 1])
    assert np.isnan(pearson(np.ones(4), a[:4]))
    with pytest.raises(ValueError, match="differ in length"):
        pearson(a, b[:3])
