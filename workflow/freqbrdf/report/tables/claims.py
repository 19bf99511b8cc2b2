"""The paper's headline claims, judged on a run's tidy metrics (:func:`claims`), with the
paper's values quoted beside ours.

Every number judged carries its t-interval over captures (:mod:`freqbrdf.report.intervals`):
a claim is ``yes`` when its criterion holds at the interval's unfavourable end, ``no`` when
it fails at the favourable end, ``within noise`` otherwise. A comparison of two methods is
judged on their paired difference, capture by capture (and test view by test view). The
thresholds are the paper's own numbers (:class:`freqbrdf.report.tables.paper.PaperResults`).

One rule serves every claim that reads Mitsuba's estimate (speed, accuracy, relighting,
fine-tuning against Mitsuba alone, the entropy's correlation with Mitsuba's error, the merge
of Mitsuba's captures): it is judged on the captures where the baseline converged, its
value on all captures beside; ``not judged`` when fewer than half converged, for an
unconverged baseline measures its budget, not the method.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace

import numpy as np
import pandas as pd

from freqbrdf.methods import METHODS, ablation_method
from freqbrdf.util.mitsuba_setup import timing_note
from freqbrdf.report.intervals import NO, NOISE, NOT_JUDGED, YES, Interval, IntervalSettings, all_hold, judge
from freqbrdf.report.tables.display import MISSING, NOT_RUN, fmt, fmt_interval, fmt_paper
from freqbrdf.report.tables.paper import AGREEMENT_ROWS, AVERAGE, FINETUNED, MERGE_AVERAGE, MITSUBA, MITSUBA_FULL, \
    OURS, SPECTRUM, PaperResults
from freqbrdf.report.tables.tidy import (capture_metric, cluster_keys, metric_interval, ran, unit_values,
                                         views_sweep)

__all__ = ["CLAIM_COLUMNS", "Claim", "ClaimContext", "claims", "verdict_counts"]

CLAIM_COLUMNS = ["claim", "paper", "ours", "holds", "criterion"]


@dataclass(frozen=True)
class Claim:
    """One headline claim of the paper, judged on our numbers."""

    claim: str
    paper: str
    ours: str
    holds: str  # a verdict of freqbrdf.report.intervals.VERDICTS, or "not run"
    criterion: str


@dataclass(frozen=True)
class ClaimContext:
    """What the claims need besides the metrics.

    Attributes
    ----------
    intervals : IntervalSettings
        The intervals' settings.
    mitsuba_budget : str
        The baseline's budget as the tables label it, e.g. ``6 epochs x 8 spp``.
    real_objects : frozenset of str
        Objects that are real captures (judged against the paper's Stanford-ORB figures).
    timing : str
        Where the run's times were taken (`freqbrdf.util.mitsuba_setup.timing_note`).
    """

    intervals: IntervalSettings = field(default_factory=IntervalSettings)
    mitsuba_budget: str = ""
    real_objects: frozenset[str] = frozenset()
    timing: str = field(default_factory=lambda: timing_note("llvm_ad_rgb"))


class _Judge:
    """Intervals of one run's metrics, with the state of its Mitsuba baseline per capture."""

    def __init__(self, df: pd.DataFrame, context: ClaimContext):
        self.df, self.context = df, context
        flags = df[(df.method == "mitsuba") & (df.metric == "mitsuba_converged")].dropna(subset=["value"])
        self.flags = flags.set_index(["object", "env", "poses"]).value == 1.0

    def values(self, method: str, metric: str, real: bool | None = False) -> pd.Series:
        """Per-unit values (:func:`unit_values`), of the synthetic or real captures (None: both)."""
        values = unit_values(self.df, method, metric)
        if real is None or values.empty:
            return values
        is_real = values.index.get_level_values("object").isin(self.context.real_objects)
        return values[is_real == real]

    def interval(self, values: pd.Series, *methods: str) -> Interval | None:
        """The interval of per-unit values of ``methods`` (clustered by object for a merge)."""
        return metric_interval(values, self.context.intervals, cluster_keys(*methods))

    def mean(self, method: str, metric: str) -> Interval | None:
        return self.interval(self.values(method, metric), method)

    def difference(self, a: str, b: str, metric: str) -> Interval | None:
        """The mean of ``a - b`` over the units both have."""
        return self.interval((self.values(a, metric) - self.values(b, metric)).dropna(), a, b)

    def converged_count(self, by_object: bool) -> tuple[int, int]:
        """How many captures (objects, ``by_object``: all of an object's captures) Mitsuba converged
        on, and of how many it says whether it did."""
        if not by_object:
            return int(self.flags.sum()), len(self.flags)
        per_object = self.flags.groupby(level="object").all()
        return int(per_object.sum()), len(per_object)

    def converged_only(self) -> _Judge:
        """The same metrics on the captures where Mitsuba converged; a merge of Mitsuba's captures
        (a method whose start is ``mitsuba``) only where all its object's captures did."""
        done = set(self.flags.index[self.flags])
        failed = {obj for obj, _, _ in self.flags.index[~self.flags]}
        keys = list(zip(self.df.object, self.df.env, self.df.poses))
        reads_all = self.df.method.map(lambda m: m in METHODS and METHODS[m].rule == "merge_svbrdf"
                                       and METHODS[m].start == "mitsuba")
        keep = pd.Series([k in done for k in keys], index=self.df.index) & ~(reads_all & self.df.object.isin(failed))
        return _Judge(self.df[keep], self.context)


def _mitsuba_rule(make: Callable[[_Judge, PaperResults], Claim],
                  by_object: bool = False) -> Callable[[_Judge, PaperResults], Claim]:
    """The claim ``make`` judges, under the rule for every claim that reads Mitsuba's estimate:
    judged on the captures where Mitsuba converged (all captures' value beside), ``not judged``
    when fewer than half did or none says whether it did. ``by_object``: a claim on a merge of an
    object's captures counts the objects whose captures all converged."""

    @functools.wraps(make)
    def claim(j: _Judge, paper: PaperResults) -> Claim:
        full = make(j, paper)
        if full.holds == NOT_RUN:
            return full
        k, n = j.converged_count(by_object)
        unit = "objects" if by_object else "captures"
        budget = f", budget {j.context.mitsuba_budget}" if j.context.mitsuba_budget else ""
        if n == 0 or 2 * k < n:
            state = "convergence unknown" if n == 0 else f"Mitsuba converged on {k} of {n} {unit}, fewer than half"
            return replace(full, ours=f"not judged: {state}{budget}; {full.ours}", holds=NOT_JUDGED)
        if k == n:
            return full
        part = make(j.converged_only(), paper)
        holds = NOT_JUDGED if part.holds == NOT_RUN else part.holds  # it ran, on none of the converged ones
        return replace(part, holds=holds, ours=f"on the {k} of {n} {unit} where Mitsuba converged{budget}: "
                                              f"{part.ours}; on all {n}: {full.ours}")

    return claim


def _time(j: _Judge, method: str, real: bool | None = None) -> pd.Series:
    """Per capture, the method's time from the capture (``time_total_s``, else ``time_s``)."""
    total = j.values(method, "time_total_s", real)
    return total if len(total) else j.values(method, "time_s", real)


def _versus(j: _Judge, claim: str, paper: str, a: str, b: str, metric: str, op: str, threshold: float,
            name: str, digits: int, criterion: str, unit: str = "") -> Claim:
    """A claim on the paired difference ``metric(a) - metric(b)``, both means shown beside it."""
    if not ran(j.df, a, b):
        return Claim(claim, paper, MISSING, NOT_RUN, criterion)
    mean_a, mean_b, diff = j.mean(a, metric), j.mean(b, metric), j.difference(a, b, metric)
    if diff is None:
        return Claim(claim, paper, MISSING, NOT_JUDGED, criterion)
    ours = (f"{name} {fmt_interval(mean_a, digits)} vs {fmt_interval(mean_b, digits)}{unit}; "
            f"difference {fmt_interval(diff, digits, sign=True)}{unit}")
    return Claim(claim, paper, ours, judge(diff, op, threshold), criterion)


def _front(j: _Judge) -> tuple[pd.Series, pd.Series]:
    """Per synthetic capture, the largest ``speed_ratio_at_mitsuba_accuracy`` over the methods (the
    fastest method at least as accurate as Mitsuba's converged run), and that method's name;
    captures none reaches are left out."""
    methods = j.df.loc[j.df.metric == "speed_ratio_at_mitsuba_accuracy", "method"].unique()
    per_method = {m: j.values(m, "speed_ratio_at_mitsuba_accuracy") for m in methods}
    per_method = {m: v for m, v in per_method.items() if len(v)}
    if not per_method:
        return pd.Series(dtype=float), pd.Series(dtype=object)
    table = pd.concat(per_method, axis=1).dropna(how="all")
    return table.max(axis=1), table.idxmax(axis=1)


_SPEED_CLAIM = "Ours (freq) fits much faster than Mitsuba"


def _speed_claim(j: _Judge, paper: PaperResults) -> Claim:
    """Table 2's comparison: each method run to its own result, Mitsuba's time to its converged
    MSE over freq's time from the capture; the fastest frequency-domain method that is at least as
    accurate as Mitsuba beside it, named."""
    threshold = paper.speedup_synthetic
    text = (f"{threshold:.1f}x ({fmt_paper(paper.table2[MITSUBA].time_s, 2)} s vs "
            f"{fmt_paper(paper.table2[OURS].time_s, 2)} s, Table 2); {paper.speedup_real:.1f}x on Stanford-ORB "
            "(Table 1)")
    criterion = (f"Mitsuba's time to its converged MSE / freq's time from the capture >= {threshold:.1f} "
                 "(Table 2: each run to its own result), geometric mean over the synthetic captures")
    if not ran(j.df, "freq", "mitsuba"):
        return Claim(_SPEED_CLAIM, text, MISSING, NOT_RUN, criterion)
    ratios = j.values("freq", "speed_ratio_at_mitsuba_converged")
    if ratios.empty:
        return Claim(_SPEED_CLAIM, text, MISSING, NOT_JUDGED, criterion)
    ratio = j.interval(np.log(ratios)).map(np.exp)
    ours = f"freq {fmt_interval(ratio, 1)}x"
    front, fastest = _front(j)
    if len(front):
        named = ", ".join(f"{m} on {n}" for m, n in fastest.value_counts().items())
        ours += (f"; the fastest frequency-domain method at least as accurate as Mitsuba "
                 f"{fmt_interval(j.interval(np.log(front)).map(np.exp), 1)}x ({named} of {len(ratios)} captures)")
    return Claim(_SPEED_CLAIM, text, ours, judge(ratio, ">=", threshold), criterion)


def _speed_real_claim(j: _Judge, paper: PaperResults) -> Claim | None:
    """On real captures (no ground truth, so no equal-accuracy time): Mitsuba's time over freq's."""
    ratios = j.values("freq", "speed_ratio_vs_mitsuba", real=True)
    if ratios.empty:
        return None
    ratio = j.interval(np.log(ratios)).map(np.exp)
    threshold = paper.speedup_real
    return Claim("Ours (freq) fits much faster than Mitsuba on real captures",
                 f"{threshold:.1f}x ({fmt_paper(paper.table1[MITSUBA]['time_s'], 2)} s vs "
                 f"{fmt_paper(paper.table1[OURS]['time_s'], 2)} s, Stanford-ORB, Table 1)",
                 f"{fmt_interval(ratio, 1)}x over {ratio.clusters} real capture(s)", judge(ratio, ">=", threshold),
                 f"time(mitsuba) / time(freq) >= {threshold:.1f} (Table 1), geometric mean over the real captures")


def _speed_order_claim(j: _Judge, paper: PaperResults) -> Claim:
    claim = "Spectrum-only is faster than ours, which is faster than Mitsuba"
    text = " < ".join(f"{fmt_paper(paper.table2[row].time_s, 2)} s" for row in (SPECTRUM, OURS, MITSUBA)) + " (Table 2)"
    criterion = "time(freq) - time(spectrum) > 0 and time(mitsuba) - time(freq) > 0, per capture"
    times = {m: _time(j, m) for m in ("spectrum", "freq", "mitsuba")}
    if any(t.empty for t in times.values()):
        return Claim(claim, text, MISSING, NOT_RUN, criterion)
    gaps = [j.interval((times[b] - times[a]).dropna()) for a, b in (("spectrum", "freq"), ("freq", "mitsuba"))]
    means = " < ".join(f"{fmt_interval(j.interval(t), 1, unit=' s')}" for t in times.values())
    ours = f"{means}; gaps {fmt_interval(gaps[0], 1, unit=' s')}, {fmt_interval(gaps[1], 1, unit=' s')}"
    return Claim(claim, text, ours, all_hold(judge(g, ">", 0.0) for g in gaps), criterion)


def _average_mse(paper: PaperResults, row: str) -> str:
    return fmt_paper(paper.table2[row].mse[AVERAGE][0], 2)


def _accuracy_claim(j: _Judge, paper: PaperResults) -> Claim:
    gap = paper.accuracy_gap_mse
    return _versus(j, "Parameter accuracy comparable to Mitsuba",
                   f"MSE {_average_mse(paper, OURS)} vs {_average_mse(paper, MITSUBA)} (Table 2)",
                   "freq", "mitsuba", "mse_average", "<=", gap, "MSE", 3,
                   f"MSE(freq) - MSE(mitsuba) <= {gap:.2f} (the paper's own gap, Table 2)")


def _relight_claim(j: _Judge, paper: PaperResults) -> Claim:
    gap = paper.relight_gap_db
    return _versus(j, "Relighting on par with Mitsuba",
                   f"PSNR-H {fmt_paper(paper.table1[OURS]['psnr_h'], 2)} vs "
                   f"{fmt_paper(paper.table1[MITSUBA]['psnr_h'], 2)} dB (Table 1)",
                   "freq", "mitsuba", "psnr_h", ">=", -gap, "PSNR-H", 2,
                   f"PSNR-H(freq) - PSNR-H(mitsuba) >= -{gap:.2f} dB (the paper's own gap, Table 1)", unit=" dB")


def _spectrum_claim(j: _Judge, paper: PaperResults) -> Claim:
    return _versus(j, "The full model is more accurate than the spectrum-only estimate",
                   f"MSE {_average_mse(paper, OURS)} vs {_average_mse(paper, SPECTRUM)} (Table 2)",
                   "freq", "spectrum", "mse_average", "<", 0.0, "MSE", 3, "MSE(freq) - MSE(spectrum) < 0")


# The Table 4 rows by the words of the claim: (shadowing, masking).
_ABLATION_PAIRS = {"neither": (False, False), "shadowing": (True, False), "masking": (False, True),
                   "both": (True, True)}
# Each better than the other: both < shadowing, both < masking, shadowing < neither, masking < neither.
_ABLATION_ORDER = (("both", "shadowing"), ("both", "masking"), ("shadowing", "neither"), ("masking", "neither"))


def _ablation_claim(j: _Judge, paper: PaperResults) -> Claim:
    names = {word: ablation_method(*pair) for word, pair in _ABLATION_PAIRS.items()}
    claim = "Shadowing and masking each improve on Ramamoorthi-Hanrahan; both together are best"
    words = ", ".join(f"{word} {fmt_paper(paper.ablation_row(*pair).values['mse'], 2)}"
                      for word, pair in _ABLATION_PAIRS.items())
    text = f"MSE {words} (Table 4)"
    criterion = "; ".join(f"MSE({names[a]}) - MSE({names[b]}) < 0" for a, b in _ABLATION_ORDER)
    if not ran(j.df, *names.values()):
        return Claim(claim, text, MISSING, NOT_RUN, criterion)
    means = {word: j.mean(name, "mse_average") for word, name in names.items()}
    diffs = [j.difference(names[a], names[b], "mse_average") for a, b in _ABLATION_ORDER]
    if None in means.values() or None in diffs:
        return Claim(claim, text, MISSING, NOT_JUDGED, criterion)
    ours = ("MSE " + ", ".join(f"{word} {fmt_interval(m, 3)}" for word, m in means.items()) + "; differences "
            + ", ".join(f"{a} - {b} {fmt_interval(d, 3, sign=True)}" for (a, b), d in zip(_ABLATION_ORDER, diffs)))
    return Claim(claim, text, ours, all_hold(judge(d, "<", 0.0) for d in diffs), criterion)


def _finetune_claim(j: _Judge, paper: PaperResults) -> Claim:
    claim = _versus(j, "Fine-tuning our result with Mitsuba improves on ours",
                    f"PSNR-H {fmt_paper(paper.table5[FINETUNED]['psnr_h'], 2)} vs "
                    f"{fmt_paper(paper.table1[OURS]['psnr_h'], 2)} dB (Tables 1, 5)",
                    "freq+mitsuba", "freq", "psnr_h", ">", 0.0, "PSNR-H", 2,
                    "PSNR-H(freq+mitsuba) - PSNR-H(freq) > 0 (as the paper judges it; MSE beside)", unit=" dB")
    mse = j.difference("freq+mitsuba", "freq", "mse_average")
    if mse is not None and claim.holds != NOT_RUN:
        claim = replace(claim, ours=f"{claim.ours}; MSE difference {fmt_interval(mse, 4, sign=True)}")
    return claim


def _finetune_time_claim(j: _Judge, paper: PaperResults) -> Claim:
    tuned, full = paper.table5[FINETUNED], paper.table5[MITSUBA_FULL]
    divisor = paper.criteria.finetune_time_divisor
    claim = "Ours + Mitsuba beats Mitsuba alone in less than a third of its time"
    text = (f"PSNR-H {fmt_paper(tuned['psnr_h'] - full['psnr_h'], 2, sign=True)} dB, "
            f"{fmt_paper(tuned['time_s'], 2)} s vs {fmt_paper(full['time_s'], 2)} s (Table 5)")
    criterion = (f"PSNR-H(freq+mitsuba) - PSNR-H(mitsuba) > 0 and time(mitsuba) / time(freq+mitsuba) > {divisor:g} "
                 "(geometric mean)")
    psnr = j.difference("freq+mitsuba", "mitsuba", "psnr_h")
    times = (np.log(_time(j, "mitsuba", real=False)) - np.log(_time(j, "freq+mitsuba", real=False))).dropna()
    if not ran(j.df, "freq+mitsuba", "mitsuba"):
        return Claim(claim, text, MISSING, NOT_RUN, criterion)
    if psnr is None or times.empty:
        return Claim(claim, text, MISSING, NOT_JUDGED, criterion)
    ratio = j.interval(times).map(np.exp)
    result = Claim(claim, text, f"PSNR-H {fmt_interval(psnr, 2, sign=True)} dB, {fmt_interval(ratio, 1)}x faster",
                   all_hold([judge(psnr, ">", 0.0), judge(ratio, ">", divisor)]), criterion)
    return result


def _entropy_claim(j: _Judge, paper: PaperResults) -> Claim:
    threshold = paper.min_correlation
    r = {m: j.mean(m, "pearson_entropy_error") for m in ("mitsuba", "freq")}
    text = (f"Pearson {fmt_paper(threshold, 2)} to {fmt_paper(max(v for k, v in paper.correlation.items() if k != AVERAGE), 2)}"
            f", mean {fmt_paper(paper.correlation[AVERAGE], 2)} (Table 2)")
    ours = "; ".join(f"{label} {fmt_interval(r[m], 2)}" for label, m in (("Mitsuba", "mitsuba"), ("freq", "freq"))
                     if r[m] is not None)
    return Claim("Our entropy correlates positively with Mitsuba's per-texel error", text, ours or MISSING,
                 NOT_RUN if r["mitsuba"] is None else judge(r["mitsuba"], ">=", threshold),
                 f"mean Pearson(entropy, Mitsuba's squared parameter error) >= {threshold:.2f} (the paper's "
                 f"smallest; its mean {paper.correlation[AVERAGE]:.2f})")


def _merge_claim(j: _Judge, paper: PaperResults) -> Claim:
    merged = next((m for m, e in METHODS.items() if "table6" in e.paper_rows), None)
    start = METHODS[merged].start if merged else None
    label = paper.table6.get(METHODS[merged].paper_rows["table6"]) if merged else None
    return _versus(j, "Merging captures by entropy beats their average",
                   f"MSE {fmt_paper(label[0], 2)} vs {fmt_paper(paper.table6[MERGE_AVERAGE][0], 2)} (Table 6)"
                   if label else MISSING, merged, start, "mse_average", "<", 0.0, "MSE", 3,
                   f"MSE({merged}) - MSE({start}) < 0, paired per capture, intervals over objects")


def _agreement_claim(j: _Judge, paper: PaperResults) -> Claim:
    row = paper.table3[AGREEMENT_ROWS["spectrum"]]
    threshold = row["pearson"] - row["std"]
    values = capture_metric(j.df, "entropy_agreement_pearson_spectrum")
    angular = capture_metric(j.df, "entropy_agreement_pearson_angular")
    r = j.interval(unit_values(j.df, "", "entropy_agreement_pearson_spectrum")) if len(values) else None
    return Claim(
        "The power-spectrum entropy agrees with the entropy Mitsuba's renders give",
        f"Pearson {fmt_paper(row['pearson'], 2)} \u00b1 {fmt_paper(row['std'], 2)} "
        f"(angular {fmt_paper(paper.table3[AGREEMENT_ROWS['angular']]['pearson'], 2)}, Table 3)",
        f"Pearson {fmt_interval(r, 2)} (angular {fmt(angular.mean() if len(angular) else None, 2)}) "
        f"over {len(values)} capture(s)" if r is not None else MISSING,
        NOT_RUN if r is None else judge(r, ">=", threshold),
        f"mean Pearson(spectrum entropy, Mitsuba grid entropy) >= {threshold:.2f} "
        "(the paper's mean minus its standard deviation)",
    )


def _views_claim(j: _Judge, paper: PaperResults) -> Claim:
    """Per capture, freq's MSE and mean entropy at the fewest views of the sweep less at the most
    (each the mean over its seeded subsets), both > 0 over the captures."""
    claim = "With fewer views, error and entropy rise together"
    sweep = views_sweep(j.df)
    counts = sorted(sweep.views.unique())
    criterion = ("MSE(fewest views) - MSE(most) > 0 and mean entropy(fewest) - mean entropy(most) > 0, freq, "
                 "paired per capture (each the mean over its seeded subsets)")
    if len(counts) < 2:
        return Claim(claim, "MSE and mean entropy both rise as views are dropped (Fig. 8)", MISSING, NOT_RUN, criterion)
    fewest, most = counts[0], counts[-1]
    rises = {name: j.interval((j.values("freq", f"views_{fewest}_{name}") - j.values("freq", f"views_{most}_{name}"))
                              .dropna(), "freq") for name in ("mse_average", "mean_entropy")}
    means = sweep.groupby("views")[["mse_average", "mean_entropy"]].mean()
    ours = (f"{fewest} views: MSE {fmt(means.mse_average[fewest])}, entropy {fmt(means.mean_entropy[fewest], 2)}; "
            f"{most}: {fmt(means.mse_average[most])}, {fmt(means.mean_entropy[most], 2)}; rises "
            f"MSE {fmt_interval(rises['mse_average'], 3, sign=True)}, "
            f"entropy {fmt_interval(rises['mean_entropy'], 2, sign=True)} over {rises['mse_average'].clusters} "
            "capture(s)")
    return Claim(claim, "MSE and mean entropy both rise as views are dropped (Fig. 8)", ours,
                 all_hold(judge(r, ">", 0.0) for r in rises.values()), criterion)


_CLAIMS: tuple[Callable[[_Judge, PaperResults], Claim | None], ...] = (
    _mitsuba_rule(_speed_claim), _speed_real_claim, _speed_order_claim, _mitsuba_rule(_accuracy_claim),
    _mitsuba_rule(_relight_claim), _spectrum_claim, _ablation_claim, _finetune_claim,
    _mitsuba_rule(_finetune_time_claim), _mitsuba_rule(_entropy_claim), _agreement_claim,
    _mitsuba_rule(_merge_claim, by_object=True), _views_claim,
)


def claims(df: pd.DataFrame, paper: PaperResults, context: ClaimContext | None = None) -> pd.DataFrame:
    """The paper's headline claims, its values, ours with their intervals, and the verdicts.

    Criteria (thresholds from ``paper``; every difference paired per capture and test view):

    1. Speed: Mitsuba's time to its converged MSE over freq's time from the capture
       (``speed_ratio_at_mitsuba_converged``, Table 2's comparison), geometric mean >= Table 2's
       33.5x on synthetic captures; the fastest frequency-domain method at least as accurate as
       Mitsuba shown beside it. On real captures Mitsuba's time over freq's (>= Table 1's 13.3x).
    2. Speed order: time(spectrum) < time(freq) < time(mitsuba).
    3. Accuracy: MSE(freq) - MSE(mitsuba) <= the paper's gap (0.02, Table 2).
    4. Relighting: PSNR-H(freq) - PSNR-H(mitsuba) >= -(the paper's gap, 0.08 dB, Table 1).
    5. Spectrum-only is less accurate than the full model.
    6. Ablation order (Table 4): both < each of shadowing and masking alone < neither.
    7. Fine-tuning improves ours: PSNR-H(freq+mitsuba) > PSNR-H(freq), as the paper judges it.
    8. Fine-tuning beats Mitsuba alone in less than a third of its time.
    9. Entropy predicts Mitsuba's error: mean Pearson >= the paper's smallest (0.13).
    10. Entropy agreement (Table 3): mean Pearson >= the paper's 0.89 minus its 0.06.
    11. Merging by entropy beats the average (Table 6).
    12. Views sweep (Fig. 8): freq's MSE and mean entropy both higher at the fewest views than at the most.

    Claims 1, 3, 4, 8, 9 and 11 read Mitsuba's estimate and follow the module's one rule: judged
    on the captures where it converged, ``not judged`` when fewer than half did.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (:func:`freqbrdf.report.tables.tidy.check_tidy`).
    paper : PaperResults
        The paper's numbers, quoted in the ``paper`` column.
    context : ClaimContext, optional
        Intervals' settings, Mitsuba's budget and the real captures; default settings.

    Returns
    -------
    DataFrame of str
        Columns ``claim, paper, ours, holds, criterion``; ``holds`` one of ``yes``, ``no``,
        ``within noise``, ``not judged`` (with the reason in ``ours`` or ``criterion``) and
        ``not run`` (a method it needs did not run).
    """
    j = _Judge(df, context or ClaimContext())
    rows = [asdict(claim) for claim in (make(j, paper) for make in _CLAIMS) if claim is not None]
    return pd.DataFrame(rows, columns=CLAIM_COLUMNS)


def verdict_counts(table: pd.DataFrame) -> dict[str, int]:
    """How many claims got each verdict, in :data:`freqbrdf.report.intervals.VERDICTS` order then ``not run``."""
    counts = table.holds.value_counts()
    return {v: int(counts.get(v, 0)) for v in (YES, NO, NOISE, NOT_JUDGED, NOT_RUN)}
