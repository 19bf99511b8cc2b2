"""Rule regulariser_figure: paper Fig. 3 on a capture's own samples (how each SH fit option keeps a known lobe)."""

import warnings

import numpy as np
import pandas as pd

from freqbrdf.artefacts import read_observations
from freqbrdf.capture.observations import band_limited_envmap, sample_equirect
from freqbrdf.estimate.shfit import FIT_OPTIONS, fit_option, mirror_directions, spectrum_log_ratio
from freqbrdf.report.figures import regulariser_figure
from freqbrdf.util.io import atomic_path, read_exr
from freqbrdf.util.logs import run_script


def main(smk, log):
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


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
