"""Rule metrics: every number of the benchmark in one tidy CSV (object, env, poses, method, relight_env, metric, value).

Every path comes from ``snakemake.input``; ``snakemake.params`` says what each
input list holds, in the same order (see rules/evaluate.smk).
"""

from concurrent.futures import ThreadPoolExecutor
from functools import cache
from itertools import accumulate
from pathlib import Path

import numpy as np
import pandas as pd

from freqbrdf.artefacts import read_entropy, read_observations, read_posterior_std, read_svbrdf
from freqbrdf.sphere.brdf import TEXTURES, parameter_mse
from freqbrdf.scene.cameras import cameras_from_json
from freqbrdf.util.io import atomic_path, read_exr, read_json, read_views
from freqbrdf.util.logs import run_script
from freqbrdf.methods import FREQUENCY_RULES, METHODS
from freqbrdf.report.metrics import (PARAMETER_COLUMNS, base_color_si_scores, brdf_log_error, is_converged,
                                     last_epoch_change, parameter_error_map, pearson,
                                     texel_parameter_columns, time_to_reach)
from freqbrdf.estimate.optimise.posterior import expected_error
from freqbrdf.report.sparsification import (baseline_maps, partial_pearson, reliability,
                                             sparsification_curves, uncertainty_scores)
from freqbrdf.report.tables.tidy import TIDY_COLUMNS
from freqbrdf.report.relight_metrics import RELIGHT_METRICS, HdrScoring, relight_view_scores, scored_pixels

COLUMNS = list(TIDY_COLUMNS)
COVERAGE_LEVEL = 0.9  # coverage90_* in metrics.csv: one of the reliability diagram's levels


def keyed(keys, paths, per=1):
    """``{key: path}`` (or ``{key: [paths]}`` with ``per`` > 1) of an input list in the order of ``keys``."""
    if len(paths) != per * len(keys):
        raise ValueError(f"metrics: {len(paths)} input paths for {len(keys)} keys x {per}")
    return {tuple(k): (paths[i * per] if per == 1 else list(paths[i * per : (i + 1) * per])) for i, k in enumerate(keys)}


def parameter_rows(smk):
    """mse_*, brdf_log_rmse and base_color_si_{psnr,ssim} of every method on every synthetic capture;
    for the entropy-scored methods, pearson_entropy_error, partial_pearson_entropy_error_views and
    ause_<map>_<error> (the entropy and the trivial baselines against the parameter and BRDF errors);
    mean_entropy (over observed texels) of each capture. Also the sparsification curves behind the AUSE."""
    p = smk.params
    truth_files = keyed([(o,) for o in p.objects], smk.input.truth, per=len(TEXTURES))
    truth = cache(lambda o: read_svbrdf(dict(zip(TEXTURES, truth_files[(o,)]))))
    captures = keyed(p.captures, smk.input.observations)
    entropies = keyed(p.captures, smk.input.entropy)
    observations = cache(lambda key: read_observations(captures[key]))
    scored = cache(lambda key: (lambda obs: obs.texels.texel[obs.observed])(observations(key)))
    entropy_atlas = cache(lambda key: read_entropy(entropies[key]).atlas.ravel())
    rows = []
    for obj, env, poses in p.captures:
        entropy = entropy_atlas((obj, env, poses))[scored((obj, env, poses))]
        rows.append(dict(object=obj, env=env, poses=poses, method="", relight_env="", metric="mean_entropy",
                         value=float(entropy.mean())))
    baselines = cache(lambda key: baseline_maps(observations(key)))
    estimates = keyed(p.synthetic, smk.input.estimates)
    for obj in {o for o, _, _ in p.captures}:  # read here, once, rather than by each thread that needs it
        truth(obj)

    def score_brdf(item):
        """The estimate and its BRDF error per scored texel."""
        (obj, env, poses, _), directory = item
        estimate = read_svbrdf(directory)
        return estimate, brdf_log_error(truth(obj), estimate, scored((obj, env, poses)))

    # most of the rule's time; NumPy releases the GIL in the large array operations
    with ThreadPoolExecutor(smk.threads) as pool:
        scored_estimates = list(pool.map(score_brdf, estimates.items()))
    curves, calibration = [], []
    for ((obj, env, poses, method), directory), (estimate, brdf_error) in zip(estimates.items(), scored_estimates):
        texels = scored((obj, env, poses))
        key = dict(object=obj, env=env, poses=poses, method=method, relight_env="")
        rows += [key | dict(metric=f"mse_{k}", value=v) for k, v in parameter_mse(truth(obj), estimate, texels).items()]
        rows.append(key | dict(metric="brdf_log_rmse", value=float(np.sqrt(brdf_error.mean()))))
        scaled = base_color_si_scores(truth(obj).base_color, estimate.base_color, texels)
        rows += [key | dict(metric=f"base_color_si_{k}", value=v) for k, v in scaled.items()]
        if method in p.entropy_methods:
            entropy = entropy_atlas((obj, env, poses))[texels]
            error = parameter_error_map(truth(obj), estimate).ravel()[texels]
            views = baselines((obj, env, poses))["views"]
            rows.append(key | dict(metric="pearson_entropy_error", value=pearson(entropy, error)))
            rows.append(key | dict(metric="partial_pearson_entropy_error_views", value=partial_pearson(entropy, error, views)))
            maps = {"entropy": entropy, **baselines((obj, env, poses))}
            if METHODS[method].has_posterior:
                posterior, coverage, levels = posterior_rows(directory, truth(obj), estimate, texels,
                                                             p.metrics["interval_widths"])
                maps["posterior"] = posterior
                rows.append(key | dict(metric="mean_posterior_error", value=float(posterior.mean())))
                rows.append(key | dict(metric="partial_pearson_posterior_error_views",
                                       value=partial_pearson(posterior, error, views)))
                rows += [key | dict(metric=f"coverage90_{name}", value=value) for name, value in coverage.items()]
                calibration += [dict(object=obj, env=env, poses=poses, method=method, parameter=name, level=level,
                                     coverage=value) for name, shares in levels.items() for level, value in shares.items()]
            errors = {"parameter": error, "brdf": brdf_error}
            rows += [key | dict(metric=name, value=value) for name, value in uncertainty_scores(maps, errors).items()]
            curves += [dict(object=obj, env=env, poses=poses, method=method) | record
                       for record in sparsification_curves(maps, errors)]
    return rows, curves, calibration


def posterior_rows(directory, truth, estimate, texels, widths=None):
    """The expected squared parameter error of each scored texel under its fit's posterior, and per
    texture and over all (``all``) the coverage of its central intervals at each level of the
    reliability diagram (`reliability`), 90% among them; ``widths``: config ``evaluate.interval_widths``."""
    est, tru, std = (texel_parameter_columns(a, texels) for a in (estimate, truth, read_posterior_std(directory)))
    per_column = None
    if widths is not None:  # (levels, 5): each parameter column its texture's widths
        per_column = np.column_stack([widths[g] for g, c in PARAMETER_COLUMNS.items() for _ in range(c.start, c.stop)])
    columns = dict(PARAMETER_COLUMNS, all=slice(None))
    levels = {g: reliability(est[:, c], tru[:, c], std[:, c], None if per_column is None else per_column[:, c])
              for g, c in columns.items()}
    return expected_error(std**2), {g: shares[COVERAGE_LEVEL] for g, shares in levels.items()}, levels


def reference_views(test, min_coverage):
    """Reference test views of a capture directory: names, images and scored-pixel masks."""
    cameras = cameras_from_json(read_json(f"{test}/cameras.json"), f"{test}/cameras.json")
    images, coverage, nonfinite = read_views(test, cameras.names, cameras.width, cameras.height)
    if nonfinite:
        raise ValueError(f"{test}: {nonfinite} NaN/Inf pixel values in the reference views")
    return cameras.names, list(images), [scored_pixels(c, min_coverage) for c in coverage]


def relight_rows(smk, log):
    """psnr_h, psnr_l, ssim, mse of every relit image set: each test view's (``view`` set), and their
    mean over the views (``view`` empty)."""
    settings = smk.params.metrics
    references = {key: reference_views(test, settings["mask_min_coverage"])
                  for key, test in keyed(smk.params.references, smk.input.references).items()}
    sets = keyed(smk.params.relights, smk.input.relit)
    scoring = HdrScoring.from_config(settings)

    def score_relit(item):
        (obj, *_, relight_env), relit = item
        names, refs, masks = references[(obj, relight_env)]
        preds = [read_exr(f"{relit}/{relight_env}/images/{name}.exr") for name in names]
        return names, relight_view_scores(preds, refs, masks, scoring)

    # SciPy's filters under the SSIM release the GIL
    with ThreadPoolExecutor(smk.threads) as pool:
        per_set = list(pool.map(score_relit, sets.items()))
    rows = []
    for (obj, env, poses, method, relight_env), (names, per_view) in zip(sets, per_set):
        key = dict(object=obj, env=env, poses=poses, method=method, relight_env=relight_env)
        rows += [key | dict(view="", metric=k, value=float(np.mean([v[k] for v in per_view])))
                 for k in RELIGHT_METRICS]
        rows += [key | dict(view=name, metric=k, value=v) for name, scores in zip(names, per_view)
                 for k, v in scores.items()]
    log.info("scored %d relit image sets", len(smk.params.relights))
    return rows


def benchmark(path):
    """Wall-clock seconds and peak resident memory (MB) of one Snakemake benchmark file."""
    table = pd.read_csv(path, sep="\t")
    return float(table["s"].mean()), float(pd.to_numeric(table["max_rss"], errors="coerce").max())


def timing_rows(smk):
    """time_s and max_rss_mb of each method's own job, time_total_s of everything it needs
    after the observations, and speed_ratio_vs_mitsuba (mitsuba's total / the method's)."""
    counts = [n for *_, n in smk.params.timings]
    ends = list(accumulate(counts))
    if ends and ends[-1] != len(smk.input.benchmarks):
        raise ValueError(f"metrics: {len(smk.input.benchmarks)} benchmark inputs, params.timings lists {ends[-1]}")
    rows, totals = [], {}
    for (obj, env, poses, method, n), end in zip(smk.params.timings, ends):
        runs = [benchmark(f) for f in smk.input.benchmarks[end - n : end]]
        seconds, rss = runs[-1]  # the method's own rule is listed last
        totals[obj, env, poses, method] = sum(s for s, _ in runs)
        key = dict(object=obj, env=env, poses=poses, method=method, relight_env="")
        rows += [key | dict(metric="time_s", value=seconds), key | dict(metric="max_rss_mb", value=rss),
                 key | dict(metric="time_total_s", value=totals[obj, env, poses, method])]
    for (obj, env, poses, method), total in totals.items():
        mitsuba = totals.get((obj, env, poses, "mitsuba"))
        if mitsuba is not None:
            rows.append(dict(object=obj, env=env, poses=poses, method=method, relight_env="",
                             metric="speed_ratio_vs_mitsuba", value=mitsuba / total))
    return rows


def equal_accuracy_rows(smk, rows, log):
    """Per synthetic capture, for every method that needs the observations: how long
    ``mitsuba`` (its logged MSE curve, optimisation time only) takes to reach the method's
    parameter MSE (``mitsuba_time_to_match_s``, NaN if never within its budget), and that
    time over the method's whole path from the capture (``speed_ratio_equal_accuracy``:
    observation extraction plus ``time_total_s``). When mitsuba never gets there, the ratio
    is its whole budget over the path, a lower bound, and ``mitsuba_reached`` is 0. For
    ``mitsuba`` itself: ``mitsuba_last_epoch_change``, the relative fall of its MSE over its last
    epoch, ``mitsuba_converged``, 1 when that is under 1% at a constant learning rate, and
    ``mitsuba_time_to_converge_s``, when its MSE first came within 1% of its final value. The
    paper's Table 2 ratio, each run to its own result: ``speed_ratio_at_mitsuba_converged`` = that
    time over the method's path, whatever the method's MSE. The other ratio of the time-accuracy
    front, at Mitsuba's accuracy: for every method that reaches Mitsuba's final MSE,
    ``speed_ratio_at_mitsuba_accuracy`` = the same ratio (NaN for a method above Mitsuba's MSE);
    the front's ratio is the largest over the methods."""
    value = {(r["object"], r["env"], r["poses"], r["method"], r["metric"]): r["value"] for r in rows}
    extraction = {key: benchmark(path)[0] for key, path in keyed(smk.params.captures, smk.input.extraction).items()}
    estimates = keyed(smk.params.synthetic, smk.input.estimates)
    out = []
    for (obj, env, poses), extract_s in extraction.items():
        if (obj, env, poses, "mitsuba") not in estimates:
            continue
        curve_file = Path(estimates[obj, env, poses, "mitsuba"]) / "mse_curve.tsv"
        if not curve_file.is_file():
            raise FileNotFoundError(f"{curve_file}: no MSE curve (rerun rule mitsuba for this capture)")
        curve = pd.read_csv(curve_file, sep="\t")
        change = last_epoch_change(curve.mse_average.to_numpy())
        final = float(curve.mse_average.iloc[-1])
        converge = time_to_reach(curve.elapsed_s.to_numpy(), curve.mse_average.to_numpy(), 1.01 * final)
        key = dict(object=obj, env=env, poses=poses, method="mitsuba", relight_env="")
        out += [key | dict(metric="mitsuba_last_epoch_change", value=change),
                key | dict(metric="mitsuba_converged", value=float(is_converged(curve.mse_average, smk.params.lr_decay))),
                key | dict(metric="mitsuba_time_to_converge_s", value=converge)]
        for method in (m for m in smk.params.methods if METHODS[m].rule in FREQUENCY_RULES):
            target, total = value.get((obj, env, poses, method, "mse_average")), value.get((obj, env, poses, method, "time_total_s"))
            if target is None or total is None:
                continue
            reach = time_to_reach(curve.elapsed_s.to_numpy(), curve.mse_average.to_numpy(), target)
            reached = reach == reach  # not NaN
            ratio = (reach if reached else float(curve.elapsed_s.iloc[-1])) / (extract_s + total)
            at_converged = converge / (extract_s + total)
            at_mitsuba = at_converged if target <= final else float("nan")
            key = dict(object=obj, env=env, poses=poses, method=method, relight_env="")
            out += [key | dict(metric="mitsuba_time_to_match_s", value=reach),
                    key | dict(metric="mitsuba_reached", value=float(reached)),
                    key | dict(metric="speed_ratio_equal_accuracy", value=ratio),
                    key | dict(metric="speed_ratio_at_mitsuba_converged", value=at_converged),
                    key | dict(metric="speed_ratio_at_mitsuba_accuracy", value=at_mitsuba)]
            if method == "freq":
                log.info("%s/%s: mitsuba reaches freq's MSE %.4f %s; equal-accuracy ratio %s%.1fx", obj, env, target,
                         f"after {reach:.1f} s" if reached else "never", "" if reached else ">= ", ratio)
    return out


def views_rows(smk):
    """views_<k>_mse_average and views_<k>_mean_entropy of freq on each views-sweep capture, per
    count k: the means over its seeded subsets."""
    rows = []
    for (obj, env, poses), table in keyed(smk.params.views, smk.input.views).items():
        key = dict(object=obj, env=env, poses=poses, method="freq", relight_env="")
        means = pd.read_csv(table, sep="\t").groupby("views", as_index=False)[["mse_average", "mean_entropy"]].mean()
        for r in means.itertuples():
            rows += [key | dict(metric=f"views_{r.views}_mse_average", value=r.mse_average),
                     key | dict(metric=f"views_{r.views}_mean_entropy", value=r.mean_entropy)]
    return rows


def agreement_rows(smk):
    """entropy_agreement_<key> for every key of each scored capture's agreement.json (paper Table 3:
    Pearson correlations with the Mitsuba grid's entropy, times, settings); rows of the capture,
    with an empty method."""
    rows = []
    for (obj, env, poses), summary in keyed(smk.params.agreement, smk.input.agreement).items():
        key = dict(object=obj, env=env, poses=poses, method="", relight_env="")
        result = read_json(summary)
        rows += [key | dict(metric=f"entropy_agreement_{name}", value=value) for name, value in result.items()]
    return rows


def main(smk, log):
    rows, curves, calibration = parameter_rows(smk)
    rows += relight_rows(smk, log) + timing_rows(smk)
    rows += equal_accuracy_rows(smk, rows, log) + views_rows(smk) + agreement_rows(smk)
    table = pd.DataFrame(rows, columns=COLUMNS)
    with atomic_path(smk.output.metrics) as tmp:
        table.to_csv(tmp, index=False, float_format="%.6g")
    with atomic_path(smk.output.sparsification) as tmp:
        pd.DataFrame(curves, columns=["object", "env", "poses", "method", "error", "map", "fraction", "value"]).to_csv(
            tmp, sep="\t", index=False, float_format="%.6g")
    with atomic_path(smk.output.reliability) as tmp:
        pd.DataFrame(calibration, columns=["object", "env", "poses", "method", "parameter", "level", "coverage"]).to_csv(
            tmp, sep="\t", index=False, float_format="%.6g")
    summary = table[table.metric.isin(["mse_average", "psnr_h", "time_total_s"]) & table.view.fillna("").eq("")]
    log.info("means over captures (and relight environments):\n%s",
             summary.pivot_table(index="method", columns="metric", values="value").to_string(float_format=lambda v: f"{v:.3f}"))


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
