"""Report figures: atlas masks, the shared error scale, and row labels that agree with the metrics."""

import numpy as np
import pytest

from freqbrdf.figures import atlas_masks, capture_maps_figure, error_scale, relight_figure
from freqbrdf.io import read_png
from freqbrdf.metrics import parameter_mse


def _svbrdf(rng, r=8):
    return {"base_color": rng.random((r, r, 3)), "roughness": rng.random((r, r)), "metallic": rng.random((r, r))}


def test_atlas_masks_place_texels_by_flat_index():
    inside, seen = atlas_masks(4, np.array([0, 5, 15]), np.array([True, False, True]))
    assert inside.shape == (4, 4) and inside.sum() == 3 and inside[1, 1] and inside[3, 3]
    assert seen.sum() == 2 and seen[0, 0] and not seen[1, 1]


def test_error_scale_is_shared_and_ignores_unseen_texels():
    seen = np.zeros((2, 2), bool)
    seen[0] = True
    errors = {"a": np.array([[0.1, 0.2], [9.0, 9.0]]), "b": np.array([[0.3, 0.4], [9.0, 9.0]])}
    assert error_scale(errors, seen, quantile=1.0) == pytest.approx(0.4)
    assert error_scale({}, seen) == 1e-6


def test_maps_figure_labels_agree_with_parameter_mse(tmp_path):
    rng = np.random.default_rng(0)
    truth = _svbrdf(rng)
    estimates = {"freq": _svbrdf(rng), "spectrum": _svbrdf(rng)}
    texel = np.arange(40)
    observed = np.arange(40) % 3 > 0
    inside, seen = atlas_masks(8, texel, observed)
    mse = capture_maps_figure(tmp_path / "maps.png", truth, estimates, rng.random((8, 8)), inside, seen, "t")
    for method, estimate in estimates.items():
        assert mse[method] == pytest.approx(parameter_mse(truth, estimate, texel[observed])["average"])
    image = read_png(tmp_path / "maps.png")
    assert image.shape[1] > 600 and image.shape[0] > 400  # three rows of four maps
    # a real capture: no ground truth, no error maps
    assert capture_maps_figure(tmp_path / "real.png", None, estimates, rng.random((8, 8)), inside, seen, "t") == {}


def test_relight_figure_with_and_without_renders(tmp_path):
    rng = np.random.default_rng(1)
    references = {"museum": rng.random((16, 16, 3))}
    relit = {"museum": {"freq": rng.random((16, 16, 3)), "rh2001": rng.random((16, 16, 3))}}
    relight_figure(tmp_path / "r.png", references, relit, {("museum", "freq"): 20.0}, "t")
    assert read_png(tmp_path / "r.png").shape[1] > 300
    relight_figure(tmp_path / "none.png", {}, {}, {}, "t")
    assert read_png(tmp_path / "none.png").shape[0] < read_png(tmp_path / "r.png").shape[0]
