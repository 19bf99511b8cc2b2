"""Rule view_selection_sweep: freq's parameter MSE with k training views chosen by expected
entropy, by the error a pilot fit's posterior expects, at random and evenly spread, at equal k."""

import time
from pathlib import Path

import numpy as np
import pandas as pd

from freqbrdf.artefacts import Observations, Svbrdf, read_observations, read_svbrdf, sample_texels
from freqbrdf.sphere.brdf import TEXTURES, parameter_mse
from freqbrdf.scene.cameras import cameras_from_json
from freqbrdf.util.io import atomic_path, read_exr, read_json
from freqbrdf.util.logs import run_script
from freqbrdf.capture.observations import band_limit_parameter, band_limited_envmap
from freqbrdf.estimate.light_table import read_light_table
from freqbrdf.estimate.optimise.model import estimate_light
from freqbrdf.estimate.optimise.settings import OptimiseSettings
from freqbrdf.studies.view_selection import (
    SelectionModel,
    farthest_views,
    greedy_selection,
    set_threads,
)
from freqbrdf.studies.candidates import capture_views
from freqbrdf.studies.posterior_selection import capture_information, greedy_posterior_selection
from freqbrdf.studies.views import estimate_subset, view_subsets


def posterior_setup(smk, obs, envmap, texels, directions, fit_setup, log):
    """The pilot's views (``pilot_views`` evenly spread) and the information every view would add
    to the sampled texels' posterior at the pilot's estimate, their images unread; with seconds
    taken. Shared by every k: each k's greedy choice (`subsets`) starts from it."""
    p = smk.params
    settings, light, e, table = fit_setup
    start = time.perf_counter()
    pilot = farthest_views(directions, p.settings["pilot_views"])
    _, _, estimate = estimate_subset(obs, pilot, envmap, p.band_limit, p.sh, p.spectrum, settings, light, e,
                                     smk.threads, table)
    sample = Observations(obs.texels.subset(texels), *(np.asarray(a)[texels] for a in
                                                        (obs.radiance, obs.weight, obs.wo_local, obs.incoming)),
                          obs.meta)
    information = capture_information(sample, pilot, {name: v[texels] for name, v in estimate.items()}, light,
                                      e[texels], settings, table=table)
    seconds = time.perf_counter() - start
    log.info("posterior-guided selection: pilot views %s fitted and every view's information in %.1f s",
             pilot.tolist(), seconds)
    return pilot, information, seconds


def subsets(smk, obs, envmap, texels, directions, k, posterior, log):
    """The k views of each strategy: (strategy, repetition) -> (view indices, seconds to choose);
    ``posterior``: `posterior_setup`'s result, or None; its rows' seconds are the pilot's and
    the greedy choice's at this k."""
    p = smk.params
    a_prime = band_limit_parameter(k, p.band_limit)
    start = time.perf_counter()
    pool = capture_views(obs, texels, band_limited_envmap(envmap, a_prime))
    model = SelectionModel.from_config(p.sh, p.spectrum, a_prime, p.settings["posterior_min_views"])
    picks, rankings = greedy_selection(model, pool, k)
    out = {("entropy", 0): (np.array(picks), time.perf_counter() - start)}
    log.info("k = %d: entropy-guided views %s, expected mean entropy %.3f (%.1f s)", k, picks,
             rankings[-1].current, out[("entropy", 0)][1])
    start = time.perf_counter()
    out[("even", 0)] = (farthest_views(directions, k), time.perf_counter() - start)
    if posterior is not None and len(posterior[0]) < k < len(directions):
        pilot, information, setup_seconds = posterior
        start = time.perf_counter()
        picks, errors = greedy_posterior_selection(information, k, chosen=pilot.tolist())
        out[("posterior", 0)] = (np.sort(np.concatenate([pilot, picks])), setup_seconds + time.perf_counter() - start)
        log.info("k = %d: posterior-guided views %s after the pilot's, mean expected error %.4f -> %.4f", k, picks,
                 errors[0], errors[-1])
    for i, seed in enumerate(p.seeds):
        start = time.perf_counter()
        out[("random", i)] = (view_subsets(len(directions), [k], seed)[k][0], time.perf_counter() - start)
    return out


def main(smk, log):
    set_threads(smk.threads)
    obs = read_observations(smk.input.observations)
    envmap = read_exr(smk.input.envmap)
    truth = read_svbrdf(dict(zip(TEXTURES, smk.input.truth)))
    cameras_file = Path(smk.input.poses) / "cameras.json"
    cameras = cameras_from_json(read_json(cameras_file), source=cameras_file)
    if list(cameras.names) != list(obs.meta["views"]):
        raise ValueError(f"{cameras_file}: views {cameras.names} are not the observations' {obs.meta['views']}")
    p = smk.params
    settings = OptimiseSettings.from_config(p.optimise, workers=smk.threads)
    light, e = estimate_light(envmap, obs, "freq", p.optimise["lmax"], p.optimise["point_sources"])
    table = (read_light_table(smk.input.light_table, light, settings.light_table)
             if "light_table" in smk.input.keys() else None)  # one table for every subset
    texels = sample_texels(np.arange(len(obs.texels)), p.settings["texels"], p.texel_seed)
    seen = obs.observed
    centre = obs.texels.position[seen].mean(axis=0)
    directions = cameras.centres - centre
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    n_views, scored = len(directions), obs.texels.texel[seen]
    done, rows = {}, []
    counts = sorted({min(int(c), n_views) for c in p.settings["sweep_counts"]})
    guided = [k for k in counts if p.settings["pilot_views"] < k < n_views]
    posterior = posterior_setup(smk, obs, envmap, texels, directions, (settings, light, e, table), log) if guided else None
    for k in counts:
        for (strategy, rep), (views, choose_s) in subsets(smk, obs, envmap, texels, directions, k, posterior,
                                                          log).items():
            key = tuple(sorted(views.tolist()))
            if key not in done:  # e.g. k = every view: one estimate for every strategy
                start = time.perf_counter()
                sub, search, estimate = estimate_subset(obs, views, envmap, p.band_limit, p.sh, p.spectrum, settings,
                                                        light, e, smk.threads, table)
                textures = Svbrdf.from_texels(obs.texels.resolution, obs.texels.texel, estimate, sub.observed)
                done[key] = {"observed_texels": int(sub.observed.sum()),
                             "mean_entropy": float(search.entropy[seen].mean()),
                             **{f"mse_{n}": v for n, v in parameter_mse(truth, textures, scored).items()},
                             "estimate_seconds": time.perf_counter() - start}
            rows.append({"strategy": strategy, "repetition": rep, "views": k, **done[key],
                         "select_seconds": choose_s, "view_names": " ".join(obs.meta["views"][v] for v in views)})
            log.info("k = %d, %s %d: MSE %.4f, mean entropy %.3f, %d texels observed", k, strategy, rep,
                     rows[-1]["mse_average"], rows[-1]["mean_entropy"], rows[-1]["observed_texels"])
    with atomic_path(smk.output.table) as f:
        pd.DataFrame(rows).to_csv(f, sep="\t", index=False, float_format="%.6g")


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
