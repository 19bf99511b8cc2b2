"""Rule fit_sh: SH coefficients and power spectra of outgoing (B) and incoming (L) radiance per texel."""

import time

import numpy as np

from freqbrdf.artefacts import ShFit, read_observations, write_sh_fit
from freqbrdf.io import atomic_directory
from freqbrdf.logs import run_script
from freqbrdf.sh import power_spectrum
from freqbrdf.shfit import fit_sh, mirror_directions


def main(smk, log):
    obs = read_observations(smk.input.observations)
    settings = smk.params.sh
    n_tex, n_views = obs.weight.shape
    start = time.perf_counter()
    # B, L and a channel of ones share directions and weights, so one fit serves
    # all three; the ones give the DC the fit assigns to a constant (see diffuse_albedo).
    values = np.concatenate([obs.radiance, obs.incoming, np.ones((n_tex, n_views, 1), np.float32)], axis=-1)
    coeffs = fit_sh(mirror_directions(np.asarray(obs.wo_local)), values, np.asarray(obs.weight), settings["lmax"],
                    regulariser=settings["regulariser"], lam=settings["lambda"],
                    penalise_dc=settings["penalise_dc"], workers=smk.threads)
    log.info("fitted %d texels x %d views at lmax %d in %.1f s", n_tex, n_views, settings["lmax"], time.perf_counter() - start)
    fit = ShFit(coeffs_outgoing=coeffs[..., 0:3], coeffs_incoming=coeffs[..., 3:6], unit_dc=coeffs[:, 0, 6],
                spectra_outgoing=power_spectrum(coeffs[..., 0:3]), spectra_incoming=power_spectrum(coeffs[..., 3:6]),
                meta={"settings": dict(settings), "texels": n_tex, "observed_texels": int(obs.observed.sum()),
                      "a_prime": obs.a_prime})
    with atomic_directory(smk.output[0]) as tmp:
        write_sh_fit(tmp, fit)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
