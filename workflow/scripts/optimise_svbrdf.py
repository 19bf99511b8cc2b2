"""Rule optimise_svbrdf: per-texel base colour, roughness and metallic by gradient descent
through the frequency-domain forward model (methods freq, freq_noshadow, freq_nomask, rh2001)."""

import time
from pathlib import Path

import numpy as np
import pandas as pd

from freqbrdf.io import atomic_directory, atomic_path, read_exr, read_svbrdf_dir, write_exr
from freqbrdf.logs import run_script
from freqbrdf.optimise import OptimiseSettings, optimise
from freqbrdf.plots import loss_figure, texture_preview
from freqbrdf.sh import project_equirect
from freqbrdf.spectral import irradiance_at_normals, observed_texels
from freqbrdf.textures import scatter_to_atlas


def main(smk, log):
    obs = Path(smk.input.observations)
    texels = np.load(obs / "texels.npz")
    texel, resolution = texels["texel"], int(texels["resolution"])
    weight = np.load(obs / "weight.npy")
    irradiance = irradiance_at_normals(project_equirect(read_exr(smk.input.envmap), 2), texels["normal"])
    init = None
    if smk.params.optimise["init"] == "spectrum":
        spectrum = read_svbrdf_dir(smk.input.init)
        init = {name: t.reshape(resolution * resolution, -1)[texel].squeeze(-1) if t.ndim == 2 else
                t.reshape(resolution * resolution, 3)[texel] for name, t in spectrum.items()}
    sh, opt = smk.params.sh, smk.params.optimise
    settings = OptimiseSettings(iterations=opt["iterations"], lr=opt["lr"], refit_every=opt["refit_every"],
                                tv_weight=opt["tv_weight"], min_roughness=opt["min_roughness"],
                                lmax=sh["lmax"], regulariser=sh["regulariser"],
                                lam=sh["lambda"], penalise_dc=sh["penalise_dc"], workers=smk.threads)
    start = time.perf_counter()
    params, curve = optimise(np.load(obs / "radiance.npy"), weight, np.load(obs / "wo_local.npy"),
                             np.load(obs / "incoming.npy"), irradiance, texel, resolution, init=init,
                             method=smk.wildcards.method, settings=settings)
    log.info("%s: %d iterations in %.1f s, loss %.4g -> %.4g", smk.wildcards.method, len(curve),
             time.perf_counter() - start, curve[0], curve[-1])

    known = observed_texels(weight)
    with atomic_directory(smk.output.estimate) as tmp:
        for name in ("base_color", "roughness", "metallic"):
            atlas = np.clip(scatter_to_atlas(resolution, texel, params[name], known), 0.0, 1.0)
            write_exr(tmp / f"{name}.exr", atlas)
            texture_preview(tmp / f"{name}.png", atlas, srgb=(name == "base_color"))
        with atomic_path(tmp / "loss.tsv") as f:
            pd.DataFrame({"iteration": np.arange(len(curve)), "loss": curve}).to_csv(f, sep="\t", index=False)
        loss_figure(tmp / "loss.png", curve, f"{smk.wildcards.object} / {smk.wildcards.env}: {smk.wildcards.method}")


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
