"""Rule spectrum_search: spectrum-only SVBRDF estimate and per-texel entropy."""

import time
from pathlib import Path

import numpy as np

from freqbrdf.io import atomic_directory, read_exr, read_json, write_exr
from freqbrdf.logs import run_script
from freqbrdf.light import irradiance
from freqbrdf.plots import entropy_figure, texel_spectra_figure, texture_preview
from freqbrdf.spectral import (
    default_grid,
    diffuse_albedo,
    observed_texels,
    principled_from_lobes,
    residual_width,
    spectrum_search,
)
from freqbrdf.textures import scatter_to_atlas

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def main(smk, log):
    sh, obs = Path(smk.input.sh), Path(smk.input.observations)
    settings = smk.params.spectrum
    fit = read_json(sh / "fit.json")
    texels = np.load(obs / "texels.npz")
    observed = observed_texels(np.load(obs / "weight.npy", mmap_mode="r"))
    s_b, s_l = np.load(sh / "spectra_outgoing.npy"), np.load(sh / "spectra_incoming.npy")
    ks_values, alpha_values = default_grid(settings["n_ks"], settings["n_alpha"], alpha_min=fit["a_prime"])
    start = time.perf_counter()
    # S_L is of the light pre-filtered by a' (the views' band limit) and S_B is not: the
    # grid's lobes act on S_L with the width that remains once a' is accounted for.
    search = spectrum_search(s_b, s_l, ks_values, residual_width(alpha_values, fit["a_prime"]),
                             sigma=settings["sigma"], combine=settings["combine"], observed=observed,
                             workers=smk.threads, normalise=settings["normalise"])
    log.info("grid search %dx%d over %d texels in %.2f s", len(ks_values), len(alpha_values), len(observed),
             time.perf_counter() - start)

    # Diffuse albedo from degree 0, with the irradiance of the whole environment at each normal.
    ks = search.ks @ LUMINANCE
    kd = diffuse_albedo(np.load(sh / "coeffs_outgoing.npy")[:, 0], np.load(sh / "coeffs_incoming.npy")[:, 0], ks,
                        irradiance(read_exr(smk.input.envmap), texels["normal"]), unit_dc=np.load(sh / "unit_dc.npy"))
    alpha = np.sqrt(search.alpha**2 + fit["a_prime"] ** 2)  # back from the residual width
    base, roughness, metallic = principled_from_lobes(np.clip(kd, 0.0, 1.0), ks, alpha)

    resolution = int(texels["resolution"])
    known = observed & ~search.unobserved
    with atomic_directory(smk.output.estimate) as tmp:
        for name, values in (("base_color", base), ("roughness", roughness), ("metallic", metallic)):
            atlas = np.clip(scatter_to_atlas(resolution, texels["texel"], values, known), 0.0, 1.0)
            write_exr(tmp / f"{name}.exr", atlas)
            texture_preview(tmp / f"{name}.png", atlas, srgb=(name == "base_color"))
    valid = np.zeros(resolution * resolution, bool)
    valid[texels["texel"]] = True
    with atomic_directory(smk.output.entropy) as tmp:
        entropy_atlas = np.ones(resolution * resolution, np.float32)
        entropy_atlas[texels["texel"]] = search.entropy
        write_exr(tmp / "entropy.exr", entropy_atlas.reshape(resolution, resolution))
        np.save(tmp / "entropy.npy", search.entropy.astype(np.float32))
        np.save(tmp / "unobserved.npy", search.unobserved)
        title = f"{smk.wildcards.object} / {smk.wildcards.env}: entropy (grey: outside the atlas)"
        entropy_figure(tmp / "entropy.png", entropy_atlas.reshape(resolution, resolution), valid.reshape(resolution, resolution), title)
        texel_spectra_figure(tmp / "texel_spectra.png", _examples(s_b, s_l, search, known))
    log.info("entropy: mean %.3f over observed texels, %d texels unobserved (entropy 1)",
             search.entropy[known].mean(), int(search.unobserved.sum()))


def _examples(s_b, s_l, search, known):
    """The most certain, a median and the least certain observed texel."""
    order = np.nonzero(known)[0][np.argsort(search.entropy[known])]
    picks = {"lowest entropy": order[0], "median": order[len(order) // 2], "highest entropy": order[-1]}
    return {label: {"s_b": s_b[t] @ LUMINANCE, "s_l": s_l[t] @ LUMINANCE, "ks": float(search.ks[t] @ LUMINANCE),
                    "alpha": float(search.alpha[t]), "entropy": float(search.entropy[t])} for label, t in picks.items()}


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
