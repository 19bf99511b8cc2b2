"""The paper's headline claims, checked on a run's tidy metrics (:func:`claims`), with the
paper's values quoted beside ours; the tolerances come from the paper's results file
(:class:`freqbrdf.report.tables.paper.ClaimCriteria`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import asdict, dataclass

import pandas as pd

from freqbrdf.methods import METHODS, ablation_method
from freqbrdf.report.tables.display import MISSING, NOT_RUN, fmt, fmt_paper, fmt_ratio, fmt_time
from freqbrdf.report.tables.paper import (AGREEMENT_ROWS, AVERAGE, FINETUNED, MERGE_AVERAGE, MITSUBA, MITSUBA_FULL,
                                          OURS, SPECTRUM, PaperResults)
from freqbrdf.report.tables.tidy import (capture_metric, equal_accuracy_ratio, mean_metric, method_time, ran,
                                         speed_ratio, views_sweep)


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


def _mse(df: pd.DataFrame, method: str) -> float | None:
    return mean_metric(df, method, "mse_average")


def _psnr(df: pd.DataFrame, method: str) -> float | None:
    return mean_metric(df, method, "psnr_h")


def _speed_claim(df: pd.DataFrame, paper: PaperResults) -> Claim:
    mitsuba, ours = paper.table2[MITSUBA].time_s, paper.table2[OURS].time_s
    orb = paper.table1[MITSUBA]["time_s"] / paper.table1[OURS]["time_s"]
    ratio, exact = equal_accuracy_ratio(df, "freq") if ran(df, "freq", "mitsuba") else (None, False)
    budget = speed_ratio(df, "freq") if ran(df, "freq", "mitsuba") else None
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
    ours, average = (_mse(df, merged), _mse(df, start)) if merged and ran(df, merged, start) else (None, None)
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
    r = capture_metric(df, "entropy_agreement_pearson_spectrum")
    angular = capture_metric(df, "entropy_agreement_pearson_angular")
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
        Tidy metrics (:func:`freqbrdf.report.tables.tidy.check_tidy`).
    paper : PaperResults
        The paper's numbers, quoted in the ``paper`` column.

    Returns
    -------
    DataFrame of str
        Columns ``claim, paper, ours, holds, criterion``.
    """
    rows = [asdict(claim(df, paper)) for claim in _CLAIMS]
    return pd.DataFrame(rows, columns=["claim", "paper", "ours", "holds", "criterion"])
