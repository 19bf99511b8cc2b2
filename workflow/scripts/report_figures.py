"""Rules capture_figure, relight_figure, convergence_figure and regulariser_figure: per-capture figures of the report."""

import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from freqbrdf.artefacts import read_entropy, read_observations, read_svbrdf
from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.report.figures import atlas_masks, capture_maps_figure, convergence_figure, regulariser_figure, relight_figure
from freqbrdf.scene.cameras import cameras_from_json
from freqbrdf.util.io import atomic_path, read_exr, read_json, read_views
from freqbrdf.report.relight_metrics import scored_pixels
from freqbrdf.util.logs import run_script
from freqbrdf.capture.observations import band_limited_envmap, sample_equirect
from freqbrdf.estimate.shfit import FIT_OPTIONS, fit_option, mirror_directions, spectrum_log_ratio


def maps(smk, log):
    obs = read_observations(smk.input.observations)
    entropy = read_entropy(smk.input.entropy).atlas
    inside, seen = atlas_masks(entropy.shape[0], obs.texels.texel, obs.observed)
    truth = read_svbrdf(dict(zip(TEXTURES, smk.input.truth))) if smk.input.truth else None
    estimates = {method: read_svbrdf(d) for method, d in zip(smk.params.methods, smk.input.estimates)}
    w = smk.wildcards
    mse = capture_maps_figure(smk.output[0], truth, estimates, entropy, inside, seen,
                              f"{w.object} captured under {w.env} ({w.poses} poses): "
                              f"{int(seen.sum())} of {int(inside.sum())} atlas texels observed")
    log.info("parameter MSE over observed texels: %s", ", ".join(f"{m} {v:.4f}" for m, v in mse.items()))


def first_view(test: Path, min_coverage: float) -> tuple[str, np.ndarray, np.ndarray]:
    """Name, linear image and scored pixels (as metrics scores them) of a test capture's first view."""
    cameras = cameras_from_json(read_json(test / "cameras.json"), f"{test}/cameras.json")
    images, coverage, _ = read_views(test, cameras.names[:1], cameras.width, cameras.height)
    return cameras.names[0], images[0], scored_pixels(coverage[0], min_coverage)


def relight(smk, log):
    w = smk.wildcards
    settings = smk.params.metrics
    references, names = {}, {}
    for relight_env, test in zip(smk.params.references, smk.input.references):
        names[relight_env], image, mask = first_view(Path(test), settings["mask_min_coverage"])
        references[relight_env] = (image, mask)
    relit = {}
    for (method, relight_env), directory in zip(smk.params.relights, smk.input.relit):
        view = Path(directory) / relight_env / "images" / f"{names[relight_env]}.exr"
        relit.setdefault(relight_env, {})[method] = read_exr(view)
    scores = relight_figure(smk.output[0], references, relit,
                            f"{w.object} captured under {w.env}: the first test view relit under held-out environments",
                            clip=settings["hdr_clip"], normalise=settings["hdr_normalise"])
    log.info("PSNR-H of the first test view: %s",
             ", ".join(f"{m} under {r} {v:.2f}" for (r, m), v in scores.items()) or "no relighting")


def convergence(smk, log):
    w = smk.wildcards
    metrics = pd.read_csv(smk.input.metrics, keep_default_na=False, na_values=[""])
    rows = metrics[(metrics.object == w.object) & (metrics.env == w.env) & (metrics.poses == w.poses)]
    value = {(m, k): float(v) for m, k, v in zip(rows.method, rows.metric, rows.value)}
    extract_s = pd.read_csv(smk.input.extraction, sep="\t")["s"].mean()
    # one-shot methods at their whole time from the capture (extraction included)
    points = {m: (extract_s + value[m, "time_total_s"], value[m, "mse_average"]) for m in smk.params.points
              if (m, "time_total_s") in value and (m, "mse_average") in value}
    curves = {}
    for method, start, directory in zip(smk.params.curves, smk.params.starts, smk.input.curves):
        curve = pd.read_csv(Path(directory) / "mse_curve.tsv", sep="\t")
        offset = points[start][0] if start in points else 0.0  # a fine-tuning run starts after its start method
        curves[method] = (offset + curve.elapsed_s.to_numpy(), curve.mse_average.to_numpy())
    convergence_figure(smk.output[0], curves, points, f"{w.object} captured under {w.env}: parameter MSE against time")
    log.info("convergence of %s; one-shot %s", ", ".join(curves), ", ".join(points))


def regulariser(smk, log):
    """Paper Fig. 3 on this capture's own sampling: the light and the light filtered by a
    known lobe, sampled along the mirror directions of a seeded set of observed texels and
    fitted with each option; the error of log(S_B / S_L) against the lobe's -2 (alpha l)^2."""
    obs = read_observations(smk.input.observations)
    envmap, alpha, sh = read_exr(smk.input.envmap), smk.params.alpha, smk.params.sh
    rng = np.random.default_rng(smk.params.seed)
    observed = np.nonzero(obs.observed)[0]
    pick = np.sort(rng.choice(observed, min(smk.params.texels, len(observed)), replace=False))
    local = mirror_directions(np.asarray(obs.wo_local[pick]))
    world = np.einsum("tji,tkj->tki", obs.frame[pick], local)
    weights = np.asarray(obs.weight[pick])
    # the light as extracted (pre-filtered by a'), and the same light under a lobe of width alpha
    light, lobe = (sample_equirect(band_limited_envmap(envmap, width), world)
                   for width in (obs.a_prime, np.hypot(obs.a_prime, alpha)))
    expected = -2.0 * (alpha * np.arange(1, sh["lmax"] + 1)) ** 2
    errors = {}
    with warnings.catch_warnings():  # texels whose fit has no power at a degree: NaN, skipped
        warnings.simplefilter("ignore", RuntimeWarning)
        for option in FIT_OPTIONS:
            b, l = (fit_option(option, local, values, weights, sh["lmax"], sh["lambda"], sh["penalise_dc"])
                    for values in (lobe, light))
            errors[option] = np.nanmean(spectrum_log_ratio(b, l), axis=-1) - expected
        rows = [{"option": o, "degree": l + 1, "median": np.nanmedian(e[:, l]),
                 "q25": np.nanpercentile(e[:, l], 25), "q75": np.nanpercentile(e[:, l], 75),
                 "mean_abs": np.nanmean(np.abs(e[:, l]))} for o, e in errors.items() for l in range(e.shape[1])]
    with atomic_path(smk.output.table) as tmp:
        pd.DataFrame(rows).to_csv(tmp, sep="\t", index=False, float_format="%.4g")
    w = smk.wildcards
    regulariser_figure(smk.output.figure, errors, f"{w.object} / {w.env}: {len(pick)} texels' own samples, "
                       f"a lobe of alpha {alpha:g}")
    log.info("mean |error of log(S_B/S_L)| over degrees 1..%d: %s", sh["lmax"],
             ", ".join(f"{o} {np.nanmean(np.abs(e)):.2f}" for o, e in errors.items()))


RULES = {"capture_figure": maps, "relight_figure": relight, "convergence_figure": convergence,
         "regulariser_figure": regulariser}
run_script(RULES[snakemake.rule], snakemake)  # noqa: F821 (injected by Snakemake)
