"""How the tables show numbers and methods: the cells ``not run`` (:data:`NOT_RUN`, a method
without a row) and ``-`` (:data:`MISSING`, a method that ran but lacks a metric), numbers
and times, and the methods' display names and order (from the registry :mod:`freqbrdf.methods`)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from decimal import ROUND_HALF_UP, Decimal

from freqbrdf.methods import METHODS

NOT_RUN = "not run"
MISSING = "-"


def fmt(value: float | None, digits: int = 3, unit: str = "") -> str:
    """A number for display; ``-`` for None or NaN."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return MISSING
    return f"{value:.{digits}f}{unit}"


def fmt_interval(interval, digits: int = 3, unit: str = "", sign: bool = False) -> str:
    """A statistic and its interval, e.g. ``0.036 [0.031, 0.042]``; ``0.036 [n = 1]`` without one;
    ``-`` for None or NaN.

    Parameters
    ----------
    interval : freqbrdf.report.intervals.Interval or None
    digits : int
        Decimals.
    unit : str
        Appended to each number.
    sign : bool
        Show a + on positive numbers (differences).
    """
    if interval is None or math.isnan(interval.value):
        return MISSING
    form = f"{'+' if sign else ''}.{digits}f"
    if math.isnan(interval.low):  # one capture (or object): no interval
        return f"{interval.value:{form}}{unit} [n = {interval.clusters}]"
    value, low, high = (f"{x:{form}}{unit}" for x in (interval.value, interval.low, interval.high))
    return f"{value} [{low}, {high}]"


def fmt_time(seconds: float | None) -> str:
    """Seconds with three significant digits, e.g. ``3.14 s``, ``105 s``."""
    if seconds is None or math.isnan(seconds):
        return MISSING
    return f"{seconds:.3g} s" if seconds < 1000 else f"{seconds:.0f} s"


def fmt_paper(value: float, digits: int, sign: bool = False) -> str:
    """A paper's number rounded half up as its decimal form reads, for the claims' text.

    ``f"{26.595:.2f}"`` gives ``26.59``, the binary float lying just below;
    this gives ``26.60``, as the paper's 26.595 rounds.
    """
    rounded = Decimal(repr(value)).quantize(Decimal(1).scaleb(-digits), rounding=ROUND_HALF_UP)
    return format(rounded, "+f" if sign else "f")


def fmt_ratio(ratio: float | None, exact: bool = True) -> str:
    """A speed-up such as ``13.3x``; ``>= 13.3x`` for a lower bound."""
    return MISSING if ratio is None else f"{'' if exact else '>= '}{ratio:.1f}x"


def method_label(method: str) -> str:
    """The display name of a registered method; an unregistered one (an old run's) shows its name."""
    return METHODS[method].label if method in METHODS else method


def ordered_methods(methods: Iterable[str]) -> list[str]:
    """Distinct method names in the registry's order (that of tables and figures), then unregistered ones by name."""
    order = list(METHODS)
    return sorted(set(methods), key=lambda m: (order.index(m) if m in order else len(order), m))
