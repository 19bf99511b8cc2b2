"""Rule fit_sh: SH coefficients and power spectra of outgoing (B) and incoming (L) radiance per texel."""

import time

from freqbrdf.artefacts import read_observations, write_sh_fit
from freqbrdf.util.io import atomic_directory
from freqbrdf.util.logs import run_script
from freqbrdf.estimate.shfit import fit_observations


def main(smk, log):
    obs = read_observations(smk.input.observations)
    start = time.perf_counter()
    fit = fit_observations(obs, smk.params.sh, workers=smk.threads)
    log.info("fitted %d texels x %d views at lmax %d in %.1f s", *obs.weight.shape, smk.params.sh["lmax"],
             time.perf_counter() - start)
    with atomic_directory(smk.output[0]) as tmp:
        write_sh_fit(tmp, fit)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
