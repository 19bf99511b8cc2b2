"""Tests for freqbrdf.estimate.merge: the uncertainty-guided merge of paper Table 6."""

import numpy as np
import pytest

from freqbrdf.estimate.merge import lowest_merge
from freqbrdf.estimate.optimise.posterior import expected_error_atlas


def constant_svbrdf(value: float, r: int = 4) -> dict[str, np.ndarray]:
    return {"base_color": np.full((r, r, 3), value), "roughness": np.full((r, r), value), "metallic": np.full((r, r), value)}


def test_each_texel_comes_from_the_lowest_entropy_estimate():
    rng = np.random.default_rng(0)
    estimates = [constant_svbrdf(v) for v in (0.1, 0.5, 0.9)]
    entropies = [rng.random((4, 4)) for _ in range(3)]
    merged, choice = lowest_merge(estimates, entropies)
    np.testing.assert_array_equal(choice, np.argmin(np.stack(entropies), axis=0))
    expected = np.array([0.1, 0.5, 0.9])[choice]
    np.testing.assert_allclose(merged.roughness, expected)
    np.testing.assert_allclose(merged.base_color, np.repeat(expected[..., None], 3, axis=-1))


def test_ties_are_averaged_whatever_the_order_and_one_capture_is_the_identity():
    estimates = [constant_svbrdf(0.2), constant_svbrdf(0.7)]
    merged, choice = lowest_merge(estimates, [np.ones((4, 4)), np.ones((4, 4))])
    assert (choice == -1).all() and np.allclose(merged.metallic, 0.45)
    alone, _ = lowest_merge(estimates[1:], [np.zeros((4, 4))])
    np.testing.assert_array_equal(alone.base_color, estimates[1]["base_color"])


def test_the_merge_is_the_same_bits_in_any_order_of_its_captures():
    """The merge is filed under each of an object's captures (it once listed its own first): every
    order must give the same textures, ties (the entropy's 1 where a capture saw nothing) included."""
    rng = np.random.default_rng(4)
    estimates = [{k: rng.random(v.shape).astype(np.float32) for k, v in constant_svbrdf(0.0, 8).items()}
                 for _ in range(3)]
    scores = [np.where(rng.random((8, 8)) < 0.5, 1.0, rng.random((8, 8))) for _ in range(3)]
    first, choice = lowest_merge(estimates, scores)
    assert (choice == -1).any() and (choice >= 0).any()
    for order in ([1, 0, 2], [2, 1, 0], [1, 2, 0]):
        other, _ = lowest_merge([estimates[k] for k in order], [scores[k] for k in order])
        for name in first:
            np.testing.assert_array_equal(other[name], first[name])


def test_merge_recovers_the_truth_when_entropy_marks_the_right_capture():
    """Two captures, each right on half the atlas and wrong elsewhere, with the entropy low where
    each is right: the merge is right everywhere, better than either and than their average."""
    truth = constant_svbrdf(0.4)
    left, right = constant_svbrdf(0.9), constant_svbrdf(0.0)
    for name in truth:
        left[name][:, :2] = truth[name][:, :2]
        right[name][:, 2:] = truth[name][:, 2:]
    h_left = np.where(np.arange(4) < 2, 0.1, 0.8)[None, :].repeat(4, axis=0)
    merged, _ = lowest_merge([left, right], [h_left, 0.9 - h_left])
    for name in truth:
        np.testing.assert_allclose(merged[name], truth[name])


def test_mismatched_inputs_are_named():
    with pytest.raises(ValueError, match="2 estimates and 1 uncertainty maps"):
        lowest_merge([constant_svbrdf(0.1)] * 2, [np.zeros((4, 4))])
    with pytest.raises(ValueError, match=r"estimate 0 is \(4, 4\), uncertainty maps \(8, 8\)"):
        lowest_merge([constant_svbrdf(0.1)], [np.zeros((8, 8))])


def test_posterior_merge_takes_the_better_determined_capture():
    """Two captures, each with small deviations on its own half: the merge takes each half from it."""
    sure, unsure = 0.01, 0.3
    halves = np.where(np.arange(4) < 2, sure, unsure)[None, :].repeat(4, axis=0)
    stds = [{"base_color": np.repeat(h[..., None], 3, axis=-1), "roughness": h, "metallic": h}
            for h in (halves, sure + unsure - halves)]
    _, choice = lowest_merge([constant_svbrdf(0.1), constant_svbrdf(0.9)], [expected_error_atlas(s) for s in stds])
    np.testing.assert_array_equal(choice, np.where(np.arange(4) < 2, 0, 1)[None, :].repeat(4, axis=0))
