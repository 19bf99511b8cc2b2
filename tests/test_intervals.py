"""The t-intervals of the benchmark's means over captures and the verdict rule (freqbrdf.report.intervals)."""

import numpy as np
import pytest

from freqbrdf.report.intervals import Interval, IntervalSettings, all_hold, cluster_means, judge, mean_interval


def test_the_mean_weighs_captures_not_units():
    # capture a: ten views at 1; capture b: one at 3: the mean over captures is 2, not 13/11
    interval = mean_interval([1.0] * 10 + [3.0], ["a"] * 10 + ["b"], IntervalSettings())
    assert interval.value == pytest.approx(2.0)
    assert interval.clusters == 2 and interval.units == 11
    # Student's t with one degree of freedom over the means 1 and 3: 2 +- 12.706 * sqrt(2) / sqrt(2)
    assert (interval.low, interval.high) == pytest.approx((2.0 - 12.7062047, 2.0 + 12.7062047))


def test_cluster_means_of_each_label_in_sorted_order():
    np.testing.assert_allclose(cluster_means([1.0, 5.0, 2.0, 4.0], ["b", "a", "b", "c"]), [5.0, 1.5, 4.0])


def test_constant_values_give_a_point_nan_values_are_left_out_and_one_capture_no_interval():
    interval = mean_interval([0.5, 0.5, np.nan, 0.5], list("abcd"), IntervalSettings())
    assert (interval.value, interval.low, interval.high, interval.units) == (0.5, 0.5, 0.5, 3)
    empty = mean_interval([np.nan], ["a"], IntervalSettings())
    assert np.isnan(empty.value) and judge(empty, ">", 0.0) == "not judged"
    single = mean_interval([0.1, 0.3], ["a", "a"], IntervalSettings())
    assert single.value == pytest.approx(0.2) and np.isnan(single.low) and np.isnan(single.high)
    assert judge(single, ">", 0.0) == "not judged"


def _coverage(n: int, quantile=None, trials: int = 4000) -> float:
    """Share of simulated benchmarks of n captures whose 95% interval covers the true mean 1.0:
    each capture's effect normal (sd 0.3) and 2-12 test views each with noise (sd 0.2), as the
    relighting scores are. ``quantile`` replaces Student's t by a fixed multiplier (the test's control)."""
    rng = np.random.default_rng(n)
    covered = 0
    for _ in range(trials):
        views = rng.integers(2, 13, n)
        effect = rng.normal(1.0, 0.3, n)
        values = np.concatenate([rng.normal(e, 0.2, k) for e, k in zip(effect, views)])
        groups = np.repeat(np.arange(n), views)
        if quantile is None:
            interval = mean_interval(values, groups, IntervalSettings(0.95))
            covered += interval.low <= 1.0 <= interval.high
        else:
            means = cluster_means(values, groups)
            half = quantile * means.std(ddof=0) / np.sqrt(n)
            covered += abs(means.mean() - 1.0) <= half
    return covered / trials


@pytest.mark.parametrize("n", [4, 8, 24])
def test_95_percent_intervals_cover_the_truth_93_to_97_percent_at_4_8_and_24_captures(n):
    """An independent oracle: benchmarks drawn from a known distribution (binomial noise of the
    share over 4,000 trials: 0.3%)."""
    assert 0.93 <= _coverage(n) <= 0.97


def test_the_coverage_check_fails_an_interval_as_narrow_as_the_percentile_bootstrap():
    """The control: the normal quantile over the plug-in spread (what a percentile bootstrap over
    captures approximates) covers 82% at 4 captures, so the check above can fail."""
    assert _coverage(4, quantile=1.96, trials=2000) < 0.85


def test_views_within_a_capture_add_their_spread():
    rng = np.random.default_rng(3)
    captures = np.repeat(np.arange(6), 8)
    calm = rng.normal(0.0, 0.01, 48)
    noisy = rng.normal(0.0, 1.0, 48)
    settings = IntervalSettings()
    assert (mean_interval(noisy, captures, settings).high - mean_interval(noisy, captures, settings).low
            > 20 * (mean_interval(calm, captures, settings).high - mean_interval(calm, captures, settings).low))


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
    assert IntervalSettings.from_config({"level": 0.9}) == IntervalSettings(0.9)
    with pytest.raises(ValueError, match="evaluate.intervals.level"):
        IntervalSettings(level=1.0)
    assert Interval(1.0, 0.5, 2.0).map(np.log) == Interval(0.0, float(np.log(0.5)), float(np.log(2.0)))
