"""Rule optimise_svbrdf: per-texel base colour, roughness and metallic by gradient descent
through the frequency-domain forward model (its methods: freqbrdf.methods.methods_of("optimise_svbrdf"))."""

import time

import numpy as np
import pandas as pd

from freqbrdf.artefacts import Svbrdf, read_observations, read_svbrdf, write_svbrdf
from freqbrdf.io import atomic_directory, atomic_path, read_exr
from freqbrdf.light import irradiance, light_quadrature
from freqbrdf.logs import run_script
from freqbrdf.methods import get_method
from freqbrdf.optimise import OptimiseSettings, identifiable_roughness, optimise
from freqbrdf.plots import loss_figure


def main(smk, log):
    obs = read_observations(smk.input.observations)
    texels = obs.texels
    envmap = read_exr(smk.input.envmap)
    init = read_svbrdf(smk.input.init).at_texels(texels.texel) if "init" in smk.input.keys() else None
    opt = smk.params.optimise
    min_roughness = identifiable_roughness(opt["lmax"]) if opt["min_roughness"] == "auto" else opt["min_roughness"]
    log.info("roughness bounded below by %.3f (optimise.min_roughness: %s)", min_roughness, opt["min_roughness"])
    settings = OptimiseSettings(iterations=opt["iterations"], lr=opt["lr"], refit_every=opt["refit_every"],
                                tv_weight=opt["tv_weight"], min_roughness=min_roughness,
                                grid_start=opt["init"] == "grid", workers=smk.threads)
    start = time.perf_counter()
    # freq_paper: the light low-passed by the views' band limit a' (paper section 4.2)
    prefilter = obs.a_prime if get_method(smk.wildcards.method).prefiltered else 0.0
    light = light_quadrature(envmap, opt["lmax"], prefilter=prefilter)
    e = irradiance(envmap, texels.normal)
    log.info("light at degree %d (pre-filter a' = %.3f) from %d quadrature nodes, irradiance at %d normals in %.1f s",
             opt["lmax"], prefilter, len(light.directions), len(texels), time.perf_counter() - start)
    params, curve = optimise(obs, e, light, init=init, method=smk.wildcards.method, settings=settings)
    log.info("%s: %d iterations in %.1f s, loss %.4g -> %.4g", smk.wildcards.method, len(curve),
             time.perf_counter() - start, curve[0], curve[-1])

    with atomic_directory(smk.output.estimate) as tmp:
        write_svbrdf(tmp, Svbrdf.from_texels(texels.resolution, texels.texel, params, obs.observed))
        with atomic_path(tmp / "loss.tsv") as f:
            pd.DataFrame({"iteration": np.arange(len(curve)), "loss": curve}).to_csv(f, sep="\t", index=False)
        loss_figure(tmp / "loss.png", curve, f"{smk.wildcards.object} / {smk.wildcards.env}: {smk.wildcards.method}")


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
