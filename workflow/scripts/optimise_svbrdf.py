"""Rule optimise_svbrdf: per-texel base colour, roughness and metallic by gradient descent
through the frequency-domain forward model (its methods: freqbrdf.methods.methods_of("optimise_svbrdf"))."""

import time
from pathlib import Path

import numpy as np
import pandas as pd

from freqbrdf.io import atomic_directory, atomic_path, read_exr, read_json, read_svbrdf_dir, write_exr
from freqbrdf.light import irradiance, light_quadrature
from freqbrdf.logs import run_script
from freqbrdf.methods import get_method
from freqbrdf.optimise import OptimiseSettings, identifiable_roughness, optimise
from freqbrdf.plots import loss_figure, texture_preview
from freqbrdf.spectral import observed_texels
from freqbrdf.textures import scatter_to_atlas


def main(smk, log):
    obs = Path(smk.input.observations)
    texels = np.load(obs / "texels.npz")
    texel, resolution = texels["texel"], int(texels["resolution"])
    weight = np.load(obs / "weight.npy")
    envmap = read_exr(smk.input.envmap)
    frame = np.stack([texels["tangent"], texels["bitangent"], texels["normal"]], axis=1)
    init = None
    if smk.params.optimise["init"] == "spectrum":
        spectrum = read_svbrdf_dir(smk.input.init)
        init = {name: t.reshape(resolution * resolution, -1)[texel].squeeze(-1) if t.ndim == 2 else
                t.reshape(resolution * resolution, 3)[texel] for name, t in spectrum.items()}
    opt = smk.params.optimise
    min_roughness = identifiable_roughness(opt["lmax"]) if opt["min_roughness"] == "auto" else opt["min_roughness"]
    log.info("roughness bounded below by %.3f (optimise.min_roughness: %s)", min_roughness, opt["min_roughness"])
    settings = OptimiseSettings(iterations=opt["iterations"], lr=opt["lr"], refit_every=opt["refit_every"],
                                tv_weight=opt["tv_weight"], min_roughness=min_roughness,
                                grid_start=opt["init"] == "grid", workers=smk.threads)
    start = time.perf_counter()
    # freq_paper: the light low-passed by the views' band limit a' (paper section 4.2)
    prefilter = read_json(obs / "views.json")["band_limit"]["a_prime"] if get_method(smk.wildcards.method).prefiltered else 0.0
    light = light_quadrature(envmap, opt["lmax"], prefilter=prefilter)
    e = irradiance(envmap, texels["normal"])
    log.info("light at degree %d (pre-filter a' = %.3f) from %d quadrature nodes, irradiance at %d normals in %.1f s",
             opt["lmax"], prefilter, len(light.directions), len(texel), time.perf_counter() - start)
    params, curve = optimise(np.load(obs / "radiance.npy"), weight, np.load(obs / "wo_local.npy"), frame, e,
                             texel, resolution, light, init=init, method=smk.wildcards.method, settings=settings)
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
