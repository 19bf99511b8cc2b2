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
