"""Rule metrics: every number of the benchmark in one tidy CSV (object, env, poses, method, relight_env, metric, value)."""

from functools import cache
from pathlib import Path

import numpy as np
import pandas as pd

from freqbrdf.cameras import cameras_from_json
from freqbrdf.io import atomic_path, read_exr, read_json, read_svbrdf_dir, read_views
from freqbrdf.logs import run_script
from freqbrdf.metrics import parameter_error_map, parameter_mse, pearson, relight_scores
from freqbrdf.spectral import observed_texels

COLUMNS = ["object", "env", "poses", "method", "relight_env", "metric", "value"]


@cache
def _truth(obj):
    """Ground-truth textures of an object (read once, shared by its captures and methods)."""
    return read_svbrdf_dir(f"results/objects/{obj}")


@cache
def _scored_texels(obj, env, poses):
    """Flat atlas indices of the texels some training view observes (what parameter MSE scores)."""
    obs = Path(f"results/observations/{obj}/{env}/{poses}")
    texel = np.load(obs / "texels.npz")["texel"]
    return texel[observed_texels(np.load(obs / "weight.npy", mmap_mode="r"))]


def parameter_rows(synthetic, entropy_methods):
    """mse_* of every method on every synthetic capture; pearson_entropy_error of the entropy methods."""
    rows = []
    for obj, env, poses, method in synthetic:
        truth = _truth(obj)
        estimate = read_svbrdf_dir(f"results/estimates/{obj}/{env}/{poses}/{method}")
        texels = _scored_texels(obj, env, poses)
        key = dict(object=obj, env=env, poses=poses, method=method, relight_env="")
        rows += [key | dict(metric=f"mse_{k}", value=v) for k, v in parameter_mse(truth, estimate, texels).items()]
        if method in entropy_methods:
            entropy = read_exr(f"results/entropy/{obj}/{env}/{poses}/entropy.exr").ravel()
            error = parameter_error_map(truth, estimate).ravel()
            rows.append(key | dict(metric="pearson_entropy_error", value=pearson(entropy[texels], error[texels])))
    return rows


@cache
def _reference(obj, relight_env, min_coverage):
    """Reference test views of an object under an environment, their names and scored-pixel masks."""
    test = Path(f"results/captures/{obj}/{relight_env}/test")
    cameras = cameras_from_json(read_json(test / "cameras.json"), test / "cameras.json")
    images, coverage, nonfinite = read_views(test, cameras.names, cameras.width, cameras.height)
    if nonfinite:
        raise ValueError(f"{test}: {nonfinite} NaN/Inf pixel values in the reference views")
    return cameras.names, list(images), list(coverage >= min_coverage - 1e-6)  # PNG quantisation: 255 / 255


def relight_rows(relights, settings, log):
    """psnr_h, psnr_l, ssim, mse (means over the test views) of every relit image set."""
    rows = []
    for obj, env, poses, method, relight_env in relights:
        names, refs, masks = _reference(obj, relight_env, settings["mask_min_coverage"])
        relit = Path(f"results/relight/{obj}/{env}/{poses}/{method}/{relight_env}")
        preds = [read_exr(relit / "images" / f"{name}.exr") for name in names]
        scores = relight_scores(preds, refs, masks, clip=settings["hdr_clip"], normalise=settings["hdr_normalise"])
        key = dict(object=obj, env=env, poses=poses, method=method, relight_env=relight_env)
        rows += [key | dict(metric=k, value=v) for k, v in scores.items()]
    log.info("scored %d relit image sets", len(relights))
    return rows


def _benchmark(path):
    """Wall-clock seconds and peak resident memory (MB) of one Snakemake benchmark file."""
    table = pd.read_csv(path, sep="\t")
    return float(table["s"].mean()), float(pd.to_numeric(table["max_rss"], errors="coerce").max())


def timing_rows(timings):
    """time_s and max_rss_mb of each method's own job, time_total_s of everything it needs
    after the observations, and speed_ratio_vs_mitsuba (mitsuba's total / the method's)."""
    rows, totals = [], {}
    for obj, env, poses, method, files in timings:
        runs = [_benchmark(f) for f in files]
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


def main(smk, log):
    p = smk.params
    rows = parameter_rows(p.synthetic, p.entropy_methods) + relight_rows(p.relights, p.metrics, log) + timing_rows(p.timings)
    table = pd.DataFrame(rows, columns=COLUMNS)
    with atomic_path(smk.output[0]) as tmp:
        table.to_csv(tmp, index=False, float_format="%.6g")
    summary = table[table.metric.isin(["mse_average", "psnr_h", "time_total_s"])]
    log.info("means over captures (and relight environments):\n%s",
             summary.pivot_table(index="method", columns="metric", values="value").to_string(float_format=lambda v: f"{v:.3f}"))


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
