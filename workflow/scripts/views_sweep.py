"""Rule views_sweep: freq's parameter MSE and the mean entropy of one capture with seeded
random subsets of its training views, several per count (paper Fig. 8)."""

import time

import numpy as np
import pandas as pd

from freqbrdf.artefacts import Svbrdf, read_observations, read_svbrdf
from freqbrdf.sphere.brdf import TEXTURES, parameter_mse
from freqbrdf.report.figures import views_figure
from freqbrdf.util.io import atomic_path, read_exr
from freqbrdf.util.logs import run_script
from freqbrdf.estimate.light_table import read_light_table
from freqbrdf.estimate.optimise.model import estimate_light
from freqbrdf.estimate.optimise.settings import OptimiseSettings
from freqbrdf.studies.views import estimate_subset, view_subsets


def main(smk, log):
    obs = read_observations(smk.input.observations)
    envmap = read_exr(smk.input.envmap)
    truth = read_svbrdf(dict(zip(TEXTURES, smk.input.truth)))
    p = smk.params
    settings = OptimiseSettings.from_config(p.optimise, workers=smk.threads)
    light, e = estimate_light(envmap, obs, "freq", p.optimise["lmax"], p.optimise["point_sources"])
    table = (read_light_table(smk.input.light_table, light, settings.light_table)
             if "light_table" in smk.input.keys() else None)  # one table for every subset
    rows = []
    subsets = view_subsets(len(obs.meta["views"]), p.counts, p.seed, p.subsets)
    for subset, views in ((k, v) for draws in subsets.values() for k, v in enumerate(draws)):
        start = time.perf_counter()
        sub, search, estimate = estimate_subset(obs, views, envmap, p.band_limit, p.sh, p.spectrum, settings, light,
                                                e, smk.threads, table)
        texels = sub.texels
        scored = texels.texel[sub.observed]
        mse = parameter_mse(truth, Svbrdf.from_texels(texels.resolution, texels.texel, estimate, sub.observed), scored)
        known = sub.observed & ~search.unobserved
        rows.append({"views": len(views), "subset": subset, "observed_texels": int(sub.observed.sum()),
                     "mean_entropy": float(search.entropy[known].mean()),
                     **{f"mse_{k}": v for k, v in mse.items()}, "seconds": time.perf_counter() - start})
        log.info("%d views (subset %d): %d texels observed, MSE %.4f, mean entropy %.3f (%.1f s)", len(views), subset,
                 rows[-1]["observed_texels"], mse["average"], rows[-1]["mean_entropy"], rows[-1]["seconds"])
    table = pd.DataFrame(rows)
    with atomic_path(smk.output.table) as f:
        table.to_csv(f, sep="\t", index=False, float_format="%.6g")
    w = smk.wildcards
    views_figure(smk.output.figure, table, f"{w.object} / {w.env}: freq with fewer training views")
    if len(table) > 1:
        log.info("Pearson correlation of MSE and mean entropy over %d subsets: %.2f", len(table),
                 np.corrcoef(table.mse_average, table.mean_entropy)[0, 1])


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
