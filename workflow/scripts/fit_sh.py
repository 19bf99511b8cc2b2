"""Rule fit_sh: SH coefficients and power spectra of outgoing (B) and incoming (L) radiance per texel."""

import time
from pathlib import Path

import numpy as np

from freqbrdf.io import atomic_directory, read_json, write_json
from freqbrdf.logs import run_script
from freqbrdf.spectral import fit_sh, mirror_directions, observed_texels, spectra


def main(smk, log):
    obs = Path(smk.input.observations)
    settings = smk.params.sh
    weight = np.load(obs / "weight.npy", mmap_mode="r")
    wo_local = np.load(obs / "wo_local.npy", mmap_mode="r")
    n_tex, n_views = weight.shape
    start = time.perf_counter()
    # B, L and a channel of ones share directions and weights, so one fit serves
    # all three; the ones give the DC the fit assigns to a constant (see diffuse_albedo).
    values = np.concatenate([np.load(obs / "radiance.npy", mmap_mode="r"), np.load(obs / "incoming.npy", mmap_mode="r"),
                             np.ones((n_tex, n_views, 1), np.float32)], axis=-1)
    coeffs = fit_sh(mirror_directions(np.asarray(wo_local)), values, np.asarray(weight), settings["lmax"],
                    regulariser=settings["regulariser"], lam=settings["lambda"],
                    penalise_dc=settings["penalise_dc"], workers=smk.threads)
    log.info("fitted %d texels x %d views at lmax %d in %.1f s", n_tex, n_views, settings["lmax"], time.perf_counter() - start)
    with atomic_directory(smk.output[0]) as tmp:
        np.save(tmp / "coeffs_outgoing.npy", coeffs[..., 0:3].astype(np.float32))
        np.save(tmp / "coeffs_incoming.npy", coeffs[..., 3:6].astype(np.float32))
        np.save(tmp / "unit_dc.npy", coeffs[:, 0, 6].astype(np.float32))
        np.save(tmp / "spectra_outgoing.npy", spectra(coeffs[..., 0:3]).astype(np.float32))
        np.save(tmp / "spectra_incoming.npy", spectra(coeffs[..., 3:6]).astype(np.float32))
        write_json(tmp / "fit.json", {
            "format": "freqbrdf-sh/1",
            "layout": "coeffs_* (texel, (lmax+1)^2 l-major, RGB); spectra_* (texel, lmax+1, RGB); unit_dc (texel,); "
                      "texel order as in the observations' texels.npz; directions: local mirror directions",
            "settings": dict(settings),
            "texels": n_tex,
            "observed_texels": int(observed_texels(np.asarray(weight)).sum()),
            "a_prime": read_json(obs / "views.json")["band_limit"]["a_prime"],
        })


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
