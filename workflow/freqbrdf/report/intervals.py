"""Intervals of the benchmark's means, and the rule that turns an interval into a verdict.

A mean over the benchmark is a mean over clusters (each weighing the same) of the
cluster's units. A cluster is a capture for most numbers: one value for a per-capture
number (a parameter MSE, a correlation), one per relighting environment and test view
for a relighting score. A merge of an object's captures is one texture set per object,
so its numbers cluster by object (:func:`freqbrdf.report.tables.tidy.cluster_keys`).

Its interval is Student's t over the cluster means: ``mean +- t(n - 1) s / sqrt(n)``,
``s`` their standard deviation. Units within a cluster share the capture, so they are
not independent; their spread reaches the interval through the cluster means, and
captures are the independent draws. Unlike a percentile bootstrap over the clusters
(narrower than the data's spread at n = 4: it cannot reach past the sample's extremes
and divides by n, not n - 1), it holds its coverage at n = 4 as at n = 24 for normal
cluster means (tested by simulation). A comparison of two methods is the interval of
their paired differences, unit by unit, so what the captures share cancels; a ratio
the exponential of the interval of its logarithms (a geometric mean). One cluster
gives no interval.

A claim holds (``yes``) when its criterion holds at the interval's unfavourable end,
fails (``no``) when it fails at the favourable end, and is ``within noise`` otherwise.
"""

from __future__ import annotations

from collections.abc import Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["Interval", "IntervalSettings", "VERDICTS", "all_hold", "cluster_means", "judge", "mean_interval"]

YES, NO, NOISE, NOT_JUDGED = "yes", "no", "within noise", "not judged"
VERDICTS = (YES, NO, NOISE, NOT_JUDGED)
_OPS = {">": np.greater, ">=": np.greater_equal, "<": np.less, "<=": np.less_equal}


@dataclass(frozen=True)
class IntervalSettings:
    """Settings of the intervals (config ``evaluate.intervals``).

    Attributes
    ----------
    level : float
        Coverage of each interval, in (0, 1).
    """

    level: float = 0.95

    def __post_init__(self) -> None:
        if not 0.0 < self.level < 1.0:
            raise ValueError(f"evaluate.intervals.level must be in (0, 1), got {self.level}")

    @classmethod
    def from_config(cls, intervals: Mapping[str, object]) -> IntervalSettings:
        """From config ``evaluate.intervals``."""
        return cls(float(intervals["level"]))


@dataclass(frozen=True)
class Interval:
    """A statistic and its interval.

    Attributes
    ----------
    value : float
        The statistic on the data (each cluster weighing the same).
    low, high : float
        The interval's ends; NaN when one cluster gives none.
    clusters, units : int
        How many clusters (captures, or objects for a merge) and units it rests on.
    """

    value: float
    low: float
    high: float
    clusters: int = 1
    units: int = 1

    def map(self, f) -> Interval:
        """The interval of a monotonically increasing function of the statistic (e.g. ``np.exp``)."""
        return Interval(float(f(self.value)), float(f(self.low)), float(f(self.high)), self.clusters, self.units)


def cluster_means(values: Sequence[float], groups: Sequence[Hashable]) -> np.ndarray:
    """The mean of each cluster's units, clusters in sorted order of their labels.

    Parameters
    ----------
    values : sequence of float, length N
        One finite value per unit.
    groups : sequence, length N
        The cluster of each unit (compared as strings).

    Returns
    -------
    ndarray, shape (C,)
        One mean per distinct cluster.
    """
    v = np.asarray(values, dtype=np.float64)
    labels, index = np.unique(np.array([str(g) for g in groups], dtype=object), return_inverse=True)
    if v.shape != index.shape:
        raise ValueError(f"cluster_means: {v.size} values but {index.size} groups")
    return np.bincount(index, weights=v, minlength=len(labels)) / np.bincount(index, minlength=len(labels))


def mean_interval(values: Sequence[float], groups: Sequence[Hashable], settings: IntervalSettings) -> Interval:
    """The mean over clusters of the mean over each cluster's units, with its t-interval.

    Parameters
    ----------
    values : sequence of float, length N
        One value per unit; NaN values are left out.
    groups : sequence, length N
        The cluster (capture, or object) of each unit.
    settings : IntervalSettings

    Returns
    -------
    Interval
        NaN throughout when no value is finite; NaN ends over a single cluster.
    """
    v = np.asarray(values, dtype=np.float64)
    g = np.asarray([str(x) for x in groups], dtype=object)
    if v.shape != g.shape:
        raise ValueError(f"mean_interval: {v.size} values but {g.size} groups")
    keep = np.isfinite(v)
    if not keep.any():
        return Interval(float("nan"), float("nan"), float("nan"), 0, 0)
    means = cluster_means(v[keep], g[keep])
    n, value = len(means), float(means.mean())
    if n < 2:
        return Interval(value, float("nan"), float("nan"), n, int(keep.sum()))
    # Imported here, not at the top: the Snakefile imports this module (through the stress and
    # report rules), and scipy.stats took most of a second of every Snakemake start-up.
    from scipy import stats

    half = stats.t.ppf(0.5 + settings.level / 2.0, n - 1) * means.std(ddof=1) / np.sqrt(n)
    return Interval(value, float(value - half), float(value + half), n, int(keep.sum()))


def judge(interval: Interval, op: str, threshold: float) -> str:
    """The verdict on ``statistic op threshold`` given the statistic's interval.

    ``yes`` when it holds at the interval's unfavourable end, ``no`` when it fails at
    the favourable end, ``within noise`` otherwise; ``not judged`` for a NaN interval.

    Parameters
    ----------
    interval : Interval
    op : {">", ">=", "<", "<="}
    threshold : float
    """
    if op not in _OPS:
        raise ValueError(f"judge: op must be one of {sorted(_OPS)}, got {op!r}")
    if not np.isfinite([interval.low, interval.high]).all():
        return NOT_JUDGED
    holds = _OPS[op]
    worst, best = (interval.low, interval.high) if op in (">", ">=") else (interval.high, interval.low)
    if holds(worst, threshold):
        return YES
    if not holds(best, threshold):
        return NO
    return NOISE


def all_hold(verdicts: Iterable[str]) -> str:
    """The verdict on several criteria that must all hold: ``no`` if any is ``no``, ``yes`` if
    all are ``yes``, ``not judged`` if any is (and none ``no``), else ``within noise``."""
    verdicts = list(verdicts)
    unknown = [v for v in verdicts if v not in VERDICTS]
    if unknown or not verdicts:
        raise ValueError(f"all_hold: verdicts must be some of {VERDICTS}, got {verdicts}")
    if NO in verdicts:
        return NO
    if all(v == YES for v in verdicts):
        return YES
    return NOT_JUDGED if NOT_JUDGED in verdicts else NOISE
