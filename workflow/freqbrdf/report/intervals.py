"""Bootstrap intervals of the benchmark's means, and the rule that turns an interval into a verdict.

A mean over the benchmark is a mean over captures (each weighing the same) of the
capture's units: one value for a per-capture number (a parameter MSE, a correlation),
one per relighting environment and test view for a relighting score. Its interval is
a percentile bootstrap that resamples the captures and, within each drawn capture,
its units, both with replacement (a two-level bootstrap: captures differ more than the
views of one capture do). A comparison of two methods is bootstrapped as the mean of
their paired differences, unit by unit, so what the captures share cancels.

A claim holds (``yes``) when its criterion holds at the interval's unfavourable end,
fails (``no``) when it fails at the favourable end, and is ``within noise`` otherwise.
"""

from __future__ import annotations

from collections.abc import Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from freqbrdf.util.validation import check_int

__all__ = ["Bootstrap", "Interval", "VERDICTS", "all_hold", "bootstrap_weights", "judge", "mean_interval"]

YES, NO, NOISE, NOT_JUDGED = "yes", "no", "within noise", "not judged"
VERDICTS = (YES, NO, NOISE, NOT_JUDGED)
_OPS = {">": np.greater, ">=": np.greater_equal, "<": np.less, "<=": np.less_equal}


@dataclass(frozen=True)
class Bootstrap:
    """Settings of the intervals (config ``evaluate.intervals``; the seed derived from ``seed``).

    Attributes
    ----------
    level : float
        Coverage of each interval, in (0, 1).
    draws : int
        Bootstrap resamples.
    seed : int
        Seed of the resampling; every interval of a run uses the same draws of captures.
    """

    level: float = 0.95
    draws: int = 2000
    seed: int = 0

    def __post_init__(self) -> None:
        if not 0.0 < self.level < 1.0:
            raise ValueError(f"evaluate.intervals.level must be in (0, 1), got {self.level}")
        check_int(self.draws, "evaluate.intervals.draws", 1)

    @classmethod
    def from_config(cls, intervals: Mapping[str, object], seed: int) -> Bootstrap:
        """From config ``evaluate.intervals`` and a seed."""
        return cls(float(intervals["level"]), int(intervals["draws"]), int(seed))


@dataclass(frozen=True)
class Interval:
    """A statistic and its bootstrap interval.

    Attributes
    ----------
    value : float
        The statistic on the data (each capture weighing the same).
    low, high : float
        The interval's ends.
    captures, units : int
        How many captures and units it rests on.
    """

    value: float
    low: float
    high: float
    captures: int = 1
    units: int = 1

    def map(self, f) -> Interval:
        """The interval of a monotonically increasing function of the statistic (e.g. ``np.exp``)."""
        return Interval(float(f(self.value)), float(f(self.low)), float(f(self.high)), self.captures, self.units)


def bootstrap_weights(groups: Sequence[Hashable], boot: Bootstrap) -> tuple[np.ndarray, np.ndarray]:
    """Weights of the units in each bootstrap draw, and in the data itself.

    Parameters
    ----------
    groups : sequence, length N
        The capture of each unit.
    boot : Bootstrap

    Returns
    -------
    draws : ndarray, shape (boot.draws, N)
        Per draw, each unit's weight: the number of times its capture was drawn times the
        number of times the unit was drawn within it, over the capture's unit count.
    data : ndarray, shape (N,)
        One over the unit count of the unit's capture (every capture weighs 1).
    """
    labels, index = np.unique(np.array([str(g) for g in groups], dtype=object), return_inverse=True)
    if not len(index):
        raise ValueError("bootstrap_weights: no units")
    rng = np.random.default_rng(boot.seed)
    n_captures = len(labels)
    picked = rng.multinomial(n_captures, np.full(n_captures, 1.0 / n_captures), size=boot.draws)
    weights = np.zeros((boot.draws, len(index)))
    data = np.zeros(len(index))
    for k in range(n_captures):
        members = np.nonzero(index == k)[0]
        m = len(members)
        # c draws of the capture, each resampling its m units: together a multinomial of c m
        weights[:, members] = rng.multinomial(picked[:, k] * m, np.full(m, 1.0 / m)) / m
        data[members] = 1.0 / m
    return weights, data


def mean_interval(values: Sequence[float], groups: Sequence[Hashable], boot: Bootstrap) -> Interval:
    """The mean over captures of the mean over each capture's units, with its bootstrap interval.

    Parameters
    ----------
    values : sequence of float, length N
        One value per unit; NaN values are left out.
    groups : sequence, length N
        The capture of each unit (:func:`bootstrap_weights`).
    boot : Bootstrap

    Returns
    -------
    Interval
        NaN throughout when no value is finite.
    """
    v = np.asarray(values, dtype=np.float64)
    g = np.asarray([str(x) for x in groups], dtype=object)
    if v.shape != g.shape:
        raise ValueError(f"mean_interval: {v.size} values but {g.size} groups")
    keep = np.isfinite(v)
    if not keep.any():
        return Interval(float("nan"), float("nan"), float("nan"), 0, 0)
    v, g = v[keep], g[keep]
    draws, data = bootstrap_weights(list(g), boot)
    stats = draws @ v / draws.sum(axis=1)
    tail = 100.0 * (1.0 - boot.level) / 2.0
    low, high = np.percentile(stats, [tail, 100.0 - tail])
    return Interval(float(data @ v / data.sum()), float(low), float(high), len(set(g)), len(v))


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
