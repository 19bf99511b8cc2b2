"""The bootstrap intervals of the benchmark's means and the verdict rule (freqbrdf.report.intervals)."""

import numpy as np
import pytest

from freqbrdf.report.intervals import Bootstrap, Interval, all_hold, bootstrap_weights, judge, mean_interval


def test_every_capture_weighs_one_in_the_data_and_in_each_draw():
    groups = ["a"] * 5 + ["b"] + ["c"] * 2
    draws, data = bootstrap_weights(groups, Bootstrap(draws=500, seed=1))
    np.testing.assert_allclose(data, [0.2] * 5 + [1.0] + [0.5] * 2)
    # each draw picks 3 captures (with replacement), each copy weighing 1 over its units
    np.testing.assert_allclose(draws.sum(axis=1), 3.0)
    for members in ([0, 1, 2, 3, 4], [5], [6, 7]):
        copies = draws[:, members].sum(axis=1)
        np.testing.assert_allclose(copies, np.round(copies))  # whole copies of the capture
    # a capture drawn once resamples its units: some draws leave out some of capture a's views
    assert (draws[:, :5] == 0).any() and (draws[:, :5].sum(axis=1) > 0).any()


def test_the_mean_weighs_captures_not_units():
    # capture a: ten views at 1; capture b: one at 3: the mean over captures is 2, not 13/11
    interval = mean_interval([1.0] * 10 + [3.0], ["a"] * 10 + ["b"], Bootstrap(draws=400))
    assert interval.value == pytest.approx(2.0)
    assert interval.captures == 2 and interval.units == 11
    assert 1.0 - 1e-12 <= interval.low < 2.0 < interval.high <= 3.0 + 1e-12


def test_constant_values_give_a_point_and_nan_values_are_left_out():
    interval = mean_interval([0.5, 0.5, np.nan, 0.5], list("abcd"), Bootstrap(draws=200))
    assert (interval.value, interval.low, interval.high, interval.units) == (0.5, 0.5, 0.5, 3)
    empty = mean_interval([np.nan], ["a"], Bootstrap(draws=200))
    assert np.isnan(empty.value) and judge(empty, ">", 0.0) == "not judged"


def test_the_interval_covers_the_true_mean_at_its_level():
    """An independent oracle: normal captures with known mean; the 95% percentile bootstrap over
    30 captures covers it in about 95% of 300 simulated benchmarks (93% expected for the percentile
    bootstrap at this size; binomial noise about 1.5%)."""
    rng = np.random.default_rng(0)
    covered = 0
    for trial in range(300):
        values = rng.normal(1.0, 0.2, 30)
        interval = mean_interval(values, range(30), Bootstrap(draws=400, seed=trial))
        covered += interval.low <= 1.0 <= interval.high
    assert 0.88 <= covered / 300 <= 0.98


def test_views_within_a_capture_add_their_spread():
    rng = np.random.default_rng(3)
    captures = np.repeat(np.arange(6), 8)
    calm = rng.normal(0.0, 0.01, 48)
    noisy = rng.normal(0.0, 1.0, 48)
    boot = Bootstrap(draws=1000, seed=2)
    assert (mean_interval(noisy, captures, boot).high - mean_interval(noisy, captures, boot).low
            > 20 * (mean_interval(calm, captures, boot).high - mean_interval(calm, captures, boot).low))


def test_the_same_seed_gives_the_same_interval():
    values, groups = np.arange(10.0), [k % 4 for k in range(10)]
    assert mean_interval(values, groups, Bootstrap(seed=5)) == mean_interval(values, groups, Bootstrap(seed=5))
    assert mean_interval(values, groups, Bootstrap(seed=5)) != mean_interval(values, groups, Bootstrap(seed=6))


@pytest.mark.parametrize("interval, op, threshold, verdict", [
    (Interval(0.5, 0.4, 0.6), ">=", 0.3, "yes"),
    (Interval(0.5, 0.4, 0.6), ">=", 0.7, "no"),
    (Interval(0.5, 0.4, 0.6), ">=", 0.5, "within noise"),
    (Interval(0.5, 0.4, 0.6), ">", 0.4, "within noise"),  # its unfavourable end only equals it
    (Interval(0.5, 0.4, 0.6), "<=", 0.6, "yes"),
    (Interval(0.5, 0.4, 0.6), "<", 0.6, "within noise"),
    (Interval(0.5, 0.4, 0.6), "<", 0.3, "no"),
    (Interval(-0.1, -0.2, 0.05), "<", 0.0, "within noise"),
])
def test_a_verdict_needs_the_whole_interval(interval, op, threshold, verdict):
    assert judge(interval, op, threshold) == verdict


def test_several_criteria_hold_together():
    assert all_hold(["yes", "yes"]) == "yes"
    assert all_hold(["yes", "within noise"]) == "within noise"
    assert all_hold(["within noise", "no"]) == "no"
    assert all_hold(["not judged", "yes"]) == "not judged"
    with pytest.raises(ValueError, match="verdicts must be"):
        all_hold(["maybe"])
    with pytest.raises(ValueError, match="op must be"):
        judge(Interval(0.0, 0.0, 0.0), "==", 0.0)


def test_settings_are_checked_and_read_from_config():
    assert Bootstrap.from_config({"level": 0.9, "draws": 500}, 7) == Bootstrap(0.9, 500, 7)
    with pytest.raises(ValueError, match="evaluate.intervals.level"):
        Bootstrap(level=1.0)
    with pytest.raises(ValueError, match="evaluate.intervals.draws"):
        Bootstrap(draws=0)
    assert Interval(1.0, 0.5, 2.0).map(np.log) == Interval(0.0, float(np.log(0.5)), float(np.log(2.0)))
