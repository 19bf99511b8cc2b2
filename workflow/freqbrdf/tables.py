"""Summary tables and the claims table, from the tidy metrics table, beside the paper's numbers.

Input everywhere is the tidy table ``results/tables/metrics.csv``: one row per
number, columns ``object, env, poses, method, relight_env, metric, value``
(``relight_env`` empty for rows that are not about relighting). Metric names:

- ``mse_base_color``, ``mse_roughness``, ``mse_metallic``, ``mse_average``:
  parameter MSE over observed texels (synthetic captures only);
- ``brdf_log_rmse``: the BRDF-space error over the same texels
  (:func:`freqbrdf.metrics.brdf_log_rmse`); ``base_color_si_psnr``,
  ``base_color_si_ssim``: the base colour after a per-channel scale
  (:func:`freqbrdf.metrics.base_color_si_scores`);
- ``psnr_h``, ``psnr_l``, ``ssim``, ``mse`` with ``relight_env`` set: relighting
  under a held-out environment, mean over the test views;
- ``pearson_entropy_error``: per capture, correlation of our entropy with that
  method's per-texel squared parameter error;
- ``time_s``, ``max_rss_mb``, ``time_total_s``, ``speed_ratio_vs_mitsuba``;
- ``mitsuba_time_to_match_s``, ``mitsuba_reached``, ``speed_ratio_equal_accuracy``:
  for the methods that need the observations, Mitsuba's time to reach their MSE
  and its ratio to their time from the capture (a lower bound when not reached).

The paper's numbers come from ``config/paper_results.yaml``
(:func:`read_paper_results`); which of our methods stands beside which of the
paper's rows, the methods' labels and their order come from the registry
:mod:`freqbrdf.methods`.

Every summary is a mean over the rows given (objects, capture environments,
relighting environments); callers select one pose source first. A method that
has no row at all is shown as ``not run``; a method that ran but lacks a
metric as ``-``. The tables are DataFrames of display strings, rendered by
:func:`to_markdown` (hand-written: pandas' own needs ``tabulate``),
:func:`to_latex` and :func:`to_html` (pandas' Styler, which needs ``jinja2``).
"""

from __future__ import annotations

import dataclasses
import html
import math
import re
import zlib
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass
from decimal import ROUND_HALF_UP, Decimal
from itertools import product
from os import PathLike

import pandas as pd
import yaml
from pandas.io.formats.style import Styler

from .methods import METHODS, ablation_method, paper_method

NOT_RUN = "not run"
MISSING = "-"

# ---------------------------------------------------------------------------
# The paper's numbers (config/paper_results.yaml)
# ---------------------------------------------------------------------------

RELIGHT_FIELDS = ("psnr_h", "psnr_l", "ssim", "lpips", "time_s")
"""Numbers of a row of the paper's Tables 1 and 5."""
ABLATION_FIELDS = ("psnr_h", "psnr_l", "ssim", "lpips", "time_orb_s", "mse", "time_s")
"""Numbers of a row of the paper's Table 4 (besides its shadowing and masking flags)."""
AVERAGE = "Average"
"""The key of the paper's Table 2 values averaged over its environments."""
AGREEMENT_FIELDS = ("pearson", "std", "time_s")
"""Numbers of a row of the paper's Table 3."""
CRITERIA_FIELDS = ("accuracy_tolerance_mse", "relight_tolerance_db", "finetune_time_divisor")

# The paper's rows that the claims quote: Tables 1 and 2 label their methods
# alike; in Table 5, "Ours" is fine-tuned and the last row is Mitsuba alone.
MITSUBA, OURS, SPECTRUM = "Mitsuba", "Ours", "Ours-Spectrum Only"
FINETUNED, MITSUBA_FULL = "Ours", "Full optimization - Constant"
MERGE_AVERAGE = "Average"  # Table 6: the mean over the separate environments
# Table 3's rows, keyed by the entropy of freqbrdf.entropy_agreement they stand beside.
AGREEMENT_ROWS = {"mitsuba": "Entropy Mitsuba", "angular": "Entropy angular", "spectrum": "Entropy power spectrum"}
CLAIM_ROWS = {"table1": (MITSUBA, OURS), "table2": (MITSUBA, OURS, SPECTRUM), "table5": (FINETUNED, MITSUBA_FULL),
              "table6": (MERGE_AVERAGE,), "table3": tuple(AGREEMENT_ROWS.values())}


class PaperResultsError(ValueError):
    """The paper's results file is malformed; the one-line message names the file and the key."""


@dataclass(frozen=True)
class ParameterRow:
    """One method row of the paper's Table 2.

    Attributes
    ----------
    mse : Mapping[str, tuple of float]
        Paper environment name, or :data:`AVERAGE`, -> (average, base colour,
        roughness, metallic) parameter MSE.
    time_s : float
        Optimisation time on the authors' GPU machine.
    """

    mse: Mapping[str, tuple[float, float, float, float]]
    time_s: float


@dataclass(frozen=True)
class AblationRow:
    """One row of the paper's Table 4: which terms the model has, and its numbers (:data:`ABLATION_FIELDS`)."""

    shadowing: bool
    masking: bool
    values: Mapping[str, float]


@dataclass(frozen=True)
class ClaimCriteria:
    """Thresholds of the claims table, derived from the paper's numbers (see the YAML's comments)."""

    accuracy_tolerance_mse: float
    relight_tolerance_db: float
    finetune_time_divisor: float


@dataclass(frozen=True)
class PaperResults:
    """The paper's numbers, keyed by its row labels (``config/paper_results.yaml``).

    Attributes
    ----------
    table1, table5 : Mapping[str, Mapping[str, float]]
        Row label -> :data:`RELIGHT_FIELDS` -> value.
    environments : Mapping[str, str]
        Kind of our environment -> name of the paper's environment of that kind (Table 2).
    table2 : Mapping[str, ParameterRow]
        Row label -> parameter MSE and time.
    correlation_with : str
        The Table 2 row whose per-texel error the paper correlates with our entropy.
    correlation : Mapping[str, float]
        Paper environment name, or :data:`AVERAGE`, -> that correlation.
    table3 : Mapping[str, Mapping[str, float]]
        Row label -> :data:`AGREEMENT_FIELDS` -> value (entropy agreement).
    table4 : Mapping[str, AblationRow]
        Row label -> flags and numbers; one row per (shadowing, masking) pair.
    table6 : Mapping[str, tuple of float]
        Row label -> (average, base colour, roughness, metallic) MSE of the entropy-guided merge.
    criteria : ClaimCriteria
    """

    table1: Mapping[str, Mapping[str, float]]
    environments: Mapping[str, str]
    table2: Mapping[str, ParameterRow]
    correlation_with: str
    correlation: Mapping[str, float]
    table3: Mapping[str, Mapping[str, float]]
    table4: Mapping[str, AblationRow]
    table5: Mapping[str, Mapping[str, float]]
    table6: Mapping[str, tuple[float, float, float, float]]
    criteria: ClaimCriteria

    def ablation_row(self, shadowing: bool, masking: bool) -> AblationRow:
        """The Table 4 row with this (shadowing, masking) pair."""
        return next(r for r in self.table4.values() if (r.shadowing, r.masking) == (shadowing, masking))


def _key(where: str, key: object) -> str:
    return f"{where}.{key}" if where else str(key)


def _mapping(node: object, where: str) -> Mapping[str, object]:
    """A non-empty mapping with string keys."""
    if not isinstance(node, Mapping) or not node:
        raise PaperResultsError(f"key {where or '<top level>'}: expected a non-empty mapping, got {node!r:.60}")
    for key in node:
        if not isinstance(key, str):
            raise PaperResultsError(f"key {_key(where, key)}: labels must be strings")
    return node


def _record(node: object, where: str, fields: Sequence[str]) -> Mapping[str, object]:
    """A mapping with exactly the keys ``fields``."""
    node = _mapping(node, where)
    missing = [f for f in fields if f not in node]
    if missing:
        raise PaperResultsError(f"key {_key(where, missing[0])}: missing")
    unexpected = [k for k in node if k not in fields]
    if unexpected:
        raise PaperResultsError(f"key {_key(where, unexpected[0])}: unexpected (expected {', '.join(fields)})")
    return node


def _number(node: object, where: str) -> float:
    # bool is an int subclass: `true` would otherwise read as 1.0.
    if isinstance(node, bool) or not isinstance(node, (int, float)) or not math.isfinite(node):
        raise PaperResultsError(f"key {where}: expected a number, got {node!r}")
    return float(node)


def _numbers(node: object, where: str, fields: Sequence[str]) -> dict[str, float]:
    record = _record(node, where, fields)
    return {f: _number(record[f], _key(where, f)) for f in fields}


def _flag(node: object, where: str) -> bool:
    if not isinstance(node, bool):
        raise PaperResultsError(f"key {where}: expected true or false, got {node!r}")
    return node


def _label(node: object, where: str) -> str:
    if not isinstance(node, str) or not node:
        raise PaperResultsError(f"key {where}: expected a row label, got {node!r}")
    return node


def _mse_parts(node: object, where: str) -> tuple[float, float, float, float]:
    if not isinstance(node, list) or len(node) != 4:
        raise PaperResultsError(f"key {where}: expected [average, base colour, roughness, metallic], got {node!r}")
    average, base, roughness, metallic = (_number(v, f"{where}[{k}]") for k, v in enumerate(node))
    return average, base, roughness, metallic


def _relight_rows(node: object, where: str) -> dict[str, dict[str, float]]:
    return {label: _numbers(row, _key(where, label), RELIGHT_FIELDS) for label, row in _mapping(node, where).items()}


def _table2(node: object, where: str = "table2"
            ) -> tuple[dict[str, str], dict[str, ParameterRow], str, dict[str, float]]:
    """Environments, rows, the correlated row and the correlation of the paper's Table 2."""
    top = _record(node, where, ("environments", "rows", "correlation"))
    at = _key(where, "environments")
    environments = {kind: _label(name, _key(at, kind)) for kind, name in _mapping(top["environments"], at).items()}
    columns = (*environments.values(), AVERAGE)
    rows = {}
    for label, row in _mapping(top["rows"], _key(where, "rows")).items():
        at = _key(_key(where, "rows"), label)
        record = _record(row, at, ("time_s", "mse"))
        mse = _record(record["mse"], _key(at, "mse"), columns)
        rows[label] = ParameterRow({c: _mse_parts(mse[c], _key(_key(at, "mse"), c)) for c in columns},
                                   _number(record["time_s"], _key(at, "time_s")))
    at = _key(where, "correlation")
    correlation = _record(top["correlation"], at, ("with", "values"))
    correlated = _label(correlation["with"], _key(at, "with"))
    if correlated not in rows:
        raise PaperResultsError(f"key {_key(at, 'with')}: {correlated!r} is not a row of {where}.rows {list(rows)}")
    return environments, rows, correlated, _numbers(correlation["values"], _key(at, "values"), columns)


def _table4(node: object, where: str = "table4") -> dict[str, AblationRow]:
    """The paper's Table 4, checking that each (shadowing, masking) pair has exactly one row."""
    rows = {}
    for label, row in _mapping(node, where).items():
        at = _key(where, label)
        record = _record(row, at, ("shadowing", "masking", *ABLATION_FIELDS))
        rows[label] = AblationRow(_flag(record["shadowing"], _key(at, "shadowing")),
                                  _flag(record["masking"], _key(at, "masking")),
                                  {f: _number(record[f], _key(at, f)) for f in ABLATION_FIELDS})
    pairs = sorted((r.shadowing, r.masking) for r in rows.values())
    if pairs != sorted(product((False, True), repeat=2)):
        raise PaperResultsError(f"key {where}: needs one row per (shadowing, masking) pair, got {pairs}")
    return rows


def parse_paper_results(data: object) -> PaperResults:
    """Check and type the paper's results as loaded from YAML.

    Raises
    ------
    PaperResultsError
        ``key <dotted.path>: <what is wrong>``.
    """
    top = _record(data, "", ("table1", "table2", "table3", "table4", "table5", "table6", "claims"))
    environments, table2, correlated, correlation = _table2(top["table2"])
    paper = PaperResults(
        table1=_relight_rows(top["table1"], "table1"), environments=environments, table2=table2,
        correlation_with=correlated, correlation=correlation,
        table3={label: _numbers(row, _key("table3", label), AGREEMENT_FIELDS)
                for label, row in _mapping(top["table3"], "table3").items()},
        table4=_table4(top["table4"]),
        table5=_relight_rows(top["table5"], "table5"),
        table6={label: _mse_parts(row, _key("table6", label)) for label, row in _mapping(top["table6"], "table6").items()},
        criteria=ClaimCriteria(**_numbers(top["claims"], "claims", CRITERIA_FIELDS)),
    )
    for table, labels in CLAIM_ROWS.items():
        missing = [label for label in labels if label not in getattr(paper, table)]
        if missing:
            raise PaperResultsError(f"key {table}.{missing[0]}: missing (the claims quote it)")
    return paper


def read_paper_results(path: str | PathLike[str]) -> PaperResults:
    """Read and check ``config/paper_results.yaml``.

    Raises
    ------
    PaperResultsError
        One line: ``<path>: key <dotted.path>: <what is wrong>``.
    """
    with open(path) as f:
        data = yaml.safe_load(f)
    try:
        return parse_paper_results(data)
    except PaperResultsError as error:
        raise PaperResultsError(f"{path}: {error}") from None


# ---------------------------------------------------------------------------
# Aggregation
# ---------------------------------------------------------------------------

TIDY_COLUMNS = ("object", "env", "poses", "method", "relight_env", "metric", "value")


def check_tidy(df: pd.DataFrame) -> pd.DataFrame:
    """Check the columns of a tidy metrics table and normalise ``relight_env``.

    Parameters
    ----------
    df : DataFrame
        Columns ``object, env, poses, method, relight_env, metric, value``.

    Returns
    -------
    DataFrame
        A copy with ``method`` and ``relight_env`` as strings ('' where empty) and ``value`` as float.

    Raises
    ------
    ValueError
        Naming the missing columns.
    """
    missing = [c for c in TIDY_COLUMNS if c not in df.columns]
    if missing:
        raise ValueError(f"metrics table lacks columns {missing} (has {list(df.columns)})")
    out = df.copy()
    # read_csv turns empty cells into NaN; compare them as ''. An empty method marks a
    # capture's own rows (the entropy agreement), an empty relight_env every row but relighting.
    for column in ("method", "relight_env"):
        out[column] = out[column].fillna("").astype(str)
    out["value"] = pd.to_numeric(out["value"], errors="coerce").astype(float)
    return out


def mean_metric(df: pd.DataFrame, method: str, metric: str, **where: str) -> float | None:
    """Mean of one metric of one method over all matching rows, or None if there are none.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (see :func:`check_tidy`).
    method, metric : str
    **where : str
        Further equality filters, e.g. ``env="studio"``.
    """
    rows = df[(df.method == method) & (df.metric == metric)]
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


# ---------------------------------------------------------------------------
# Formatting
# ---------------------------------------------------------------------------


def fmt(value: float | None, digits: int = 3, unit: str = "") -> str:
    """A number for display; ``-`` for None or NaN."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return MISSING
    return f"{value:.{digits}f}{unit}"


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


def _ours(df: pd.DataFrame, method: str | None, text: str) -> str:
    """A cell of our numbers: ``not run`` when the method has no row at all."""
    if method is None or not (df.method == method).any():
        return NOT_RUN
    return text


def _mse_cell(values: Sequence[float | None], digits: int) -> str:
    """``avg (base, roughness, metallic)`` as in the paper's Table 2."""
    avg, *parts = values
    if avg is None:
        return MISSING
    return f"{fmt(avg, digits)} ({', '.join(fmt(p, digits) for p in parts)})"


# ---------------------------------------------------------------------------
# Tables
# ---------------------------------------------------------------------------

_RELIGHT_METRICS = (("psnr_h", "PSNR-H", 2), ("psnr_l", "PSNR-L", 2), ("ssim", "SSIM", 3))
_MSE_METRICS = ("mse_average", "mse_base_color", "mse_roughness", "mse_metallic")
# Beside the MSE in Table 2, each a mean over captures: (metric, column, decimals)
_BRDF_METRICS = (("brdf_log_rmse", "BRDF log-RMSE", 3), ("base_color_si_psnr", "Base SI-PSNR", 2),
                 ("base_color_si_ssim", "Base SI-SSIM", 3))


def method_label(method: str) -> str:
    """The display name of a registered method; an unregistered one (an old run's) shows its name."""
    return METHODS[method].label if method in METHODS else method


def ordered_methods(methods: Iterable[str]) -> list[str]:
    """Distinct method names in the registry's order (that of tables and figures), then unregistered ones by name."""
    order = list(METHODS)
    return sorted(set(methods), key=lambda m: (order.index(m) if m in order else len(order), m))


def _relight_cells(df: pd.DataFrame, method: str | None, paper: Mapping[str, float] | None) -> dict[str, str]:
    """PSNR-H, PSNR-L and SSIM of a method (mean over captures, relighting
    environments and test views), each followed by the paper's value."""
    cells = {}
    for metric, label, digits in _RELIGHT_METRICS:
        ours = mean_metric(df, method, metric) if method else None
        cells[label] = _ours(df, method, fmt(ours, digits))
        cells[f"{label} (paper)"] = fmt(paper[metric], digits) if paper else MISSING
    return cells


def relighting_table(df: pd.DataFrame, paper: PaperResults) -> pd.DataFrame:
    """Paper Table 1: relighting under held-out environments, per method.

    Rows are the paper's (ours beside them where the registry has one, ``not
    run`` otherwise), then any other method of ours with relighting numbers.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (:func:`check_tidy`).
    paper : PaperResults

    Returns
    -------
    DataFrame of str
        ``Method, method, PSNR-H, PSNR-H (paper), PSNR-L, ..., Time, Time (paper)``, and the
        speed-up over Mitsuba at its fixed budget, at equal parameter MSE, and the paper's.
    """
    rows = []
    for label, values in paper.table1.items():
        method = paper_method("table1", label)
        row = {"Method": label, "method": method or MISSING, **_relight_cells(df, method, values)}
        row["Time"] = _ours(df, method, fmt_time(method_time(df, method)) if method else MISSING)
        row["Time (paper)"] = fmt_time(values["time_s"])
        row |= _speed_cells(df, method, paper.table1[MITSUBA]["time_s"] / values["time_s"])
        rows.append(row)
    listed = {paper_method("table1", label) for label in paper.table1}
    for method in ordered_methods(df[df.relight_env != ""].method):
        if method in listed:
            continue
        row = {"Method": method_label(method), "method": method, **_relight_cells(df, method, None)}
        row["Time"] = fmt_time(method_time(df, method))
        row["Time (paper)"] = MISSING
        row |= _speed_cells(df, method, None)
        rows.append(row)
    return pd.DataFrame(rows)


def _speed_cells(df: pd.DataFrame, method: str | None, paper_ratio: float | None) -> dict[str, str]:
    """How many times faster than Mitsuba: at its fixed budget, at equal parameter MSE
    (fewest over captures), and the paper's (Table 1 times)."""
    fixed = speed_ratio(df, method) if method and _ran(df, method, "mitsuba") and method != "mitsuba" else None
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
              env_kinds: Mapping[str, str], digits: int) -> list[dict[str, str]]:
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
        row["Avg."] = _ours(df, method, _mse_cell([mean_metric(df, method, p) for p in _MSE_METRICS], digits))
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
                    digits: int = 3) -> pd.DataFrame:
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
        Tidy metrics (:func:`check_tidy`).
    paper : PaperResults
    env_kinds : mapping, optional
        Our environment name -> kind (``studio``, ``museum``, ``sunny``,
        ``overcast``); by default an environment's name is its kind.
    digits : int
        Decimals of our numbers (the paper prints 2).

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
    rows = _mse_rows(df, paper, headers, env_kinds, digits) + _correlation_rows(df, paper, headers, env_kinds)
    columns = ["Method", "source", *headers.values(), "Avg.", *(label for _, label, _ in _BRDF_METRICS), "Time"]
    return pd.DataFrame(rows, columns=columns).fillna(MISSING)


def ablation_table(df: pd.DataFrame, paper: PaperResults, digits: int = 3) -> pd.DataFrame:
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
               "method": method, **_relight_cells(df, method, values.values)}
        row["MSE"] = _ours(df, method, fmt(mean_metric(df, method, "mse_average"), digits))
        row["MSE (paper)"] = fmt(values.values["mse"], 2)
        row["Time"] = _ours(df, method, fmt_time(method_time(df, method)))
        row["Time (paper)"] = fmt_time(values.values["time_s"])
        rows.append(row)
    return pd.DataFrame(rows)


def finetune_table(df: pd.DataFrame, paper: PaperResults, digits: int = 3) -> pd.DataFrame:
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
        row = {"Initialization": label, "method": method or MISSING, **_relight_cells(df, method, values)}
        row["MSE"] = _ours(df, method, fmt(mean_metric(df, method, "mse_average"), digits) if method else MISSING)
        row["Total time"] = _ours(df, method, fmt_time(method_time(df, method)) if method else MISSING)
        row["Total time (paper)"] = fmt_time(values["time_s"])
        rows.append(row)
    return pd.DataFrame(rows)


def merge_table(df: pd.DataFrame, paper: PaperResults, digits: int = 3) -> pd.DataFrame:
    """Paper Table 6: each entropy-merged method beside the mean of the estimates it merges.

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
            rows.append({"Method": label, "method": shown, "MSE": _mse_cell(parts, digits),
                         "MSE (paper)": _mse_cell(paper.table6[paper_row], 2) if paper_row else MISSING})
    return pd.DataFrame(rows, columns=["Method", "method", "MSE", "MSE (paper)"])


def _capture_metric(df: pd.DataFrame, metric: str) -> pd.Series:
    """Per-capture values of a metric of the captures themselves (rows with an empty method)."""
    return df[(df.method == "") & (df.metric == metric)].value.dropna()


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
            r, r_half = pd.Series([1.0]), _capture_metric(df, "entropy_agreement_pearson_mitsuba_reduced")
        else:
            r = _capture_metric(df, f"entropy_agreement_pearson_{name}")
            r_half = _capture_metric(df, f"entropy_agreement_pearson_{name}_reduced")
        seconds = _capture_metric(df, f"entropy_agreement_time_{name}_s")
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


# ---------------------------------------------------------------------------
# Claims
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Claim:
    """One headline claim of the paper, checked on our numbers."""

    claim: str
    paper: str
    ours: str
    holds: str  # "yes", "no" or "not run"
    criterion: str


def _verdict(ok: bool | None) -> str:
    return NOT_RUN if ok is None else ("yes" if ok else "no")


def _ran(df: pd.DataFrame, *methods: str) -> bool:
    return all((df.method == m).any() for m in methods)


def equal_accuracy_ratio(df: pd.DataFrame, method: str) -> tuple[float | None, bool]:
    """The smallest ``speed_ratio_equal_accuracy`` of a method over the captures, and whether
    it is exact (``mitsuba`` reached the method's MSE on every capture) or only a lower bound."""
    rows = df[(df.method == method) & (df.metric == "speed_ratio_equal_accuracy")].dropna(subset=["value"])
    if rows.empty:
        return None, False
    reached = df[(df.method == method) & (df.metric == "mitsuba_reached")].value
    return float(rows.value.min()), bool(len(reached) and (reached == 1.0).all())


def fmt_ratio(ratio: float | None, exact: bool = True) -> str:
    """A speed-up such as ``13.3x``; ``>= 13.3x`` for a lower bound."""
    return MISSING if ratio is None else f"{'' if exact else '>= '}{ratio:.1f}x"


def _mse(df: pd.DataFrame, method: str) -> float | None:
    return mean_metric(df, method, "mse_average")


def _psnr(df: pd.DataFrame, method: str) -> float | None:
    return mean_metric(df, method, "psnr_h")


def _speed_claim(df: pd.DataFrame, paper: PaperResults) -> Claim:
    mitsuba, ours = paper.table2[MITSUBA].time_s, paper.table2[OURS].time_s
    orb = paper.table1[MITSUBA]["time_s"] / paper.table1[OURS]["time_s"]
    ratio, exact = equal_accuracy_ratio(df, "freq") if _ran(df, "freq", "mitsuba") else (None, False)
    budget = speed_ratio(df, "freq") if _ran(df, "freq", "mitsuba") else None
    return Claim(
        "Ours (freq) fits much faster than Mitsuba",
        f"{mitsuba / ours:.1f}x ({fmt_paper(mitsuba, 2)} s vs {fmt_paper(ours, 2)} s, Table 2); "
        f"{orb:.1f}x on Stanford-ORB (Table 1)",
        MISSING if ratio is None else
        f"{fmt_ratio(ratio, exact)} at equal MSE (fewest over captures; {fmt_ratio(budget)} at Mitsuba's fixed budget)",
        _verdict(None if ratio is None else ratio >= orb),
        f"time for Mitsuba to reach freq's MSE / freq's time from the capture >= {orb:.1f} "
        "(the paper's lower figure) on every capture",
    )


def _speed_order_claim(df: pd.DataFrame, paper: PaperResults) -> Claim:
    times = [method_time(df, m) for m in ("spectrum", "freq", "mitsuba")]
    known = None not in times
    return Claim(
        "Spectrum-only is faster than ours, which is faster than Mitsuba",
        " < ".join(f"{fmt_paper(paper.table2[row].time_s, 2)} s" for row in (SPECTRUM, OURS, MITSUBA)) + " (Table 2)",
        " < ".join(fmt_time(t) for t in times) if known else MISSING,
        _verdict(times[0] < times[1] < times[2] if known else None),
        "time(spectrum) < time(freq) < time(mitsuba), mean per capture",
    )


def _average_mse(paper: PaperResults, row: str) -> str:
    return fmt_paper(paper.table2[row].mse[AVERAGE][0], 2)


def _versus_mitsuba(claim: str, paper_text: str, ours: float | None, mitsuba: float | None, quantity: str,
                    digits: int, ok: Callable[[float, float], bool], criterion: str) -> Claim:
    """A claim comparing freq's mean ``quantity`` with Mitsuba's."""
    known = ours is not None and mitsuba is not None
    return Claim(claim, paper_text, f"{quantity} {fmt(ours, digits)} vs {fmt(mitsuba, digits)}" if known else MISSING,
                 _verdict(ok(ours, mitsuba) if known else None), criterion)


def _accuracy_claim(df: pd.DataFrame, paper: PaperResults) -> Claim:
    tolerance = paper.criteria.accuracy_tolerance_mse
    return _versus_mitsuba(
        "Parameter accuracy comparable to Mitsuba",
        f"MSE {_average_mse(paper, OURS)} vs {_average_mse(paper, MITSUBA)} (Table 2)",
        _mse(df, "freq"), _mse(df, "mitsuba"), "MSE", 3, lambda ours, theirs: ours - theirs <= tolerance,
        f"MSE(freq) - MSE(mitsuba) <= {tolerance}",
    )


def _relight_claim(df: pd.DataFrame, paper: PaperResults) -> Claim:
    tolerance = paper.criteria.relight_tolerance_db
    claim = _versus_mitsuba(
        "Relighting on par with Mitsuba",
        f"PSNR-H {fmt_paper(paper.table1[OURS]['psnr_h'], 2)} vs {fmt_paper(paper.table1[MITSUBA]['psnr_h'], 2)} dB "
        "(Table 1)",
        _psnr(df, "freq"), _psnr(df, "mitsuba"), "PSNR-H", 2, lambda ours, theirs: ours >= theirs - tolerance,
        f"PSNR-H(freq) >= PSNR-H(mitsuba) - {tolerance} dB",
    )
    return dataclasses.replace(claim, ours=claim.ours + " dB" if claim.ours != MISSING else MISSING)


def _spectrum_claim(df: pd.DataFrame, paper: PaperResults) -> Claim:
    ours, spectrum = _mse(df, "freq"), _mse(df, "spectrum")
    known = spectrum is not None and ours is not None
    return Claim(
        "The full model is more accurate than the spectrum-only estimate",
        f"MSE {_average_mse(paper, OURS)} vs {_average_mse(paper, SPECTRUM)} (Table 2)",
        f"MSE {fmt(ours)} vs {fmt(spectrum)}" if known else MISSING,
        _verdict(ours < spectrum if known else None),
        "MSE(freq) < MSE(spectrum)",
    )


# The Table 4 rows by the words of the claim: (shadowing, masking).
_ABLATION_PAIRS = {"neither": (False, False), "shadowing": (True, False), "masking": (False, True),
                   "both": (True, True)}


def _ablation_claim(df: pd.DataFrame, paper: PaperResults) -> Claim:
    names = {word: ablation_method(*pair) for word, pair in _ABLATION_PAIRS.items()}
    mse = {word: _mse(df, name) for word, name in names.items()}
    known = None not in mse.values()
    if known:
        ordered = (mse["both"] < min(mse["shadowing"], mse["masking"])
                   and max(mse["shadowing"], mse["masking"]) < mse["neither"])
    words = ", ".join(f"{word} {fmt_paper(paper.ablation_row(*pair).values['mse'], 2)}"
                      for word, pair in _ABLATION_PAIRS.items())
    return Claim(
        "Shadowing and masking each improve on Ramamoorthi-Hanrahan; both together are best",
        f"MSE {words} (Table 4)",
        "MSE " + ", ".join(f"{word} {fmt(value)}" for word, value in mse.items()) if known else MISSING,
        _verdict(ordered if known else None),
        f"MSE({names['both']}) < MSE({names['shadowing']}), MSE({names['masking']}); "
        f"MSE({names['shadowing']}), MSE({names['masking']}) < MSE({names['neither']})",
    )


def _finetune_claim(df: pd.DataFrame, paper: PaperResults) -> Claim:
    tuned, ours = _mse(df, "freq+mitsuba"), _mse(df, "freq")
    known = tuned is not None and ours is not None
    extra = ""
    if _psnr(df, "freq+mitsuba") is not None and _psnr(df, "freq") is not None:
        extra = f"; PSNR-H {fmt(_psnr(df, 'freq+mitsuba'), 2)} vs {fmt(_psnr(df, 'freq'), 2)} dB"
    return Claim(
        "Fine-tuning our result with Mitsuba improves on ours",
        f"PSNR-H {fmt_paper(paper.table5[FINETUNED]['psnr_h'], 2)} vs {fmt_paper(paper.table1[OURS]['psnr_h'], 2)} dB "
        "(Tables 1, 5)",
        f"MSE {fmt(tuned)} vs {fmt(ours)}{extra}" if known else MISSING,
        _verdict(tuned < ours if known else None),
        "MSE(freq+mitsuba) < MSE(freq)",
    )


def _finetune_time_claim(df: pd.DataFrame, paper: PaperResults) -> Claim:
    psnr = {m: _psnr(df, m) for m in ("freq+mitsuba", "mitsuba")}
    time = {m: method_time(df, m) for m in ("freq+mitsuba", "mitsuba")}
    known = None not in (*psnr.values(), *time.values())
    tuned, full = paper.table5[FINETUNED], paper.table5[MITSUBA_FULL]
    divisor = paper.criteria.finetune_time_divisor
    return Claim(
        "Ours + Mitsuba beats Mitsuba alone in less than a third of its time",
        f"PSNR-H {fmt_paper(tuned['psnr_h'] - full['psnr_h'], 2, sign=True)} dB, "
        f"{fmt_paper(tuned['time_s'], 2)} s vs {fmt_paper(full['time_s'], 2)} s (Table 5)",
        (f"PSNR-H {psnr['freq+mitsuba'] - psnr['mitsuba']:+.2f} dB, "
         f"{fmt_time(time['freq+mitsuba'])} vs {fmt_time(time['mitsuba'])}") if known else MISSING,
        _verdict(psnr["freq+mitsuba"] > psnr["mitsuba"]
                 and time["freq+mitsuba"] < time["mitsuba"] / divisor if known else None),
        f"PSNR-H(freq+mitsuba) > PSNR-H(mitsuba) and time(freq+mitsuba) < time(mitsuba) / {divisor:g}",
    )


def _entropy_claim(df: pd.DataFrame, paper: PaperResults) -> Claim:
    r_mitsuba = mean_metric(df, "mitsuba", "pearson_entropy_error")
    r_freq = mean_metric(df, "freq", "pearson_entropy_error")
    ours = [f"{label} {fmt(r, 2)}" for label, r in (("Mitsuba", r_mitsuba), ("freq", r_freq)) if r is not None]
    per_env = [r for env, r in paper.correlation.items() if env != AVERAGE]
    return Claim(
        "Our entropy correlates positively with Mitsuba's per-texel error",
        f"Pearson {fmt_paper(min(per_env), 2)} to {fmt_paper(max(per_env), 2)}, "
        f"mean {fmt_paper(paper.correlation[AVERAGE], 2)} (Table 2)",
        "; ".join(ours) if ours else MISSING,
        _verdict(None if r_mitsuba is None else r_mitsuba > 0.0),
        "mean Pearson(entropy, Mitsuba's squared parameter error) > 0",
    )


def _merge_claim(df: pd.DataFrame, paper: PaperResults) -> Claim:
    merged = next((m for m, e in METHODS.items() if "table6" in e.paper_rows), None)
    start = METHODS[merged].start if merged else None
    ours, average = (_mse(df, merged), _mse(df, start)) if merged and _ran(df, merged, start) else (None, None)
    known = ours is not None and average is not None
    label = paper.table6.get(METHODS[merged].paper_rows["table6"]) if merged else None
    return Claim(
        "Merging captures by entropy beats their average",
        f"MSE {fmt_paper(label[0], 2)} vs {fmt_paper(paper.table6[MERGE_AVERAGE][0], 2)} (Table 6)" if label
        else MISSING,
        f"MSE {fmt(ours)} vs {fmt(average)} ({merged} vs {start})" if known else MISSING,
        _verdict(ours < average if known else None),
        f"MSE({merged}) < MSE({start}), both means over the captures",
    )


def _agreement_claim(df: pd.DataFrame, paper: PaperResults) -> Claim:
    row = paper.table3[AGREEMENT_ROWS["spectrum"]]
    threshold = row["pearson"] - row["std"]
    r = _capture_metric(df, "entropy_agreement_pearson_spectrum")
    angular = _capture_metric(df, "entropy_agreement_pearson_angular")
    known = len(r) > 0
    return Claim(
        "The power-spectrum entropy agrees with the entropy Mitsuba's renders give",
        f"Pearson {fmt_paper(row['pearson'], 2)} \u00b1 {fmt_paper(row['std'], 2)} "
        f"(angular {fmt_paper(paper.table3[AGREEMENT_ROWS['angular']]['pearson'], 2)}, Table 3)",
        f"Pearson {fmt(r.mean(), 2)} (angular {fmt(angular.mean() if len(angular) else None, 2)}) "
        f"over {len(r)} capture(s)" if known else MISSING,
        _verdict(bool(r.mean() >= threshold) if known else None),
        f"mean Pearson(spectrum entropy, Mitsuba grid entropy) >= {threshold:.2f} "
        "(the paper's mean minus its standard deviation)",
    )


def views_sweep(df: pd.DataFrame) -> pd.DataFrame:
    """The views sweep's rows as a table: ``object, env, views, mse_average, mean_entropy``."""
    rows = df[df.metric.str.fullmatch(r"views_\d+_(mse_average|mean_entropy)")]
    if rows.empty:
        return pd.DataFrame(columns=["object", "env", "views", "mse_average", "mean_entropy"])
    parts = rows.metric.str.extract(r"views_(\d+)_(\w+)")
    wide = rows.assign(views=parts[0].astype(int), quantity=parts[1]).pivot_table(
        index=["object", "env", "views"], columns="quantity", values="value").reset_index()
    return wide.sort_values(["object", "env", "views"])


def _views_claim(df: pd.DataFrame, paper: PaperResults) -> Claim:
    sweep = views_sweep(df)
    if len(sweep):  # the first capture swept (the pipeline sweeps one)
        sweep = sweep[(sweep.object == sweep.object.iloc[0]) & (sweep.env == sweep.env.iloc[0])]
    known = len(sweep) >= 2
    fewest, most = (sweep.iloc[0], sweep.iloc[-1]) if known else (None, None)
    r = float(sweep.mse_average.corr(sweep.mean_entropy)) if len(sweep) >= 3 else float("nan")
    return Claim(
        "With fewer views, error and entropy rise together",
        "MSE and mean entropy both rise as views are dropped (Fig. 8)",
        (f"{int(fewest.views)} views: MSE {fmt(fewest.mse_average)}, entropy {fmt(fewest.mean_entropy, 2)}; "
         f"{int(most.views)}: {fmt(most.mse_average)}, {fmt(most.mean_entropy, 2)}; Pearson {fmt(r, 2)}")
        if known else MISSING,
        _verdict(bool(fewest.mse_average > most.mse_average and fewest.mean_entropy > most.mean_entropy
                      and not r < 0) if known else None),
        "fewest views: MSE and mean entropy above those of the most views, and their Pearson correlation "
        "over the counts not negative (freq, first capture)",
    )


_CLAIMS: tuple[Callable[[pd.DataFrame, PaperResults], Claim], ...] = (
    _speed_claim, _speed_order_claim, _accuracy_claim, _relight_claim, _spectrum_claim,
    _ablation_claim, _finetune_claim, _finetune_time_claim, _entropy_claim, _agreement_claim, _merge_claim, _views_claim,
)


def claims(df: pd.DataFrame, paper: PaperResults) -> pd.DataFrame:
    """The paper's headline claims, its values, ours, and whether each holds here.

    Criteria (each a mean over the captures in ``df``; tolerances from ``paper.criteria``):

    1. Speed: freq reaches its MSE at least 13x (the paper's lower figure, Table 1) sooner than Mitsuba does, on every capture.
    2. Speed order: time(spectrum) < time(freq) < time(mitsuba).
    3. Accuracy: MSE(freq) - MSE(mitsuba) <= accuracy_tolerance_mse.
    4. Relighting: PSNR-H(freq) >= PSNR-H(mitsuba) - relight_tolerance_db.
    5. Spectrum-only is less accurate than the full model: MSE(spectrum) > MSE(freq).
    6. Ablation order (the Table 4 methods, :func:`freqbrdf.methods.ablation_method`):
       MSE(both) < min(MSE(shadowing only), MSE(masking only)) and
       max(MSE(shadowing only), MSE(masking only)) < MSE(neither).
    7. Fine-tuning improves ours: MSE(freq+mitsuba) < MSE(freq).
    8. Fine-tuning beats Mitsuba alone, in less than a third of its time:
       PSNR-H(freq+mitsuba) > PSNR-H(mitsuba) and
       time(freq+mitsuba) < time(mitsuba) / finetune_time_divisor.
    9. Entropy predicts Mitsuba's error: mean Pearson(entropy, squared error) > 0.
    10. Entropy agreement (Table 3): mean Pearson(spectrum entropy, Mitsuba grid entropy) >= the
        paper's 0.89 minus its standard deviation 0.06.
    11. Merging by entropy beats the average (Table 6); 12. fewer views raise MSE and entropy (Fig. 8).

    A claim whose methods did not run (or lack the metric) is ``not run``.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (:func:`check_tidy`).
    paper : PaperResults
        The paper's numbers, quoted in the ``paper`` column.

    Returns
    -------
    DataFrame of str
        Columns ``claim, paper, ours, holds, criterion``.
    """
    rows = [asdict(claim(df, paper)) for claim in _CLAIMS]
    return pd.DataFrame(rows, columns=["claim", "paper", "ours", "holds", "criterion"])


# ---------------------------------------------------------------------------
# Rendering
# ---------------------------------------------------------------------------


def _is_numeric(cell: str) -> bool:
    """Whether a display cell is a number (possibly with a unit or a bracketed breakdown)."""
    head = cell.split(" ")[0].rstrip("x")
    try:
        float(head)
    except ValueError:
        return False
    return True


def _right_aligned(table: pd.DataFrame) -> list[bool]:
    """Right-align columns whose filled cells are all numbers."""
    out = []
    for column in table.columns:
        cells = [str(c) for c in table[column] if str(c) not in (MISSING, NOT_RUN, "")]
        out.append(bool(cells) and all(_is_numeric(c) for c in cells))
    return out


def to_markdown(table: pd.DataFrame, title: str | None = None, caption: str | None = None) -> str:
    """A GitHub-flavoured Markdown pipe table, with a level-3 heading ``title`` and a caption paragraph.

    Cells are converted with ``str``; ``|`` is escaped.
    """

    def line(cells: Iterable[object]) -> str:
        return "| " + " | ".join(str(c).replace("|", r"\|").replace("\n", " ") for c in cells) + " |"

    rule = "|" + "|".join("---:" if right else "---" for right in _right_aligned(table)) + "|"
    lines = [f"### {title}", ""] if title else []
    lines += [line(table.columns), rule, *(line(row) for row in table.itertuples(index=False))]
    if caption:
        lines += ["", caption]
    return "\n".join(lines) + "\n"


_LATEX_SPECIAL = {
    "\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
    "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
    # In text mode with the default OT1 font encoding, < and > print as inverted ! and ?.
    "<": r"\textless{}", ">": r"\textgreater{}",
}


def latex_escape(text: str) -> str:
    """Escape LaTeX's special characters in plain text."""
    return "".join(_LATEX_SPECIAL.get(ch, ch) for ch in str(text))


def _styler(table: pd.DataFrame, escape: Callable[[str], str]) -> Styler:
    """A Styler of the display strings, cells and headers escaped by ``escape``, without the index."""
    # Our own escapes rather than Styler's escape="latex"/"html": pandas' LaTeX
    # one leaves < and > as they are (see _LATEX_SPECIAL).
    return (Styler(table, cell_ids=False)
            .hide(axis="index")
            .format(lambda value: escape(str(value)))
            .format_index(lambda value: escape(str(value)), axis=1))


def to_latex(table: pd.DataFrame, caption: str | None = None, label: str | None = None) -> str:
    """A LaTeX ``table`` with a booktabs ``tabular`` (needs ``\\usepackage{booktabs}``).

    Parameters
    ----------
    table : DataFrame
        Cells are converted with ``str`` and escaped.
    caption, label : str, optional
        ``\\caption`` (escaped) and ``\\label`` of the float.
    """
    spec = "".join("r" if right else "l" for right in _right_aligned(table))
    # Styler writes table styles it does not know as commands: this one is \small.
    styler = _styler(table, latex_escape).set_table_styles([{"selector": "small", "props": ":;"}])
    return styler.to_latex(column_format=spec, position="ht", position_float="centering", hrules=True,
                           label=label, caption=latex_escape(caption) if caption else None, environment="table")


def _cell_classes(table: pd.DataFrame, verdicts: str | None) -> pd.DataFrame:
    """CSS classes of each cell: ``notrun``, the verdict (``yes``/``no``) in column ``verdicts``, ``num``."""
    right = dict(zip(table.columns, _right_aligned(table)))

    def classes(column: str, text: str) -> str:
        verdict = text if column == verdicts and text in ("yes", "no") else ""
        return " ".join(c for c in ("notrun" if text == NOT_RUN else "", verdict, "num" if right[column] else "") if c)

    return pd.DataFrame({c: [classes(c, str(v)) for v in table[c]] for c in table.columns}, index=table.index)


# Styler writes a <style> element before its table even with no styles (ours
# are classes, styled by the page's head); <style> in <body> is not valid HTML.
_EMPTY_STYLE = re.compile(r'<style type="text/css">\s*</style>\s*')


def to_html(table: pd.DataFrame, title: str | None = None, caption: str | None = None,
            verdicts: str | None = None) -> str:
    """An HTML fragment: heading, ``<table>`` and caption paragraph (styled by :data:`HTML_STYLE`).

    Parameters
    ----------
    table : DataFrame
        Cells are converted with ``str`` and escaped; numeric columns get the class ``num``.
    title, caption : str, optional
        ``<h2>`` above and a paragraph below the table.
    verdicts : str, optional
        A column of ``yes`` / ``no`` / ``not run`` (the claims' ``holds``) whose
        cells get the classes ``yes``, ``no`` and ``notrun``, for colour.
        ``not run`` cells elsewhere get ``notrun`` too (greyed).
    """
    table = table.reset_index(drop=True)  # set_td_classes aligns on a unique index
    styler = _styler(table, html.escape).set_td_classes(_cell_classes(table, verdicts))
    # Element ids must differ between the tables of a page and stay put from run to run.
    content = f"{title}\n{table.to_csv()}"
    uuid = f"{zlib.crc32(content.encode()):08x}"
    parts = [f"<h2>{html.escape(title)}</h2>"] if title else []
    # A table wider than the report's frame scrolls inside its box instead of being cut off.
    parts.append(f'<div class="scroll">{_EMPTY_STYLE.sub("", styler.to_html(table_uuid=uuid)).strip()}</div>')
    if caption:
        parts.append(f'<p class="caption">{html.escape(caption)}</p>')
    return "\n".join(parts) + "\n"


HTML_STYLE = """
body { font-family: sans-serif; font-size: 13px; margin: 1.2em; color: #222; }
h1 { font-size: 20px; } h2 { font-size: 16px; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.4em 0; }
th, td { border: 1px solid #ccc; padding: 3px 7px; }
th { min-width: 4em; } td.num, td.notrun { white-space: nowrap; }
div.scroll { overflow-x: auto; max-width: 100%; }
th { background: #eef; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
td.yes { background: #d8f5d0; } td.no { background: #f8d0d0; } td.notrun { color: #888; }
p.caption { max-width: 60em; color: #444; }
"""


def html_page(title: str, body: str) -> str:
    """A self-contained HTML page (inline style, no external resources)."""
    return (f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{html.escape(title)}</title>"
            f"<style>{HTML_STYLE}</style></head>\n<body>\n<h1>{html.escape(title)}</h1>\n{body}</body></html>\n")


def run_facts(run: Mapping[str, object]) -> dict[str, str]:
    """What a run did, as the report's summary states it: one line per aspect.

    Parameters
    ----------
    run : mapping
        From the run's configuration: ``seed``, ``objects``, ``real_captures``
        (names), ``capture_envs``, ``envs``, ``relight_envs`` (config
        ``evaluate.relight_envs``), ``render`` (``train_views``, ``test_views``,
        ``resolution``, ``spp``), ``poses`` (config ``poses.source``) and ``methods``.

    Returns
    -------
    dict of str to str
        Aspect -> text, in reading order.
    """
    render, relight = run["render"], run["relight_envs"]
    if relight == "held_out":
        relit = "every environment a capture was not taken under (held out)"
    else:
        relit = "every environment" if relight == "all" else ", ".join(relight)
    return {
        "Objects": f"{', '.join(run['objects']) or 'none'} (synthetic, seeded ground truth)",
        "Real captures": ", ".join(run["real_captures"]) or "none",
        "Captured under": ", ".join(run["capture_envs"]),
        "Relit under": f"{relit}, of {', '.join(run['envs'])}",
        "Views": (f"{render['train_views']} training and {render['test_views']} test views per capture, "
                  f"{render['resolution']} x {render['resolution']} pixels at {render['spp']} samples per pixel"),
        "Poses": str(run["poses"]),
        "Methods": ", ".join(f"{method_label(m)} ({m})" for m in run["methods"]),
        "Seed": str(run["seed"]),
    }


def headline_table(df: pd.DataFrame) -> pd.DataFrame:
    """The run's headline numbers: one row per method (registry order), means over the captures.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (:func:`check_tidy`).

    Returns
    -------
    DataFrame of str
        ``Method, method, Parameter MSE, PSNR-H, Time``: average parameter MSE
        (observed texels), PSNR-H (dB, held-out relighting) and time per capture.
    """
    rows = [{"Method": method_label(m), "method": m, "Parameter MSE": fmt(mean_metric(df, m, "mse_average")),
             "PSNR-H": fmt(mean_metric(df, m, "psnr_h"), 2), "Time": fmt_time(method_time(df, m))}
            for m in ordered_methods(df.method)]
    return pd.DataFrame(rows, columns=["Method", "method", "Parameter MSE", "PSNR-H", "Time"])


def scoped_style(style: str, scope: str) -> str:
    """CSS rules with every selector prefixed by ``scope``; rules for ``body`` dropped."""
    rules = re.findall(r"([^{}]+)\{([^}]*)\}", style)
    return "\n".join(", ".join(f"{scope} {sel.strip()}" for sel in selectors.split(",")) + f" {{{body}}}"
                     for selectors, body in rules if selectors.strip() != "body")


# The summary sits in the report's own page: its style is scoped to its box.
RUN_SUMMARY_STYLE = scoped_style(HTML_STYLE, "div.freqbrdf-summary")


def run_summary_html(facts: Mapping[str, str], claims_table: pd.DataFrame, headline: pd.DataFrame) -> str:
    """The report's landing summary as an HTML fragment: what was run, the paper's claims
    with their verdicts, and the headline numbers.

    Parameters
    ----------
    facts : mapping of str to str
        From :func:`run_facts`.
    claims_table : DataFrame
        From :func:`claims` (its ``criterion`` column is left to the claims page).
    headline : DataFrame
        From :func:`headline_table`.
    """
    counts = claims_table.holds.value_counts()
    tally = ", ".join(f"{counts.get(v, 0)} {text}" for v, text in (("yes", "hold"), ("no", "do not hold"),
                                                                   (NOT_RUN, "not run")))
    lines = "".join(f"<li><b>{html.escape(k)}:</b> {html.escape(v)}</li>" for k, v in facts.items())
    return (f'<div class="freqbrdf-summary"><style>{RUN_SUMMARY_STYLE}</style>\n'
            f"<h2>This run</h2>\n<ul>{lines}</ul>\n"
            + to_html(claims_table[["claim", "holds", "ours", "paper"]], "The paper's claims on this run",
                      f"{len(claims_table)} claims: {tally}. Criteria and the paper's sources: Tables, claims.",
                      verdicts="holds")
            + to_html(headline, "Headline numbers",
                      "Means over this run's captures: parameter MSE over observed texels, PSNR-H of relighting "
                      "under held-out environments, time per capture on 2 CPU cores. Every number: "
                      "Tables, metrics.csv.")
            + "</div>\n")


@dataclass(frozen=True)
class Summary:
    """One summary table with its file stem, title and caption."""

    key: str
    title: str
    caption: str
    table: pd.DataFrame


SUMMARY_KEYS = ("table1_relighting", "table2_parameters", "table3_agreement", "table4_ablation", "table5_finetune",
                "table6_merge", "claims")
"""Keys of `summaries`, in its order: the stems of rule tables' output files."""


def summaries(df: pd.DataFrame, paper: PaperResults, env_kinds: Mapping[str, str] | None = None) -> list[Summary]:
    """Every summary table of the report, in the paper's order, then the claims.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (:func:`check_tidy`), one pose source.
    paper : PaperResults
        The paper's numbers (:func:`read_paper_results`).
    env_kinds : mapping, optional
        Our environment name -> kind, to place the paper's environments (:func:`parameter_table`).

    Returns
    -------
    list of Summary
        Keyed by :data:`SUMMARY_KEYS` (the output file stems).
    """
    n_captures = len(df[["object", "env"]].drop_duplicates())
    n_truth = len(df[df.metric == "mse_average"][["object", "env"]].drop_duplicates())
    scope = (f"Ours: means over this run's {n_captures} capture(s), {n_truth} with ground truth "
             "(parameter MSE, relighting); times on 2 CPU cores. "
             "Paper: Wiersma et al. 2024 (arXiv 2406.17774), on an RTX 4090.")
    return [
        Summary("table1_relighting", "Table 1: relighting under held-out environments",
                "PSNR-H (linear HDR), PSNR-L (tone-mapped) and SSIM of renders of the recovered textures "
                "against ground-truth renders under environments not seen in training, mean over test views. "
                "The paper's numbers are on Stanford-ORB photographs; ours on the synthetic benchmark. "
                "LPIPS is not computed (no network weights offline). " + scope,
                relighting_table(df, paper)),
        Summary("table2_parameters", "Table 2: parameter MSE per capture environment",
                "Average (base colour, roughness, metallic) MSE against the ground-truth textures over "
                "observed texels; 'paper' rows give the paper's value for the environment of the same kind. "
                "BRDF log-RMSE: RMS difference of log(1 + f cos theta_i) between the estimated and true "
                "BRDF over a fixed set of direction pairs, on the same texels; Base SI-PSNR/SSIM: the base colour "
                "after a per-channel least-squares scale (Stanford-ORB), sRGB; both means over captures. "
                "Error-entropy correlation: Pearson correlation between our entropy and the method's "
                "per-texel squared error (the paper correlates with Mitsuba's). " + scope,
                parameter_table(df, paper, env_kinds)),
        Summary("table3_agreement", "Table 3: entropy agreement",
                "Pearson correlation, over a seeded sample of each capture's observed texels, of each entropy "
                "with the entropy of a grid of uniform materials (roughness x metallic x base colour) path traced "
                "by Mitsuba at the training views; mean \u00b1 standard deviation over the captures. 'Half the "
                "paths': against the Mitsuba grid from one of its two sample sets. Times are for the sampled "
                "texels (ours) and for whole captures on a GPU (paper). " + scope,
                agreement_table(df, paper)),
        Summary("table4_ablation", "Table 4: ablation of shadowing and masking",
                "Our model with and without the shadowing G1(theta_i) and masking G1(theta_o) terms; "
                "rh2001 has neither (Ramamoorthi and Hanrahan 2001). The paper's relighting numbers are on "
                "Stanford-ORB and its MSE and time on its synthetic set, both without cosine weighting of "
                "the samples; ours use cosine weighting. " + scope,
                ablation_table(df, paper)),
        Summary("table5_finetune", "Table 5: fine-tuning with Mitsuba",
                "A short Mitsuba optimisation started from our textures (freq+mitsuba) against Mitsuba's "
                "full optimisation from a constant (mitsuba) and our textures alone (freq). Total time "
                "includes the initialisation. Rows without a method of ours are not in this pipeline. " + scope,
                finetune_table(df, paper)),
        Summary("table6_merge", "Table 6: captures merged by entropy",
                "One texture set per object from all its captures: each texel takes the parameters of the "
                "capture whose spectrum entropy is lowest there, against the mean of the separate captures' "
                "estimates; parameter MSE as in Table 2. The paper merged Mitsuba's results. " + scope,
                merge_table(df, paper)),
        Summary("claims", "Claims of the paper, checked on this run",
                "holds: 'yes' or 'no' by the stated criterion on this run's means; 'not run' when a method "
                "it needs is not in the configuration's methods or produced no such metric. " + scope,
                claims(df, paper)),
    ]
