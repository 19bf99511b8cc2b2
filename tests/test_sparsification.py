"""Sparsification curves, AUSE and the partial correlation: analytic values and brute-force oracles."""

import itertools

import numpy as np
import pytest

from freqbrdf.report.metrics import pearson
from freqbrdf.report.sparsification import (LEVELS, ause, conformal_widths, gaussian_widths, partial_pearson,
                                             random_ause, reliability, sparsification_curve)


def test_a_curve_by_hand_including_a_texel_cut_in_half():
    error = np.array([4.0, 3.0, 2.0, 1.0])  # mean 2.5
    curve = sparsification_curve(error, error, np.array([0.0, 0.125, 0.25, 0.5]))
    # k = 0; k = 0.5: half of the 4 gone, (10 - 2) / 3.5; k = 1: (3 + 2 + 1) / 3; k = 2: (2 + 1) / 2
    np.testing.assert_allclose(curve, np.array([2.5, 8 / 3.5, 2.0, 1.5]) / 2.5, rtol=1e-15)


def test_the_oracle_has_no_area_and_a_backward_order_has_more_than_a_random_one():
    rng = np.random.default_rng(0)
    error = rng.exponential(size=500)
    assert ause(error, error) == 0.0
    noisy = error + rng.normal(scale=0.5, size=500)
    assert 0 < ause(noisy, error) < random_ause(error) < ause(-error, error)


def test_tied_uncertainties_are_removed_as_the_mean_over_their_orders():
    """Oracle: every order of the tied texels, the mean of the rest at whole numbers of texels."""
    uncertainty = np.array([2.0, 1.0, 1.0, 1.0, 0.0, 0.0])
    error = np.array([5.0, 0.0, 3.0, 6.0, 1.0, 2.0])
    fractions = np.arange(6) / 6
    orders = [np.array([0, *a, *b]) for a in itertools.permutations([1, 2, 3]) for b in itertools.permutations([4, 5])]
    expected = np.mean([[error[order[k:]].mean() for k in range(6)] for order in orders], axis=0) / error.mean()
    np.testing.assert_allclose(sparsification_curve(uncertainty, error, fractions), expected, rtol=1e-14)
    np.testing.assert_allclose(sparsification_curve(np.zeros(6), error, fractions), 1.0, rtol=1e-14)


def test_only_the_order_counts_so_minus_views_and_one_over_sqrt_views_agree():
    rng = np.random.default_rng(1)
    views = rng.integers(1, 12, size=300)
    error = rng.exponential(size=300) / views
    assert ause(-views, error) == pytest.approx(ause(1 / np.sqrt(views), error), abs=1e-15)
    assert ause(-views, error) < random_ause(error)


def test_partial_correlation_matches_the_formula_and_removes_a_shared_cause():
    rng = np.random.default_rng(2)
    views = rng.normal(size=4000)
    a, b = views + rng.normal(size=4000), views + rng.normal(size=4000)  # related only through views
    r_ab, r_ac, r_bc = pearson(a, b), pearson(a, views), pearson(b, views)
    formula = (r_ab - r_ac * r_bc) / np.sqrt((1 - r_ac**2) * (1 - r_bc**2))
    assert partial_pearson(a, b, views) == pytest.approx(formula, abs=1e-12)
    assert r_ab > 0.4 and abs(partial_pearson(a, b, views)) < 0.05
    shared = rng.normal(size=4000)
    assert partial_pearson(views + shared, shared + 0.5 * rng.normal(size=4000), views) > 0.8


@pytest.mark.parametrize("uncertainty, error, message", [
    (np.ones(3), np.ones(4), "equally long"),
    (np.array([np.nan, 1.0]), np.ones(2), "finite"),
    (np.ones(2), np.array([-1.0, 2.0]), "error must be >= 0"),
    (np.ones(2), np.zeros(2), "positive mean"),
])
def test_bad_inputs_are_named(uncertainty, error, message):
    with pytest.raises(ValueError, match=message):
        sparsification_curve(uncertainty, error)


def test_baseline_maps_count_the_views_and_average_the_light_they_see():
    from freqbrdf.artefacts import Observations
    from freqbrdf.report.sparsification import baseline_maps

    weight = np.array([[0.5, 0.0, 1.0], [0.0, 0.0, 0.0], [0.2, 0.3, 0.4]])  # texel 1 unobserved
    incoming = np.zeros((3, 3, 3))
    incoming[0, :, :] = [[1.0] * 3, [99.0] * 3, [3.0] * 3]  # the unseen view's light does not count
    incoming[2, :, :] = 2.0
    obs = Observations.from_arrays(np.zeros((3, 3, 3)), weight, np.zeros((3, 3, 3)), np.tile(np.eye(3), (3, 1, 1)),
                                   np.arange(3), 2, incoming=incoming)
    maps = baseline_maps(obs)
    np.testing.assert_allclose(maps["views"], [-2.0, -3.0])
    np.testing.assert_allclose(maps["inv_sqrt_views"], [1 / np.sqrt(2), 1 / np.sqrt(3)])
    np.testing.assert_allclose(maps["light"], [-2.0, -2.0])  # luminance weights sum to 1


def test_the_curves_behind_the_scores_include_random_and_an_oracle_below_every_order():
    from freqbrdf.report.sparsification import FRACTIONS, sparsification_curves

    rng = np.random.default_rng(3)
    error = rng.exponential(size=200)
    maps = {"entropy": error + rng.normal(size=200), "views": -rng.integers(1, 9, size=200).astype(float)}
    records = sparsification_curves(maps, {"parameter": error})
    assert len(records) == 4 * len(FRACTIONS)
    curve = {name: np.array([r["value"] for r in records if r["map"] == name]) for name in (*maps, "random", "oracle")}
    assert np.all(curve["random"] == 1.0)
    for name in ("entropy", "views", "random"):
        assert np.all(curve["oracle"] <= curve[name] + 1e-12)
    assert np.trapezoid(curve["entropy"] - curve["oracle"], FRACTIONS) == pytest.approx(ause(maps["entropy"], error))


def test_a_perfect_estimate_has_no_scores_and_no_curves():
    from freqbrdf.report.sparsification import sparsification_curves, uncertainty_scores

    maps, errors = {"entropy": np.arange(5.0)}, {"parameter": np.zeros(5)}
    assert all(np.isnan(v) for v in uncertainty_scores(maps, errors).values())
    assert set(uncertainty_scores(maps, errors)) == {"ause_entropy_parameter", "ause_random_parameter"}
    assert sparsification_curves(maps, errors) == []


def test_reliability_of_a_calibrated_posterior_is_the_diagonal_and_of_a_narrow_one_below_it():
    """Errors drawn from the posterior itself cover each level's share; halved deviations cover
    what a Gaussian gives at half the width (an analytic value, e.g. 0.5 at 1.645 / 2 sd: 58.9%)."""
    rng = np.random.default_rng(3)
    std = rng.uniform(0.01, 0.2, 400_000)
    truth = rng.uniform(0, 1, std.size)
    estimate = truth + rng.normal(0.0, std)
    shares = reliability(estimate, truth, std)
    assert list(shares) == list(LEVELS)
    np.testing.assert_allclose(list(shares.values()), LEVELS, atol=0.003)
    assert shares[0.9] == np.mean(np.abs(estimate - truth) <= 1.6448536269514722 * std)  # the 95th percentile
    narrow = reliability(estimate, truth, std / 2)
    from statistics import NormalDist
    half = [2 * NormalDist().cdf(NormalDist().inv_cdf(0.5 + level / 2) / 2) - 1 for level in LEVELS]
    np.testing.assert_allclose(list(narrow.values()), half, atol=0.003)
    with pytest.raises(ValueError, match=r"levels must lie in \(0, 1\)"):
        reliability(estimate, truth, std, levels=(0.5, 1.0))
    # given widths: the Gaussian's, per column too, reproduce it
    np.testing.assert_array_equal(list(reliability(estimate, truth, std, gaussian_widths()).values()),
                                  list(shares.values()))
    two = np.column_stack([estimate, estimate])
    per_column = np.column_stack([gaussian_widths(), np.full(len(LEVELS), 1e9)])  # the second column always in
    mixed = reliability(two, np.column_stack([truth, truth]), np.column_stack([std, std]), per_column)
    np.testing.assert_allclose(list(mixed.values()), (np.array(list(shares.values())) + 1) / 2)


def test_conformal_widths_are_ranks_and_hold_their_level_on_new_draws():
    """By hand on five values, then on heavy tails (Student's t, 3 degrees of freedom), where the
    Gaussian's widths fall short at 99% and the conformal ones hold on fresh draws."""
    np.testing.assert_array_equal(conformal_widths(np.array([5.0, 1.0, 4.0, 2.0, 3.0]), (0.5, 0.8, 0.99)),
                                  [3.0, 5.0, 5.0])  # ranks ceil(6 p): 3, 5, 6 -> the largest
    rng = np.random.default_rng(11)
    calibration, fresh = (np.abs(rng.standard_t(3, n)) / np.sqrt(3.0) for n in (50_000, 200_000))  # unit variance
    widths = conformal_widths(calibration)
    held = reliability(fresh, np.zeros_like(fresh), np.ones_like(fresh), widths)
    np.testing.assert_allclose(list(held.values()), LEVELS, atol=0.006)
    gaussian = reliability(fresh, np.zeros_like(fresh), np.ones_like(fresh))
    assert gaussian[0.99] < 0.985 and gaussian[0.5] > 0.6  # flatter than the diagonal, as the posterior's
    with pytest.raises(ValueError, match="finite and >= 0"):
        conformal_widths(np.array([1.0, np.nan]))
