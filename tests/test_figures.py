"""Report figures: atlas masks, the shared error scale, and row labels that agree with the metrics."""

import numpy as np
import pytest

from freqbrdf.methods import METHODS
from freqbrdf.report.figures import (GREY, atlas_masks, capture_maps_figure, draw_capture_maps, error_scale,
                                     relight_figure)
from freqbrdf.util.previews import pyplot
from freqbrdf.util.io import read_png
from freqbrdf.sphere.brdf import parameter_mse
from freqbrdf.report.relight_metrics import HdrScoring, psnr_h


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


def test_maps_figure_draws_unobserved_texels_grey_in_the_entropy_map(tmp_path):
    """Every texel inside the atlas, half of them observed, entropy 1 everywhere (Turbo's dark
    red): the unobserved half is drawn in the figure's grey, not at the top of the scale."""
    rng = np.random.default_rng(2)
    dark = {"base_color": 0.3 * rng.random((8, 8, 3)), "roughness": 0.5 * rng.random((8, 8)),
            "metallic": 0.5 * rng.random((8, 8))}  # nothing near the grey 0.85
    inside, seen = atlas_masks(8, np.arange(64), np.arange(64) < 32)
    capture_maps_figure(tmp_path / "maps.png", None, {"freq": dark}, np.ones((8, 8)), inside, seen, "t")
    image = read_png(tmp_path / "maps.png")[..., :3].astype(float)
    grey = (np.abs(image - float(GREY) * 255) <= 1).all(axis=-1)  # 8-bit rounding
    # half of one map (about 190 x 95 pixels); the colour bars' grey steps are a few pixels wide
    assert int(grey.sum()) > 5000


@pytest.mark.parametrize("with_truth", [True, False])
def test_maps_figure_shows_every_value_scale_whole_in_its_first_two_rows(with_truth):
    """The default run's 11 rows (ground truth and 10 methods) make a figure taller than the
    report's window, whose bottom was cut off with the value scales under the last row: every
    colour bar, with its tick labels and label, lies inside the canvas and above the second
    row's bottom, within the top 800 pixels of the saved PNG (100 dpi)."""
    rng = np.random.default_rng(3)
    inside, seen = atlas_masks(16, np.arange(200), np.arange(200) % 4 > 0)
    estimates = {m: _svbrdf(rng, 16) for m in list(METHODS)[:10]}
    fig, _ = draw_capture_maps(_svbrdf(rng, 16) if with_truth else None, estimates, rng.random((16, 16)),
                               inside, seen, "sphere captured under studio")
    try:
        renderer = fig.canvas.get_renderer()
        fig.canvas.draw()
        bars = [ax for ax in fig.axes if getattr(ax, "_colorbar", None) is not None]
        assert len(bars) == (5 if with_truth else 4)  # 3 parameters, the entropy, and the error if scored
        canvas = fig.bbox
        second_row = next(ax for ax in fig.axes if ax.get_ylabel().startswith(METHODS[list(METHODS)[0]].label))
        for bar in bars:
            box = bar.get_tightbbox(renderer)
            label = bar.get_xlabel() or bar.get_ylabel()
            assert label and bar.get_xticklabels() + bar.get_yticklabels(), "a scale without its ticks or label"
            assert (box.x0 >= canvas.x0 and box.x1 <= canvas.x1 and box.y0 >= canvas.y0 and box.y1 <= canvas.y1), \
                f"the {label!r} scale is cut off: {box} outside {canvas}"
            assert box.y0 >= second_row.get_window_extent(renderer).y0, f"the {label!r} scale is below the second row"
            assert (canvas.y1 - box.y0) / fig.dpi * 100 < 800, f"the {label!r} scale is not near the top"
        assert canvas.height / fig.dpi * 100 > 1900  # taller than the report screenshot's window
    finally:
        pyplot().close(fig)


def test_relight_figure_prints_each_views_psnr_h(tmp_path):
    rng = np.random.default_rng(1)
    mask = np.zeros((16, 16), bool)
    mask[4:12, 3:14] = True
    references = {"museum": (rng.random((16, 16, 3)), mask), "sunny": (4 * rng.random((16, 16, 3)), mask)}
    relit = {env: {"freq": rng.random((16, 16, 3)), "rh2001": rng.random((16, 16, 3))} for env in references}
    scores = relight_figure(tmp_path / "r.png", references, relit, "t", HdrScoring(clip=2.0, normalise=False))
    assert set(scores) == {(env, m) for env in references for m in ("freq", "rh2001")}
    for (env, method), score in scores.items():
        assert score == pytest.approx(psnr_h(relit[env][method], references[env][0], mask,
                                              HdrScoring(clip=2.0, normalise=False)))
    assert len(set(scores.values())) == 4  # each view its own number, not one per method
    # two rows (renders, error images) per environment
    assert read_png(tmp_path / "r.png").shape[0] > 2 * 2 * 150
    assert relight_figure(tmp_path / "none.png", {}, {}, "t") == {}
    assert read_png(tmp_path / "none.png").shape[0] < read_png(tmp_path / "r.png").shape[0]
