"""Summary tables and the claims table, from the tidy metrics table, beside the paper's numbers.

Input everywhere is the tidy table ``results/tables/metrics.csv``: one row per
number, columns ``object, env, poses, method, relight_env, metric, value``
(``relight_env`` empty for rows that are not about relighting). Metric names:

- ``mse_base_color``, ``mse_roughness``, ``mse_metallic``, ``mse_average``:
  parameter MSE over observed texels (synthetic captures only);
- ``psnr_h``, ``psnr_l``, ``ssim``, ``mse`` with ``relight_env`` set: relighting
  under a held-out environment, mean over the test views;
- ``pearson_entropy_error``: per capture, correlation of our entropy with that
  method's per-texel squared parameter error;
- ``time_s``, ``max_rss_mb``, ``time_total_s``, ``speed_ratio_vs_mitsuba``.

Every summary is a mean over the rows given (objects, capture environments,
relighting environments); callers select one pose source first. A method that
has no row at all is shown as ``not run``; a method that ran but lacks a
metric as ``-``. The tables are DataFrames of display strings, rendered by
:func:`to_markdown`, :func:`to_latex` and :func:`to_html` (no dependency on
``tabulate``).
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass

import pandas as pd

NOT_RUN = "not run"
MISSING = "-"

# ---------------------------------------------------------------------------
# The paper's numbers: Wiersma et al. 2024, "Fast and Uncertainty-Aware SVBRDF
# Recovery from Multi-View Capture using Frequency Domain Analysis",
# arXiv 2406.17774. Timings are theirs (RTX 4090 + Ryzen 9 7950X); ours run on
# 2 CPU cores, so only ratios of times are comparable.
# ---------------------------------------------------------------------------

# Table 1: novel-scene relighting on Stanford-ORB (PSNR-H on linear HDR, PSNR-L
# on tone-mapped LDR, SSIM, LPIPS, optimisation time). Keys are the paper's row
# labels; PAPER_TABLE1_METHODS maps them to our methods (None: not in this pipeline).
PAPER_TABLE1: dict[str, dict[str, float]] = {
    "NVDiffRec": {"psnr_h": 24.319, "psnr_l": 31.492, "ssim": 0.969, "lpips": 0.036, "time_s": 142.143},
    "Mitsuba": {"psnr_h": 26.595, "psnr_l": 34.185, "ssim": 0.977, "lpips": 0.032, "time_s": 69.96},
    "Ours": {"psnr_h": 26.677, "psnr_l": 33.936, "ssim": 0.977, "lpips": 0.029, "time_s": 5.27},
    "Ours-Spectrum Only": {"psnr_h": 24.478, "psnr_l": 31.117, "ssim": 0.971, "lpips": 0.037, "time_s": 1.96},
    "Ours+Mitsuba (1 epoch)": {"psnr_h": 27.038, "psnr_l": 34.560, "ssim": 0.978, "lpips": 0.030, "time_s": 19.87},
    "Ours+Mitsuba (2 epochs)": {"psnr_h": 27.199, "psnr_l": 34.770, "ssim": 0.978, "lpips": 0.029, "time_s": 33.39},
}
PAPER_TABLE1_METHODS: dict[str, str | None] = {
    "NVDiffRec": None,
    "Mitsuba": "mitsuba",
    "Ours": "freq",
    "Ours-Spectrum Only": "spectrum",
    "Ours+Mitsuba (1 epoch)": "freq+mitsuba",
    "Ours+Mitsuba (2 epochs)": None,
}

# Table 2: synthetic benchmark, parameter MSE "Average (BaseColor, Roughness,
# Metallicity)" per environment, and the error-entropy correlation (our entropy
# vs Mitsuba's per-texel squared error). Environments are keyed by the kind of
# our nearest analogue: Photo Studio -> studio, Overcast -> overcast,
# Museum -> museum, Rural Road (outdoor, sun) -> sunny.
PAPER_ENV_NAMES: dict[str, str] = {
    "studio": "Photo Studio", "overcast": "Overcast", "museum": "Museum", "sunny": "Rural Road",
}
PAPER_TABLE2_MSE: dict[str, dict[str, tuple[float, float, float, float]]] = {
    "mitsuba": {
        "studio": (0.04, 0.01, 0.03, 0.07), "overcast": (0.03, 0.01, 0.02, 0.06),
        "museum": (0.04, 0.01, 0.04, 0.08), "sunny": (0.04, 0.01, 0.03, 0.07),
        "avg": (0.04, 0.01, 0.03, 0.07),
    },
    "freq": {
        "studio": (0.07, 0.02, 0.09, 0.10), "overcast": (0.06, 0.02, 0.07, 0.09),
        "museum": (0.07, 0.02, 0.08, 0.11), "sunny": (0.05, 0.01, 0.05, 0.08),
        "avg": (0.06, 0.02, 0.07, 0.09),
    },
    "spectrum": {
        "studio": (0.19, 0.07, 0.15, 0.37), "overcast": (0.20, 0.06, 0.14, 0.40),
        "museum": (0.25, 0.09, 0.20, 0.46), "sunny": (0.22, 0.06, 0.16, 0.43),
        "avg": (0.21, 0.07, 0.16, 0.41),
    },
}
PAPER_TABLE2_TIME_S: dict[str, float] = {"mitsuba": 105.19, "freq": 3.14, "spectrum": 1.20}
PAPER_TABLE2_CORRELATION: dict[str, float] = {
    "studio": 0.21, "overcast": 0.13, "museum": 0.18, "sunny": 0.14, "avg": 0.16,
}

# Table 4: BRDF-model ablation, without cosine weighting of the samples.
# Keys (shadowing, masking); Stanford-ORB relighting and synthetic MSE / time.
PAPER_TABLE4: dict[tuple[bool, bool], dict[str, float]] = {
    (False, False): {"psnr_h": 25.646, "psnr_l": 32.809, "ssim": 0.973, "lpips": 0.035, "time_orb_s": 1.09,
                     "mse": 0.16, "time_s": 2.57},
    (True, False): {"psnr_h": 26.245, "psnr_l": 33.399, "ssim": 0.975, "lpips": 0.034, "time_orb_s": 1.21,
                    "mse": 0.14, "time_s": 2.81},
    (False, True): {"psnr_h": 26.070, "psnr_l": 33.101, "ssim": 0.974, "lpips": 0.035, "time_orb_s": 1.19,
                    "mse": 0.13, "time_s": 2.89},
    (True, True): {"psnr_h": 26.411, "psnr_l": 33.557, "ssim": 0.975, "lpips": 0.034, "time_orb_s": 1.31,
                   "mse": 0.12, "time_s": 3.14},
}
# Our method for each (shadowing, masking) pair (README: gradient-descent estimator).
ABLATION_METHODS: dict[tuple[bool, bool], str] = {
    (False, False): "rh2001", (True, False): "freq_nomask", (False, True): "freq_noshadow", (True, True): "freq",
}

# Table 5: fine-tuning with Mitsuba from different initialisations (Stanford-ORB):
# 1 epoch at 16 spp for the first three rows, 2 epochs at 32 spp for the fourth;
# the last row is Mitsuba's full optimisation from a constant. The extra row
# "Ours, no fine-tuning" is Table 1's "Ours", for reference.
PAPER_TABLE5: dict[str, dict[str, float]] = {
    "Constant": {"psnr_h": 24.339, "psnr_l": 30.558, "ssim": 0.969, "lpips": 0.047, "time_s": 14.74},
    "Ours-Spectrum Only": {"psnr_h": 25.745, "psnr_l": 33.158, "ssim": 0.975, "lpips": 0.033, "time_s": 16.29},
    "Ours": {"psnr_h": 27.038, "psnr_l": 34.560, "ssim": 0.978, "lpips": 0.030, "time_s": 19.87},
    "Ours (2 epochs)": {"psnr_h": 27.199, "psnr_l": 34.770, "ssim": 0.978, "lpips": 0.029, "time_s": 33.39},
    "Full optimization - Constant": {"psnr_h": 26.595, "psnr_l": 34.185, "ssim": 0.977, "lpips": 0.032,
                                     "time_s": 69.96},
    "Ours, no fine-tuning (Table 1)": {"psnr_h": 26.677, "psnr_l": 33.936, "ssim": 0.977, "lpips": 0.029,
                                       "time_s": 5.27},
}
PAPER_TABLE5_METHODS: dict[str, str | None] = {
    "Constant": None,
    "Ours-Spectrum Only": None,
    "Ours": "freq+mitsuba",
    "Ours (2 epochs)": None,
    "Full optimization - Constant": "mitsuba",
    "Ours, no fine-tuning (Table 1)": "freq",
}

# Display names of our methods.
METHOD_LABELS: dict[str, str] = {
    "mitsuba": "Mitsuba", "freq": "Ours", "spectrum": "Ours-Spectrum Only", "freq+mitsuba": "Ours+Mitsuba",
    "freq_paper": "Ours, paper's band limit", "freq_noshadow": "Ours, no shadowing", "freq_nomask": "Ours, no masking", "rh2001": "RH2001 (neither)",
}

# ---------------------------------------------------------------------------
# Criteria of the claims table (see claims()).
# ---------------------------------------------------------------------------
# "Comparable accuracy to Mitsuba": the paper's gap in average parameter MSE is
# 0.02 (0.06 vs 0.04); we accept up to 1.5 times that.
ACCURACY_TOLERANCE_MSE = 0.03
# "Relighting on par with Mitsuba": the paper's methods lie within 0.1 dB
# PSNR-H; 1 dB is the smallest difference we call a real loss.
RELIGHT_TOLERANCE_DB = 1.0
# "Fine-tuning in less than a third of Mitsuba's time" (paper section 5.6.1).
FINETUNE_TIME_FRACTION = 1.0 / 3.0


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
        A copy with ``relight_env`` as strings ('' where empty) and ``value`` as float.

    Raises
    ------
    ValueError
        Naming the missing columns.
    """
    missing = [c for c in TIDY_COLUMNS if c not in df.columns]
    if missing:
        raise ValueError(f"metrics table lacks columns {missing} (has {list(df.columns)})")
    out = df.copy()
    # read_csv turns empty relight_env cells into NaN; compare them as ''.
    out["relight_env"] = out["relight_env"].fillna("").astype(str)
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


def _relight_cells(df: pd.DataFrame, method: str | None, paper: Mapping[str, float] | None) -> dict[str, str]:
    """PSNR-H, PSNR-L and SSIM of a method (mean over captures, relighting
    environments and test views), each followed by the paper's value."""
    cells = {}
    for metric, label, digits in _RELIGHT_METRICS:
        ours = mean_metric(df, method, metric) if method else None
        cells[label] = _ours(df, method, fmt(ours, digits))
        cells[f"{label} (paper)"] = fmt(paper[metric], digits) if paper else MISSING
    return cells


def relighting_table(df: pd.DataFrame) -> pd.DataFrame:
    """Paper Table 1: relighting under held-out environments, per method.

    Rows are the paper's methods (ours where this pipeline has them, ``not run``
    otherwise), then any other method of ours with relighting numbers.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (:func:`check_tidy`).

    Returns
    -------
    DataFrame of str
        ``Method, method, PSNR-H, PSNR-H (paper), PSNR-L, ..., Time, Time (paper)``.
    """
    rows = []
    for label, method in PAPER_TABLE1_METHODS.items():
        paper = PAPER_TABLE1[label]
        row = {"Method": label, "method": method or MISSING, **_relight_cells(df, method, paper)}
        row["Time"] = _ours(df, method, fmt_time(method_time(df, method)) if method else MISSING)
        row["Time (paper)"] = fmt_time(paper["time_s"])
        rows.append(row)
    relit = df[df.relight_env != ""]
    listed = {m for m in PAPER_TABLE1_METHODS.values() if m}
    for method in _ordered_methods(relit.method.unique()):
        if method in listed:
            continue
        row = {"Method": METHOD_LABELS.get(method, method), "method": method, **_relight_cells(df, method, None)}
        row["Time"] = fmt_time(method_time(df, method))
        row["Time (paper)"] = MISSING
        rows.append(row)
    return pd.DataFrame(rows)


def _ordered_methods(methods) -> list[str]:
    """Our methods in display order: the paper's main rows first, then the ablations."""
    order = list(METHOD_LABELS)
    return sorted(methods, key=lambda m: (order.index(m) if m in order else len(order), m))


def _ordered_envs(df: pd.DataFrame, env_kinds: Mapping[str, str]) -> list[str]:
    """Capture environments with parameter MSE, in configuration order, then the rest."""
    present = set(df[df.metric == "mse_average"].env) | set(df[df.metric == "pearson_entropy_error"].env)
    order = list(env_kinds)
    return sorted(present, key=lambda e: (order.index(e) if e in order else len(order), e))


def parameter_table(df: pd.DataFrame, env_kinds: Mapping[str, str] | None = None, digits: int = 3) -> pd.DataFrame:
    """Paper Table 2: parameter MSE per capture environment, with the error-entropy correlation.

    Cells read ``average (base colour, roughness, metallic)``, means over
    objects. For each method the paper has, a ``paper`` row sits above our
    (``here``) row; its environment columns hold the paper's value for the
    environment of the same kind (``env_kinds``), e.g. Rural Road for sunny.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (:func:`check_tidy`).
    env_kinds : mapping, optional
        Our environment name -> kind (``studio``, ``museum``, ``sunny``,
        ``overcast``); by default an environment's name is its kind.
    digits : int
        Decimals of our numbers (the paper prints 2).

    Returns
    -------
    DataFrame of str
        ``Method, source, <env> [paper: <name>] ..., Avg., Time``.
    """
    env_kinds = dict(env_kinds or {})
    envs = _ordered_envs(df, env_kinds)
    headers = {}
    for env in envs:
        kind = env_kinds.get(env, env)
        headers[env] = f"{env} [paper: {PAPER_ENV_NAMES[kind]}]" if kind in PAPER_ENV_NAMES else env
    parts = ("mse_average", "mse_base_color", "mse_roughness", "mse_metallic")

    methods = ["mitsuba", "freq", "spectrum"]
    methods += [m for m in _ordered_methods(df[df.metric == "mse_average"].method.unique()) if m not in methods]
    rows = []
    for method in methods:
        label = f"{METHOD_LABELS.get(method, method)} ({method})"
        if method in PAPER_TABLE2_MSE:
            paper = PAPER_TABLE2_MSE[method]
            row = {"Method": label, "source": "paper"}
            for env in envs:
                kind = env_kinds.get(env, env)
                row[headers[env]] = _mse_cell(paper[kind], 2) if kind in paper else MISSING
            row["Avg."] = _mse_cell(paper["avg"], 2)
            row["Time"] = fmt_time(PAPER_TABLE2_TIME_S[method])
            rows.append(row)
        row = {"Method": label, "source": "here"}
        for env in envs:
            row[headers[env]] = _ours(df, method, _mse_cell([mean_metric(df, method, p, env=env) for p in parts], digits))
        row["Avg."] = _ours(df, method, _mse_cell([mean_metric(df, method, p) for p in parts], digits))
        row["Time"] = _ours(df, method, fmt_time(method_time(df, method)))
        rows.append(row)

    # The correlation row: our entropy against Mitsuba's error (the paper's),
    # then against our own error (not in the paper).
    for method in ("mitsuba", "freq"):
        label = f"Error-entropy correlation ({method})"
        if method == "mitsuba":
            row = {"Method": label, "source": "paper"}
            for env in envs:
                kind = env_kinds.get(env, env)
                row[headers[env]] = fmt(PAPER_TABLE2_CORRELATION[kind], 2) if kind in PAPER_TABLE2_CORRELATION else MISSING
            row["Avg."] = fmt(PAPER_TABLE2_CORRELATION["avg"], 2)
            row["Time"] = MISSING
            rows.append(row)
        row = {"Method": label, "source": "here"}
        for env in envs:
            row[headers[env]] = _ours(df, method, fmt(mean_metric(df, method, "pearson_entropy_error", env=env), 2))
        row["Avg."] = _ours(df, method, fmt(mean_metric(df, method, "pearson_entropy_error"), 2))
        row["Time"] = MISSING
        rows.append(row)
    columns = ["Method", "source", *headers.values(), "Avg.", "Time"]
    return pd.DataFrame(rows, columns=columns)


def ablation_table(df: pd.DataFrame, digits: int = 3) -> pd.DataFrame:
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
    for (shadowing, masking), paper in PAPER_TABLE4.items():
        method = ABLATION_METHODS[(shadowing, masking)]
        row = {"Shadowing": "yes" if shadowing else "no", "Masking": "yes" if masking else "no", "method": method}
        row.update(_relight_cells(df, method, paper))
        row["MSE"] = _ours(df, method, fmt(mean_metric(df, method, "mse_average"), digits))
        row["MSE (paper)"] = fmt(paper["mse"], 2)
        row["Time"] = _ours(df, method, fmt_time(method_time(df, method)))
        row["Time (paper)"] = fmt_time(paper["time_s"])
        rows.append(row)
    return pd.DataFrame(rows)


def finetune_table(df: pd.DataFrame, digits: int = 3) -> pd.DataFrame:
    """Paper Table 5: a short Mitsuba fine-tuning pass from different initialisations.

    Our parameter MSE is added (the paper reports none for this table).

    Returns
    -------
    DataFrame of str
        ``Initialization, method, PSNR-H, PSNR-H (paper), ..., MSE, Total time, Total time (paper)``.
    """
    rows = []
    for label, method in PAPER_TABLE5_METHODS.items():
        paper = PAPER_TABLE5[label]
        row = {"Initialization": label, "method": method or MISSING, **_relight_cells(df, method, paper)}
        row["MSE"] = _ours(df, method, fmt(mean_metric(df, method, "mse_average"), digits) if method else MISSING)
        row["Total time"] = _ours(df, method, fmt_time(method_time(df, method)) if method else MISSING)
        row["Total time (paper)"] = fmt_time(paper["time_s"])
        rows.append(row)
    return pd.DataFrame(rows)


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


def claims(df: pd.DataFrame) -> pd.DataFrame:
    """The paper's headline claims, its values, ours, and whether each holds here.

    Criteria (each a mean over the captures in ``df``):

    1. Speed: freq is faster than Mitsuba (speed ratio > 1).
    2. Speed order: time(spectrum) < time(freq) < time(mitsuba).
    3. Accuracy: MSE(freq) - MSE(mitsuba) <= ACCURACY_TOLERANCE_MSE.
    4. Relighting: PSNR-H(freq) >= PSNR-H(mitsuba) - RELIGHT_TOLERANCE_DB.
    5. Spectrum-only is less accurate than the full model: MSE(spectrum) > MSE(freq).
    6. Ablation order: MSE(freq) < min(MSE(freq_noshadow), MSE(freq_nomask)) and
       max(MSE(freq_noshadow), MSE(freq_nomask)) < MSE(rh2001).
    7. Fine-tuning improves ours: MSE(freq+mitsuba) < MSE(freq).
    8. Fine-tuning beats Mitsuba alone, in less than a third of its time:
       PSNR-H(freq+mitsuba) > PSNR-H(mitsuba) and
       time(freq+mitsuba) < FINETUNE_TIME_FRACTION * time(mitsuba).
    9. Entropy predicts Mitsuba's error: mean Pearson(entropy, squared error) > 0.

    A claim whose methods did not run (or lack the metric) is ``not run``.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (:func:`check_tidy`).

    Returns
    -------
    DataFrame of str
        Columns ``claim, paper, ours, holds, criterion``.
    """
    mse = {m: mean_metric(df, m, "mse_average") for m in
           ("mitsuba", "freq", "spectrum", "freq_noshadow", "freq_nomask", "rh2001", "freq+mitsuba")}
    psnr = {m: mean_metric(df, m, "psnr_h") for m in ("mitsuba", "freq", "freq+mitsuba")}
    time = {m: method_time(df, m) for m in ("mitsuba", "freq", "spectrum", "freq+mitsuba")}
    out: list[Claim] = []

    ratio = speed_ratio(df, "freq") if _ran(df, "freq", "mitsuba") else None
    out.append(Claim(
        "Ours (freq) fits much faster than Mitsuba",
        "33.5x (105.19 s vs 3.14 s, Table 2); 13.3x on Stanford-ORB (Table 1)",
        MISSING if ratio is None else f"{ratio:.1f}x ({fmt_time(time['mitsuba'])} vs {fmt_time(time['freq'])})",
        _verdict(None if ratio is None else ratio > 1.0),
        "speed ratio time(mitsuba) / time(freq) > 1",
    ))

    times = [time["spectrum"], time["freq"], time["mitsuba"]]
    known = None not in times
    out.append(Claim(
        "Spectrum-only is faster than ours, which is faster than Mitsuba",
        "1.20 s < 3.14 s < 105.19 s (Table 2)",
        " < ".join(fmt_time(t) for t in times) if known else MISSING,
        _verdict(times[0] < times[1] < times[2] if known else None),
        "time(spectrum) < time(freq) < time(mitsuba), mean per capture",
    ))

    known = mse["freq"] is not None and mse["mitsuba"] is not None
    out.append(Claim(
        "Parameter accuracy comparable to Mitsuba",
        "MSE 0.06 vs 0.04 (Table 2)",
        f"MSE {fmt(mse['freq'])} vs {fmt(mse['mitsuba'])}" if known else MISSING,
        _verdict(mse["freq"] - mse["mitsuba"] <= ACCURACY_TOLERANCE_MSE if known else None),
        f"MSE(freq) - MSE(mitsuba) <= {ACCURACY_TOLERANCE_MSE}",
    ))

    known = psnr["freq"] is not None and psnr["mitsuba"] is not None
    out.append(Claim(
        "Relighting on par with Mitsuba",
        "PSNR-H 26.68 vs 26.60 dB (Table 1)",
        f"PSNR-H {fmt(psnr['freq'], 2)} vs {fmt(psnr['mitsuba'], 2)} dB" if known else MISSING,
        _verdict(psnr["freq"] >= psnr["mitsuba"] - RELIGHT_TOLERANCE_DB if known else None),
        f"PSNR-H(freq) >= PSNR-H(mitsuba) - {RELIGHT_TOLERANCE_DB} dB",
    ))

    known = mse["spectrum"] is not None and mse["freq"] is not None
    out.append(Claim(
        "The full model is more accurate than the spectrum-only estimate",
        "MSE 0.06 vs 0.21 (Table 2)",
        f"MSE {fmt(mse['freq'])} vs {fmt(mse['spectrum'])}" if known else MISSING,
        _verdict(mse["freq"] < mse["spectrum"] if known else None),
        "MSE(freq) < MSE(spectrum)",
    ))

    ablation = [mse[m] for m in ("rh2001", "freq_nomask", "freq_noshadow", "freq")]
    known = None not in ablation
    if known:
        neither, shadow_only, mask_only, both = ablation
        ordered = both < min(shadow_only, mask_only) and max(shadow_only, mask_only) < neither
    out.append(Claim(
        "Shadowing and masking each improve on Ramamoorthi-Hanrahan; both together are best",
        "MSE neither 0.16, shadowing 0.14, masking 0.13, both 0.12 (Table 4)",
        "MSE neither {}, shadowing {}, masking {}, both {}".format(*map(fmt, ablation)) if known else MISSING,
        _verdict(ordered if known else None),
        "MSE(freq) < MSE(freq_noshadow), MSE(freq_nomask) < MSE(rh2001)",
    ))

    known = mse["freq+mitsuba"] is not None and mse["freq"] is not None
    extra = ""
    if psnr["freq+mitsuba"] is not None and psnr["freq"] is not None:
        extra = f"; PSNR-H {fmt(psnr['freq+mitsuba'], 2)} vs {fmt(psnr['freq'], 2)} dB"
    out.append(Claim(
        "Fine-tuning our result with Mitsuba improves on ours",
        "PSNR-H 27.04 vs 26.68 dB (Tables 1, 5)",
        f"MSE {fmt(mse['freq+mitsuba'])} vs {fmt(mse['freq'])}{extra}" if known else MISSING,
        _verdict(mse["freq+mitsuba"] < mse["freq"] if known else None),
        "MSE(freq+mitsuba) < MSE(freq)",
    ))

    known = None not in (psnr["freq+mitsuba"], psnr["mitsuba"], time["freq+mitsuba"], time["mitsuba"])
    out.append(Claim(
        "Ours + Mitsuba beats Mitsuba alone in less than a third of its time",
        "PSNR-H +0.44 dB, 19.87 s vs 69.96 s (Table 5)",
        (f"PSNR-H {psnr['freq+mitsuba'] - psnr['mitsuba']:+.2f} dB, "
         f"{fmt_time(time['freq+mitsuba'])} vs {fmt_time(time['mitsuba'])}") if known else MISSING,
        _verdict(psnr["freq+mitsuba"] > psnr["mitsuba"]
                 and time["freq+mitsuba"] < FINETUNE_TIME_FRACTION * time["mitsuba"] if known else None),
        "PSNR-H(freq+mitsuba) > PSNR-H(mitsuba) and time(freq+mitsuba) < time(mitsuba) / 3",
    ))

    r_mitsuba = mean_metric(df, "mitsuba", "pearson_entropy_error")
    r_freq = mean_metric(df, "freq", "pearson_entropy_error")
    ours = [f"{label} {fmt(r, 2)}" for label, r in (("Mitsuba", r_mitsuba), ("freq", r_freq)) if r is not None]
    out.append(Claim(
        "Our entropy correlates positively with Mitsuba's per-texel error",
        "Pearson 0.13 to 0.21, mean 0.16 (Table 2)",
        "; ".join(ours) if ours else MISSING,
        _verdict(None if r_mitsuba is None else r_mitsuba > 0.0),
        "mean Pearson(entropy, Mitsuba's squared parameter error) > 0",
    ))
    return pd.DataFrame([asdict(c) for c in out], columns=["claim", "paper", "ours", "holds", "criterion"])


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
    """A GitHub-flavoured Markdown pipe table (with optional heading and caption).

    Parameters
    ----------
    table : DataFrame
        Cells are converted with ``str``; ``|`` is escaped.
    title : str, optional
        Level-3 heading above the table.
    caption : str, optional
        Paragraph below the table.
    """

    def cell(value) -> str:
        return str(value).replace("|", r"\|").replace("\n", " ")

    lines = []
    if title:
        lines += [f"### {title}", ""]
    lines.append("| " + " | ".join(cell(c) for c in table.columns) + " |")
    lines.append("|" + "|".join("---:" if right else "---" for right in _right_aligned(table)) + "|")
    for row in table.itertuples(index=False):
        lines.append("| " + " | ".join(cell(v) for v in row) + " |")
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


def to_latex(table: pd.DataFrame, caption: str | None = None, label: str | None = None) -> str:
    """A LaTeX ``table`` with a booktabs ``tabular`` (needs ``\\usepackage{booktabs}``).

    Parameters
    ----------
    table : DataFrame
        Cells are converted with ``str`` and escaped.
    caption, label : str, optional
        ``\\caption`` and ``\\label`` of the float.
    """
    spec = "".join("r" if right else "l" for right in _right_aligned(table))
    lines = [r"\begin{table}[ht]", r"\centering", r"\small", rf"\begin{{tabular}}{{{spec}}}", r"\toprule"]
    lines.append(" & ".join(latex_escape(c) for c in table.columns) + r" \\")
    lines.append(r"\midrule")
    for row in table.itertuples(index=False):
        lines.append(" & ".join(latex_escape(v) for v in row) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}"]
    if caption:
        lines.append(rf"\caption{{{latex_escape(caption)}}}")
    if label:
        lines.append(rf"\label{{{label}}}")
    lines.append(r"\end{table}")
    return "\n".join(lines) + "\n"


def to_html(table: pd.DataFrame, title: str | None = None, caption: str | None = None,
            verdicts: str | None = None) -> str:
    """An HTML fragment: heading, ``<table>`` and caption paragraph.

    Parameters
    ----------
    table : DataFrame
        Cells are converted with ``str`` and escaped.
    title, caption : str, optional
        ``<h2>`` above and a paragraph below the table.
    verdicts : str, optional
        A column of ``yes`` / ``no`` / ``not run`` (the claims' ``holds``) whose
        cells get the classes ``yes``, ``no`` and ``notrun``, for colour.
        ``not run`` cells elsewhere get ``notrun`` too (greyed).
    """
    right = _right_aligned(table)
    verdict_index = list(table.columns).index(verdicts) if verdicts is not None else -1
    parts = []
    if title:
        parts.append(f"<h2>{html.escape(title)}</h2>")
    parts.append("<table>")
    parts.append("<thead><tr>" + "".join(f"<th>{html.escape(str(c))}</th>" for c in table.columns) + "</tr></thead>")
    parts.append("<tbody>")
    for row in table.itertuples(index=False):
        cells = []
        for k, (value, is_right) in enumerate(zip(row, right)):
            text = str(value)
            classes = ["notrun" if text == NOT_RUN else ""]
            if k == verdict_index:
                classes.append({"yes": "yes", "no": "no"}.get(text, ""))
            if is_right:
                classes.append("num")
            cls = " ".join(c for c in classes if c)
            cells.append(f'<td class="{cls}">{html.escape(text)}</td>' if cls else f"<td>{html.escape(text)}</td>")
        parts.append("<tr>" + "".join(cells) + "</tr>")
    parts.append("</tbody></table>")
    if caption:
        parts.append(f'<p class="caption">{html.escape(caption)}</p>')
    return "\n".join(parts) + "\n"


HTML_STYLE = """
body { font-family: sans-serif; font-size: 13px; margin: 1.2em; color: #222; }
h1 { font-size: 20px; } h2 { font-size: 16px; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.4em 0; }
th, td { border: 1px solid #ccc; padding: 3px 7px; }
th, td.num, td.notrun { white-space: nowrap; }
th { background: #eef; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
td.yes { background: #d8f5d0; } td.no { background: #f8d0d0; } td.notrun { color: #888; }
p.caption { max-width: 60em; color: #444; }
"""


def html_page(title: str, body: str) -> str:
    """A self-contained HTML page (inline style, no external resources)."""
    return (f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{html.escape(title)}</title>"
            f"<style>{HTML_STYLE}</style></head>\n<body>\n<h1>{html.escape(title)}</h1>\n{body}</body></html>\n")


@dataclass(frozen=True)
class Summary:
    """One summary table with its file stem, title and caption."""

    key: str
    title: str
    caption: str
    table: pd.DataFrame


def summaries(df: pd.DataFrame, env_kinds: Mapping[str, str] | None = None) -> list[Summary]:
    """Every summary table of the report, in the paper's order, then the claims.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (:func:`check_tidy`), one pose source.
    env_kinds : mapping, optional
        Our environment name -> kind, to place the paper's environments (:func:`parameter_table`).

    Returns
    -------
    list of Summary
        Keys ``table1_relighting``, ``table2_parameters``, ``table4_ablation``,
        ``table5_finetune``, ``claims`` (the output file stems).
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
                relighting_table(df)),
        Summary("table2_parameters", "Table 2: parameter MSE per capture environment",
                "Average (base colour, roughness, metallic) MSE against the ground-truth textures over "
                "observed texels; 'paper' rows give the paper's value for the environment of the same kind. "
                "Error-entropy correlation: Pearson correlation between our entropy and the method's "
                "per-texel squared error (the paper correlates with Mitsuba's). " + scope,
                parameter_table(df, env_kinds)),
        Summary("table4_ablation", "Table 4: ablation of shadowing and masking",
                "Our model with and without the shadowing G1(theta_i) and masking G1(theta_o) terms; "
                "rh2001 has neither (Ramamoorthi and Hanrahan 2001). The paper's relighting numbers are on "
                "Stanford-ORB and its MSE and time on its synthetic set, both without cosine weighting of "
                "the samples; ours use cosine weighting. " + scope,
                ablation_table(df)),
        Summary("table5_finetune", "Table 5: fine-tuning with Mitsuba",
                "A short Mitsuba optimisation started from our textures (freq+mitsuba) against Mitsuba's "
                "full optimisation from a constant (mitsuba) and our textures alone (freq). Total time "
                "includes the initialisation. Rows without a method of ours are not in this pipeline. " + scope,
                finetune_table(df)),
        Summary("claims", "Claims of the paper, checked on this run",
                "holds: 'yes' or 'no' by the stated criterion on this run's means; 'not run' when a method "
                "it needs is not in the configuration's methods or produced no such metric. " + scope,
                claims(df)),
    ]
