"""The paper's Tables 1 to 6 and the run's headline numbers, from the tidy metrics
(:mod:`freqbrdf.report.tables.tidy`), beside the paper's numbers (:mod:`freqbrdf.report.tables.paper`).

Which of our methods stands beside which of the paper's rows, the methods' labels and their
order come from the registry :mod:`freqbrdf.methods`.

Every summary is a mean over the rows given (objects, capture environments,
relighting environments); callers select one pose source first. A method that
has no row at all is shown as ``not run``; a method that ran but lacks a
metric as ``-``. The tables are DataFrames of display strings, rendered by
:mod:`freqbrdf.report.tables.render`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import pandas as pd

from freqbrdf.methods import METHODS, ablation_method, paper_method
from freqbrdf.report.intervals import IntervalSettings
from freqbrdf.report.tables.display import (MISSING, NOT_RUN, fmt, fmt_interval, fmt_paper, fmt_ratio, fmt_time,
                                            method_label, ordered_methods)
from freqbrdf.report.tables.paper import AGREEMENT_ROWS, AVERAGE, MERGE_AVERAGE, MITSUBA, PaperResults
from freqbrdf.report.tables.tidy import (capture_metric, cluster_keys, equal_accuracy_ratio, mean_metric,
                                         method_time, metric_interval, ran, speed_ratio, unit_values)
from freqbrdf.sphere.brdf import TEXTURES


def _ours(df: pd.DataFrame, method: str | None, text: str) -> str:
    """A cell of our numbers: ``not run`` when the method has no row at all."""
    if method is None or not (df.method == method).any():
        return NOT_RUN
    return text


def _mse_cell(values: Sequence[float | None], digits: int, average: str | None = None) -> str:
    """``avg (base, roughness, metallic)`` as in the paper's Table 2; ``average`` replaces the
    first number's text (e.g. with its interval)."""
    avg, *parts = values
    if avg is None:
        return MISSING
    return f"{average or fmt(avg, digits)} ({', '.join(fmt(p, digits) for p in parts)})"


def _mean(df: pd.DataFrame, method: str | None, metric: str, digits: int, intervals: IntervalSettings | None) -> str:
    """A method's mean of a metric over the captures (and test views), with its interval when
    ``intervals`` is given (:mod:`freqbrdf.report.intervals`); ``-`` when it has none."""
    if method is None:
        return MISSING
    if intervals is None:
        return fmt(mean_metric(df, method, metric), digits)
    return fmt_interval(metric_interval(unit_values(df, method, metric), intervals, cluster_keys(method)), digits)


_RELIGHT_METRICS = (("psnr_h", "PSNR-H", 2), ("psnr_l", "PSNR-L", 2), ("ssim", "SSIM", 3))
_MSE_METRICS = ("mse_average", "mse_base_color", "mse_roughness", "mse_metallic")
# Beside the MSE in Table 2, each a mean over captures: (metric, column, decimals)
_BRDF_METRICS = (("brdf_log_rmse", "BRDF log-RMSE", 3), ("base_color_si_psnr", "Base SI-PSNR", 2),
                 ("base_color_si_ssim", "Base SI-SSIM", 3))


def _relight_cells(df: pd.DataFrame, method: str | None, paper: Mapping[str, float] | None,
                   intervals: IntervalSettings | None = None) -> dict[str, str]:
    """PSNR-H, PSNR-L and SSIM of a method (mean over captures, relighting
    environments and test views, with its interval when ``intervals`` is given), each
    followed by the paper's value."""
    cells = {}
    for metric, label, digits in _RELIGHT_METRICS:
        cells[label] = _ours(df, method, _mean(df, method, metric, digits, intervals))
        cells[f"{label} (paper)"] = fmt(paper[metric], digits) if paper else MISSING
    return cells


def relighting_table(df: pd.DataFrame, paper: PaperResults, intervals: IntervalSettings | None = None) -> pd.DataFrame:
    """Paper Table 1: relighting under held-out environments, per method.

    Rows are the paper's (ours beside them where the registry has one, ``not
    run`` otherwise), then any other method of ours with relighting numbers.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (:func:`freqbrdf.report.tables.tidy.check_tidy`).
    paper : PaperResults
    intervals : IntervalSettings, optional
        Show each mean with its interval.

    Returns
    -------
    DataFrame of str
        ``Method, method, PSNR-H, PSNR-H (paper), PSNR-L, ..., Time, Time (paper)``, and the
        speed-up over Mitsuba at its fixed budget, at equal parameter MSE, and the paper's.
    """
    rows = []
    for label, values in paper.table1.items():
        method = paper_method("table1", label)
        row = {"Method": label, "method": method or MISSING, **_relight_cells(df, method, values, intervals)}
        row["Time"] = _ours(df, method, fmt_time(method_time(df, method)) if method else MISSING)
        row["Time (paper)"] = fmt_time(values["time_s"])
        row |= _speed_cells(df, method, paper.table1[MITSUBA]["time_s"] / values["time_s"])
        rows.append(row)
    listed = {paper_method("table1", label) for label in paper.table1}
    for method in ordered_methods(df[df.relight_env != ""].method):
        if method in listed:
            continue
        row = {"Method": method_label(method), "method": method, **_relight_cells(df, method, None, intervals)}
        row["Time"] = fmt_time(method_time(df, method))
        row["Time (paper)"] = MISSING
        row |= _speed_cells(df, method, None)
        rows.append(row)
    return pd.DataFrame(rows)


def _speed_cells(df: pd.DataFrame, method: str | None, paper_ratio: float | None) -> dict[str, str]:
    """How many times faster than Mitsuba: at its fixed budget, at equal parameter MSE
    (fewest over captures), and the paper's (Table 1 times)."""
    fixed = speed_ratio(df, method) if method and ran(df, method, "mitsuba") and method != "mitsuba" else None
    equal, exact = equal_accuracy_ratio(df, method) if method else (None, False)
    return {"x Mitsuba": _ours(df, method, fmt_ratio(fixed)),
            "x Mitsuba, equal MSE": _ours(df, method, fmt_ratio(equal, exact)),
            "x Mitsuba (paper)": fmt_ratio(paper_ratio)}


def _ordered_envs(df: pd.DataFrame, env_kinds: Mapping[str, str]) -> list[str]:
    """Capture environments with parameter MSE, in configuration order, then the rest."""
    present = set(df[df.metric == "mse_average"].env) | set(df[df.metric == "pearson_entropy_error"].env)
    order = list(env_kinds)
    return sorted(present, key=lambda e: (order.index(e) if e in order else len(order), e))


def _paper_column(env: str, env_kinds: Mapping[str, str], paper: PaperResults) -> str | None:
    """The paper's environment of the same kind as ours, if it has one."""
    return paper.environments.get(env_kinds.get(env, env))


def _mse_rows(df: pd.DataFrame, paper: PaperResults, headers: Mapping[str, str],
              env_kinds: Mapping[str, str], digits: int, intervals: IntervalSettings | None) -> list[dict[str, str]]:
    """The MSE rows of Table 2: the paper's rows, each with ours below, then our other methods."""
    paired = [(label, paper_method("table2", label)) for label in paper.table2]
    listed = {method for _, method in paired}
    extra = [(None, m) for m in ordered_methods(df[df.metric == "mse_average"].method) if m not in listed]
    rows = []
    for label, method in paired + extra:
        name = f"{method_label(method)} ({method})" if method else label
        if label is not None:
            values = paper.table2[label]
            row = {"Method": name, "source": "paper"}
            for env, header in headers.items():
                column = _paper_column(env, env_kinds, paper)
                row[header] = _mse_cell(values.mse[column], 2) if column else MISSING
            row["Avg."] = _mse_cell(values.mse[AVERAGE], 2)
            row["Time"] = fmt_time(values.time_s)
            rows.append(row)
        row = {"Method": name, "source": "here"}
        for env, header in headers.items():
            parts = [mean_metric(df, method, p, env=env) for p in _MSE_METRICS]
            row[header] = _ours(df, method, _mse_cell(parts, digits))
        average = _mean(df, method, "mse_average", digits, intervals) if intervals else None
        row["Avg."] = _ours(df, method, _mse_cell([mean_metric(df, method, p) for p in _MSE_METRICS], digits, average))
        for metric, label, decimals in _BRDF_METRICS:
            row[label] = _ours(df, method, fmt(mean_metric(df, method, metric), decimals))
        row["Time"] = _ours(df, method, fmt_time(method_time(df, method)))
        rows.append(row)
    return rows


def _correlation_rows(df: pd.DataFrame, paper: PaperResults, headers: Mapping[str, str],
                      env_kinds: Mapping[str, str]) -> list[dict[str, str]]:
    """The error-entropy correlation rows of Table 2: the paper's, above the method it
    correlates with, then every other method whose error ``metrics`` correlates."""
    correlated = paper_method("table2", paper.correlation_with)
    scored = [m for m, entry in METHODS.items() if entry.entropy_scored and m != correlated]
    rows = []
    for method in ([correlated] if correlated else []) + scored:
        label = f"Error-entropy correlation ({method})"
        if method == correlated:
            row = {"Method": label, "source": "paper"}
            for env, header in headers.items():
                column = _paper_column(env, env_kinds, paper)
                row[header] = fmt(paper.correlation[column], 2) if column else MISSING
            row["Avg."] = fmt(paper.correlation[AVERAGE], 2)
            row["Time"] = MISSING
            rows.append(row)
        row = {"Method": label, "source": "here"}
        for env, header in headers.items():
            row[header] = _ours(df, method, fmt(mean_metric(df, method, "pearson_entropy_error", env=env), 2))
        row["Avg."] = _ours(df, method, fmt(mean_metric(df, method, "pearson_entropy_error"), 2))
        row["Time"] = MISSING
        rows.append(row)
    return rows


def parameter_table(df: pd.DataFrame, paper: PaperResults, env_kinds: Mapping[str, str] | None = None,
                    digits: int = 3, intervals: IntervalSettings | None = None) -> pd.DataFrame:
    """Paper Table 2: parameter MSE per capture environment, with the error-entropy correlation.

    Cells read ``average (base colour, roughness, metallic)``, means over
    objects. For each of the paper's rows, a ``paper`` row sits above our
    (``here``) row; its environment columns hold the paper's value for the
    environment of the same kind (``env_kinds``), e.g. Rural Road for sunny.
    Our rows add the BRDF-space error and the scale-invariant base colour
    PSNR and SSIM, means over all captures (the paper has neither).

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (:func:`freqbrdf.report.tables.tidy.check_tidy`).
    paper : PaperResults
    env_kinds : mapping, optional
        Our environment name -> kind (``studio``, ``museum``, ``sunny``,
        ``overcast``); by default an environment's name is its kind.
    digits : int
        Decimals of our numbers (the paper prints 2).
    intervals : IntervalSettings, optional
        Show our average MSE over all captures with its interval.

    Returns
    -------
    DataFrame of str
        ``Method, source, <env> [paper: <name>] ..., Avg., BRDF log-RMSE, Base SI-PSNR, Base SI-SSIM, Time``.
    """
    env_kinds = dict(env_kinds or {})
    headers = {}
    for env in _ordered_envs(df, env_kinds):
        column = _paper_column(env, env_kinds, paper)
        headers[env] = f"{env} [paper: {column}]" if column else env
    rows = _mse_rows(df, paper, headers, env_kinds, digits, intervals) + _correlation_rows(df, paper, headers, env_kinds)
    columns = ["Method", "source", *headers.values(), "Avg.", *(label for _, label, _ in _BRDF_METRICS), "Time"]
    return pd.DataFrame(rows, columns=columns).fillna(MISSING)


def ablation_table(df: pd.DataFrame, paper: PaperResults, digits: int = 3, intervals: IntervalSettings | None = None) -> pd.DataFrame:
    """Paper Table 4: the BRDF model with and without shadowing and masking.

    Our relighting metrics (synthetic, held-out environments) stand beside the
    paper's Stanford-ORB ones, our parameter MSE and time beside the paper's
    synthetic ones.

    Returns
    -------
    DataFrame of str
        ``Shadowing, Masking, method, PSNR-H, PSNR-H (paper), ..., MSE, MSE (paper), Time, Time (paper)``.
    """
    rows = []
    for values in paper.table4.values():
        method = ablation_method(values.shadowing, values.masking)
        row = {"Shadowing": "yes" if values.shadowing else "no", "Masking": "yes" if values.masking else "no",
               "method": method, **_relight_cells(df, method, values.values, intervals)}
        row["MSE"] = _ours(df, method, _mean(df, method, "mse_average", digits, intervals))
        row["MSE (paper)"] = fmt(values.values["mse"], 2)
        row["Time"] = _ours(df, method, fmt_time(method_time(df, method)))
        row["Time (paper)"] = fmt_time(values.values["time_s"])
        rows.append(row)
    return pd.DataFrame(rows)


def finetune_table(df: pd.DataFrame, paper: PaperResults, digits: int = 3, intervals: IntervalSettings | None = None) -> pd.DataFrame:
    """Paper Table 5: a short Mitsuba fine-tuning pass from different initialisations.

    Our parameter MSE is added (the paper reports none for this table).

    Returns
    -------
    DataFrame of str
        ``Initialization, method, PSNR-H, PSNR-H (paper), ..., MSE, Total time, Total time (paper)``.
    """
    rows = []
    for label, values in paper.table5.items():
        method = paper_method("table5", label)
        row = {"Initialization": label, "method": method or MISSING, **_relight_cells(df, method, values, intervals)}
        row["MSE"] = _ours(df, method, _mean(df, method, "mse_average", digits, intervals))
        row["Total time"] = _ours(df, method, fmt_time(method_time(df, method)) if method else MISSING)
        row["Total time (paper)"] = fmt_time(values["time_s"])
        rows.append(row)
    return pd.DataFrame(rows)


def merge_table(df: pd.DataFrame, paper: PaperResults, digits: int = 3, intervals: IntervalSettings | None = None) -> pd.DataFrame:
    """Paper Table 6: each merged method beside the mean of the estimates it merges.

    Returns
    -------
    DataFrame of str
        ``Method, method, MSE, MSE (paper)``: for every ``merge_svbrdf`` method of the run,
        a row for the average over the separate captures of its start method, then its own,
        each as ``average (base colour, roughness, metallic)``.
    """
    rows = []
    for method in ordered_methods(df[df.metric == "mse_average"].method):
        entry = METHODS[method]
        if entry.rule != "merge_svbrdf":
            continue
        merged_row = entry.paper_rows.get("table6")
        for shown, label, paper_row in ((entry.start, f"{method_label(entry.start)}, average over captures",
                                         MERGE_AVERAGE if merged_row else None),
                                        (method, method_label(method), merged_row)):
            parts = [mean_metric(df, shown, f"mse_{k}") for k in ("average", "base_color", "roughness", "metallic")]
            average = _mean(df, shown, "mse_average", digits, intervals) if intervals else None
            rows.append({"Method": label, "method": shown, "MSE": _mse_cell(parts, digits, average),
                         "MSE (paper)": _mse_cell(paper.table6[paper_row], 2) if paper_row else MISSING})
    return pd.DataFrame(rows, columns=["Method", "method", "MSE", "MSE (paper)"])


def agreement_table(df: pd.DataFrame, paper: PaperResults, digits: int = 2) -> pd.DataFrame:
    """Paper Table 3: each entropy's Pearson correlation with the Mitsuba grid's, and its time.

    Returns
    -------
    DataFrame of str
        ``Entropy, Pearson, Pearson (half the paths), Time, Pearson (paper), Time (paper)``:
        means (and standard deviations) over the captures of the run's
        ``entropy_agreement_*`` rows; ``-`` where the rule did not run.
    """
    rows = []
    for name, label in AGREEMENT_ROWS.items():
        if name == "mitsuba":
            r, r_half = pd.Series([1.0]), capture_metric(df, "entropy_agreement_pearson_mitsuba_reduced")
        else:
            r = capture_metric(df, f"entropy_agreement_pearson_{name}")
            r_half = capture_metric(df, f"entropy_agreement_pearson_{name}_reduced")
        seconds = capture_metric(df, f"entropy_agreement_time_{name}_s")
        ran = len(seconds) > 0
        spread = f" \u00b1 {r.std(ddof=0):.{digits}f}" if len(r) > 1 else ""
        rows.append({
            "Entropy": label,
            "Pearson": f"{r.mean():.{digits}f}{spread}" if ran and len(r) else MISSING,
            "Pearson (half the paths)": fmt(r_half.mean() if len(r_half) else None, digits),
            "Time": fmt_time(seconds.mean() if ran else None),
            "Pearson (paper)": f"{fmt_paper(paper.table3[label]['pearson'], 2)} \u00b1 "
                               f"{fmt_paper(paper.table3[label]['std'], 2)}",
            "Time (paper)": fmt_time(paper.table3[label]["time_s"]),
        })
    return pd.DataFrame(rows, columns=["Entropy", "Pearson", "Pearson (half the paths)", "Time", "Pearson (paper)",
                                       "Time (paper)"])


def headline_table(df: pd.DataFrame, intervals: IntervalSettings | None = None) -> pd.DataFrame:
    """The run's headline numbers: one row per method (registry order), means over the captures.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (:func:`freqbrdf.report.tables.tidy.check_tidy`).
    intervals : IntervalSettings, optional
        Show the MSE and PSNR-H with their intervals.

    Returns
    -------
    DataFrame of str
        ``Method, Parameter MSE, PSNR-H, Time``: the display name with the config name
        (``Ours (freq)``, as the summary lists the methods), average parameter MSE
        (observed texels), PSNR-H (dB, held-out relighting) and time per capture. The
        captures' own rows (empty method: the entropy agreement) are no method's.
    """
    rows = [{"Method": f"{method_label(m)} ({m})", "Parameter MSE": _mean(df, m, "mse_average", 3, intervals),
             "PSNR-H": _mean(df, m, "psnr_h", 2, intervals), "Time": fmt_time(method_time(df, m))}
            for m in ordered_methods(df.method[df.method != ""])]
    return pd.DataFrame(rows, columns=["Method", "Parameter MSE", "PSNR-H", "Time"])


UNCERTAINTY_MAPS = (("entropy", "Entropy"), ("posterior", "Posterior"), ("views", "-views"), ("light", "-light"),
                    ("random", "Random"))
"""The uncertainty maps of :func:`uncertainty_table`'s AUSE columns: metric part, column label."""


def uncertainty_table(df: pd.DataFrame, intervals: IntervalSettings | None = None, digits: int = 3) -> pd.DataFrame:
    """How well the entropy ranks each entropy-scored method's per-texel errors, against trivial baselines.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics with ``ause_<map>_<error>``, ``pearson_entropy_error`` and
        ``partial_pearson_entropy_error_views`` rows (:mod:`freqbrdf.report.sparsification`).
    intervals : IntervalSettings, optional
        Show each mean with its interval over captures.

    Returns
    -------
    DataFrame of str
        ``Method, Error, AUSE: Entropy, Posterior, -views, -light, Random, Pearson r, partial r | views,
        90% coverage, 90% coverage, worst``: one row per method and error (parameter, BRDF); lower AUSE ranks better (the
        posterior's only for the methods of rule optimise_svbrdf); the correlations (parameter error
        only) with the entropy, then with the view count's linear part removed; the share of true
        parameters inside the posterior's 90% intervals, pooled and at its lowest over the captures
        and parameters (named).
    """
    rows = []
    for method in ordered_methods(df.method[df.metric == "ause_entropy_parameter"]):
        for error, label in (("parameter", "parameter"), ("brdf", "BRDF")):
            row = {"Method": f"{method_label(method)} ({method})", "Error": label}
            row |= {f"AUSE: {title}": _mean(df, method, f"ause_{name}_{error}", digits, intervals)
                    for name, title in UNCERTAINTY_MAPS}
            correlations = error == "parameter"
            row["Pearson r"] = _mean(df, method, "pearson_entropy_error", 2, intervals) if correlations else ""
            row["partial r | views"] = (_mean(df, method, "partial_pearson_entropy_error_views", 2, intervals)
                                        if correlations else "")
            row["90% coverage"] = _mean(df, method, "coverage90_all", 3, intervals) if correlations else ""
            row["90% coverage, worst"] = _worst_coverage(df, method, 3) if correlations else ""
            rows.append(row)
    columns = ["Method", "Error", *(f"AUSE: {t}" for _, t in UNCERTAINTY_MAPS), "Pearson r", "partial r | views",
               "90% coverage", "90% coverage, worst"]
    return pd.DataFrame(rows, columns=columns)


def _worst_coverage(df: pd.DataFrame, method: str, digits: int) -> str:
    """The lowest ``coverage90_<texture>`` over the captures and textures, e.g. ``0.815 (sphere/lobby,
    roughness)``: the pooled coverage can hold while one capture's parameter misses; ``-`` without rows."""
    names = {f"coverage90_{t}": t for t in TEXTURES}
    rows = df[(df.method == method) & df.metric.isin(list(names)) & (df.view == "")].dropna(subset=["value"])
    if rows.empty:
        return MISSING
    worst = rows.loc[rows.value.idxmin()]
    return f"{fmt(worst.value, digits)} ({worst.object}/{worst.env}, {names[worst.metric]})"
