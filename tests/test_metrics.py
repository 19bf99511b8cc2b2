"""Metrics against known values."""

import numpy as np
import pytest

from freqbrdf.metrics import parameter_mse


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


# --------------------------------------------------------------------------
# relighting metrics
# --------------------------------------------------------------------------
from freqbrdf.colour import to_srgb  # noqa: E402
from freqbrdf.metrics import (  # noqa: E402
    channel_scale,
    hdr_pair,
    image_mse,
    parameter_error_map,
    relight_scores,
    scored_pixels,
    psnr_h,
    psnr_l,
    ssim,
)


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
    assert psnr_h(noisy, ref, mask, normalise=False) == pytest.approx(expected, abs=0.1)
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
    assert psnr_h(pred, ref, mask, normalise=False) > 60  # every difference is above 4: clipped away
    assert psnr_h(pred, ref, mask, clip=20.0, normalise=False) < 20


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
    assert psnr_h(worse, ref, mask, normalise=False) < psnr_h(pred, ref, mask, normalise=False)
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
    scores = relight_scores(preds, [ref, ref], [mask, mask], clip=4.0, normalise=False)
    assert set(scores) == {"psnr_h", "psnr_l", "ssim", "mse"}
    assert scores["psnr_h"] == pytest.approx(np.mean([psnr_h(p, ref, mask, normalise=False) for p in preds]))
    assert scores["ssim"] == pytest.approx(np.mean([ssim(p, ref, mask) for p in preds]))
    assert scores["mse"] == pytest.approx((0.01**2 + 0.03**2) / 2, rel=0.05)
    with pytest.raises(ValueError, match="2 predictions, 1 references, 1 masks"):
        relight_scores(preds, [ref], [mask])


def test_time_to_reach_interpolates_and_says_never():
    from freqbrdf.metrics import time_to_reach

    t, mse = np.array([0.0, 10.0, 20.0, 30.0]), np.array([0.20, 0.10, 0.06, 0.05])
    assert time_to_reach(t, mse, 0.08) == pytest.approx(15.0)  # halfway from 0.10 to 0.06
    assert time_to_reach(t, mse, 0.10) == pytest.approx(10.0)
    assert time_to_reach(t, mse, 0.30) == 0.0  # the start is already there
    assert np.isnan(time_to_reach(t, mse, 0.01))  # never within the budget
    # a curve that dips below and rises again is timed at its first crossing
    assert time_to_reach(t, np.array([0.2, 0.05, 0.2, 0.2]), 0.1) == pytest.approx(10 * (0.1 / 0.15))
    with pytest.raises(ValueError, match="must not decrease"):
        time_to_reach(t[::-1], mse, 0.1)


def test_hdr_pair_is_what_psnr_h_averages():
    rng = np.random.default_rng(7)
    pred, ref = 3 * rng.random((12, 10, 3)), 3 * rng.random((12, 10, 3))
    mask = rng.random((12, 10)) > 0.3
    for normalise in (True, False):
        p, r = hdr_pair(pred, ref, mask, clip=1.5, normalise=normalise)
        assert p.max() <= 1.5 and r.max() <= 1.5
        mse = ((p - r) ** 2).mean(axis=2)[mask].mean()
        assert -10 * np.log10(mse) == pytest.approx(psnr_h(pred, ref, mask, clip=1.5, normalise=normalise))


def test_scored_pixels_keeps_full_coverage_read_from_a_png():
    coverage = np.array([[255, 254], [0, 128]]) / 255.0
    assert scored_pixels(coverage, 1.0).tolist() == [[True, False], [False, False]]
    assert scored_pixels(coverage, 0.5).tolist() == [[True, True], [False, True]]
