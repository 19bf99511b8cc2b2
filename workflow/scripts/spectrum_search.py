"""Rule spectrum_search: spectrum-only SVBRDF estimate and per-texel entropy."""

import time

import numpy as np

from freqbrdf.artefacts import Svbrdf, read_observations, read_sh_fit, write_entropy, write_svbrdf
from freqbrdf.sphere.brdf import principled_from_lobes
from freqbrdf.util.colour import LUMINANCE
from freqbrdf.util.io import atomic_directory, read_exr
from freqbrdf.estimate.light import irradiance
from freqbrdf.util.logs import run_script
from freqbrdf.util.previews import entropy_figure, texel_spectra_figure
from freqbrdf.estimate.spectrum import diffuse_albedo, residual_width, search_fit


def main(smk, log):
    settings = smk.params.spectrum
    fit, obs = read_sh_fit(smk.input.sh), read_observations(smk.input.observations)
    texels, observed = obs.texels, obs.observed
    s_b, s_l = fit.spectra_outgoing, fit.spectra_incoming
    start = time.perf_counter()
    search = search_fit(fit, observed, settings, workers=smk.threads)
    log.info("grid search %dx%d over %d texels in %.2f s", settings["n_ks"], settings["n_alpha"], len(observed),
             time.perf_counter() - start)

    # Diffuse albedo from degree 0, with the irradiance of the whole environment at each normal.
    ks = search.ks @ LUMINANCE
    kd = diffuse_albedo(fit.coeffs_outgoing[:, 0], fit.coeffs_incoming[:, 0], ks,
                        irradiance(read_exr(smk.input.envmap), texels.normal), unit_dc=fit.unit_dc)
    base, roughness, metallic = principled_from_lobes(np.clip(kd, 0.0, 1.0), ks, search.alpha)

    known = observed & ~search.unobserved
    with atomic_directory(smk.output.estimate) as tmp:
        write_svbrdf(tmp, Svbrdf.from_texels(texels.resolution, texels.texel,
                                             {"base_color": base, "roughness": roughness, "metallic": metallic}, known))
    r = texels.resolution
    inside = np.zeros(r * r, bool)
    inside[texels.texel] = True
    with atomic_directory(smk.output.entropy) as tmp:
        entropy = write_entropy(tmp, texels, search.entropy, search.unobserved)
        title = f"{smk.wildcards.object} / {smk.wildcards.env}: entropy (grey: outside the atlas)"
        entropy_figure(tmp / "entropy.png", entropy.atlas, inside.reshape(r, r), title)
        texel_spectra_figure(tmp / "texel_spectra.png", _examples(s_b, s_l, search, known, fit.a_prime))
    log.info("entropy: mean %.3f over observed texels, %d texels unobserved (entropy 1)",
             search.entropy[known].mean(), int(search.unobserved.sum()))


def _examples(s_b, s_l, search, known, a_prime):
    """The most certain, a median and the least certain observed texel, with the width of the lobe
    as it acts on the pre-filtered light (what the figure's model curve applies to S_L)."""
    order = np.nonzero(known)[0][np.argsort(search.entropy[known])]
    picks = {"lowest entropy": order[0], "median": order[len(order) // 2], "highest entropy": order[-1]}
    return {label: {"s_b": s_b[t] @ LUMINANCE, "s_l": s_l[t] @ LUMINANCE, "ks": float(search.ks[t] @ LUMINANCE),
                    "alpha": float(residual_width(search.alpha[t], a_prime)), "entropy": float(search.entropy[t])} for label, t in picks.items()}


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
