"""Queries on the tidy metrics table, the input of every table and claim.

The tidy table (`freqbrdf.layout.METRICS`) has one row per
number, columns ``object, env, poses, method, relight_env, view, metric, value``
(``relight_env`` empty for rows that are not about relighting; ``view`` empty but for
the relighting scores of single test views, whose mean over the views is the row
with an empty ``view``). Metric names:

- ``mse_base_color``, ``mse_roughness``, ``mse_metallic``, ``mse_average``:
  parameter MSE over observed texels (synthetic captures only);
- ``brdf_log_rmse``: the BRDF-space error over the same texels
  (:func:`freqbrdf.report.metrics.brdf_log_rmse`); ``base_color_si_psnr``,
  ``base_color_si_ssim``: the base colour after a per-channel scale
  (:func:`freqbrdf.report.metrics.base_color_si_scores`);
- ``psnr_h``, ``psnr_l``, ``ssim``, ``mse`` with ``relight_env`` set: relighting
  under a held-out environment, per test view and their mean;
- ``pearson_entropy_error``: per capture, correlation of our entropy with that
  method's per-texel squared parameter error; ``partial_pearson_entropy_error_views``:
  the same with the view count's linear part removed from both;
- ``ause_<map>_<error>``: per capture, the area between the sparsification curve
  of an uncertainty map (``entropy``, ``posterior``, ``views``, ``inv_sqrt_views``, ``light``,
  ``random``) and the oracle's, for the ``parameter`` or ``brdf`` error
  (:mod:`freqbrdf.report.sparsification`); ``partial_pearson_posterior_error_views``;
  ``coverage90_<texture>``, ``coverage90_all``: the share of true values inside the
  posterior's central 90% intervals, of config ``evaluate.interval_widths``
  (:func:`freqbrdf.report.sparsification.reliability`);
- ``time_s``, ``max_rss_mb``, ``time_total_s``, ``speed_ratio_vs_mitsuba``;
- ``mitsuba_time_to_match_s``, ``mitsuba_reached``, ``speed_ratio_equal_accuracy``:
  for the methods that need the observations, Mitsuba's time to reach their MSE
  and its ratio to their time from the capture (a lower bound when not reached);
  ``speed_ratio_at_mitsuba_converged``: Mitsuba's time to its own converged MSE over
  theirs (the paper's Table 2 comparison), and ``speed_ratio_at_mitsuba_accuracy``: the
  same for those at least as accurate (NaN for the others);
  ``mitsuba_last_epoch_change``, ``mitsuba_converged``, ``mitsuba_time_to_converge_s``:
  whether the baseline converged, and when.
"""

from __future__ import annotations

from os import PathLike

import pandas as pd

from freqbrdf.methods import METHODS
from freqbrdf.report.intervals import Interval, IntervalSettings, mean_interval

TIDY_COLUMNS = ("object", "env", "poses", "method", "relight_env", "view", "metric", "value")
_OPTIONAL = ("view",)  # a table without per-view rows may leave it out


def check_tidy(df: pd.DataFrame) -> pd.DataFrame:
    """Check the columns of a tidy metrics table and normalise ``relight_env``.

    Parameters
    ----------
    df : DataFrame
        Columns ``object, env, poses, method, relight_env, view, metric, value``; ``view``
        may be left out.

    Returns
    -------
    DataFrame
        A copy with ``method``, ``relight_env`` and ``view`` as strings ('' where empty) and
        ``value`` as float.

    Raises
    ------
    ValueError
        Naming the missing columns.
    """
    missing = [c for c in TIDY_COLUMNS if c not in df.columns and c not in _OPTIONAL]
    if missing:
        raise ValueError(f"metrics table lacks columns {missing} (has {list(df.columns)})")
    out = df.copy()
    for column in _OPTIONAL:
        if column not in out.columns:
            out.insert(list(TIDY_COLUMNS).index(column), column, "")
    # read_csv turns empty cells into NaN; compare them as ''. An empty method marks a
    # capture's own rows (the entropy agreement), an empty relight_env every row but relighting.
    for column in ("method", "relight_env", "view"):
        out[column] = out[column].fillna("").astype(str)
    out["value"] = pd.to_numeric(out["value"], errors="coerce").astype(float)
    return out


UNIT_KEYS = ("object", "env", "poses", "relight_env", "view")
"""The columns that name a unit of a mean: a capture's number, or one test view's relighting score."""


def unit_values(df: pd.DataFrame, method: str, metric: str) -> pd.Series:
    """One method's values of one metric per unit: per test view where the table holds them, else per row.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (see :func:`check_tidy`).
    method, metric : str

    Returns
    -------
    Series
        Indexed by :data:`UNIT_KEYS`; NaN values left out.
    """
    rows = df[(df.method == method) & (df.metric == metric)]
    views = rows[rows.view != ""]
    rows = views if len(views) else rows
    return rows.set_index(list(UNIT_KEYS)).value.dropna()


def read_tidy(path: str | PathLike[str]) -> pd.DataFrame:
    """Read and check a tidy metrics CSV (``metrics.csv``): names stay strings (a test view
    ``0001`` is not the number 1), empty cells are ''.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    DataFrame
        As :func:`check_tidy` returns it.
    """
    names = {column: str for column in TIDY_COLUMNS if column != "value"}
    return check_tidy(pd.read_csv(path, keep_default_na=False, na_values=[""], dtype=names))


def mitsuba_convergence(df: pd.DataFrame) -> tuple[bool, str]:
    """Whether the ``mitsuba`` baseline converged on every capture (``mitsuba_converged``), and
    how the tables and claims say it: ``converged``, ``not converged on k of n captures`` or
    ``convergence unknown`` (no MSE curve)."""
    flags = df[(df.method == "mitsuba") & (df.metric == "mitsuba_converged")].value.dropna()
    if flags.empty:
        return False, "convergence unknown"
    missed = int((flags != 1.0).sum())
    return missed == 0, "converged" if missed == 0 else f"not converged on {missed} of {len(flags)} captures"


def cluster_keys(*methods: str) -> tuple[str, ...]:
    """The columns that name an interval's independent draw for numbers of ``methods``: the
    capture, or the object where one of them merges an object's captures (one texture set per
    object, filed under each of its captures)."""
    merged = any(m in METHODS and METHODS[m].rule == "merge_svbrdf" for m in methods)
    return ("object",) if merged else ("object", "env", "poses")


def metric_interval(values: pd.Series, settings: IntervalSettings,
                    clusters: tuple[str, ...] = ("object", "env", "poses")) -> Interval | None:
    """The mean over clusters of per-unit values (:func:`unit_values`) with its interval.

    Parameters
    ----------
    values : Series
        Indexed by :data:`UNIT_KEYS`.
    settings : IntervalSettings
    clusters : tuple of str
        Index levels naming a unit's cluster (:func:`cluster_keys`).

    Returns
    -------
    Interval or None
        None when there are no values.
    """
    if values.empty:
        return None
    frame = values.index.to_frame(index=False)
    groups = frame[list(clusters)].astype(str).agg("/".join, axis=1).tolist()
    return mean_interval(values.to_numpy(), groups, settings)


def mean_metric(df: pd.DataFrame, method: str, metric: str, **where: str) -> float | None:
    """Mean of one metric of one method over all matching rows (per capture and relighting
    environment: the rows of single views are left out), or None if there are none.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (see :func:`check_tidy`).
    method, metric : str
    **where : str
        Further equality filters, e.g. ``env="studio"``.
    """
    rows = df[(df.method == method) & (df.metric == metric) & (df.view == "")]
    for column, value in where.items():
        rows = rows[rows[column] == value]
    values = rows.value.dropna()
    return float(values.mean()) if len(values) else None


def method_time(df: pd.DataFrame, method: str) -> float | None:
    """Mean time of a method per capture: ``time_total_s`` (the method and the
    steps it needs, e.g. SH fits), else ``time_s`` (its own rule only)."""
    total = mean_metric(df, method, "time_total_s")
    return total if total is not None else mean_metric(df, method, "time_s")


def speed_ratio(df: pd.DataFrame, method: str) -> float | None:
    """How many times faster than Mitsuba a method is: the mean of
    ``speed_ratio_vs_mitsuba`` if present, else the ratio of mean times."""
    ratio = mean_metric(df, method, "speed_ratio_vs_mitsuba")
    if ratio is not None:
        return ratio
    t_method, t_mitsuba = method_time(df, method), method_time(df, "mitsuba")
    if t_method is None or t_mitsuba is None or t_method <= 0:
        return None
    return t_mitsuba / t_method


def ran(df: pd.DataFrame, *methods: str) -> bool:
    """Whether every one of ``methods`` has a row."""
    return all((df.method == m).any() for m in methods)


def equal_accuracy_ratio(df: pd.DataFrame, method: str) -> tuple[float | None, bool]:
    """The smallest ``speed_ratio_equal_accuracy`` of a method over the captures, and whether
    it is exact (``mitsuba`` reached the method's MSE on every capture) or only a lower bound."""
    rows = df[(df.method == method) & (df.metric == "speed_ratio_equal_accuracy")].dropna(subset=["value"])
    if rows.empty:
        return None, False
    reached = df[(df.method == method) & (df.metric == "mitsuba_reached")].value
    return float(rows.value.min()), bool(len(reached) and (reached == 1.0).all())


def capture_metric(df: pd.DataFrame, metric: str) -> pd.Series:
    """Per-capture values of a metric of the captures themselves (rows with an empty method)."""
    return df[(df.method == "") & (df.metric == metric)].value.dropna()


def views_sweep(df: pd.DataFrame) -> pd.DataFrame:
    """The views sweep's rows as a table: ``object, env, views, mse_average, mean_entropy``."""
    rows = df[df.metric.str.fullmatch(r"views_\d+_(mse_average|mean_entropy)")]
    if rows.empty:
        return pd.DataFrame(columns=["object", "env", "views", "mse_average", "mean_entropy"])
    parts = rows.metric.str.extract(r"views_(\d+)_(\w+)")
    wide = rows.assign(views=parts[0].astype(int), quantity=parts[1]).pivot_table(
        index=["object", "env", "views"], columns="quantity", values="value").reset_index()
    return wide.sort_values(["object", "env", "views"])
