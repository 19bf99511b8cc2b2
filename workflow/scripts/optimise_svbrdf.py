"""Rule optimise_svbrdf: per-texel base colour, roughness and metallic by gradient descent
through the frequency-domain forward model (its methods: freqbrdf.methods.methods_of("optimise_svbrdf"))."""

import time

import numpy as np
import pandas as pd

from freqbrdf.artefacts import Svbrdf, read_observations, read_svbrdf, write_svbrdf
from freqbrdf.util.io import atomic_directory, atomic_path, read_exr
from freqbrdf.util.logs import run_script
from freqbrdf.methods import get_method
from freqbrdf.estimate.optimise.model import estimate_light
from freqbrdf.estimate.optimise.settings import OptimiseSettings
from freqbrdf.estimate.optimise.solve import optimise
from freqbrdf.report.plots import loss_figure


def main(smk, log):
    obs = read_observations(smk.input.observations)
    texels = obs.texels
    envmap = read_exr(smk.input.envmap)
    init = read_svbrdf(smk.input.init).at_texels(texels.texel) if "init" in smk.input.keys() else None
    opt = smk.params.optimise
    settings = OptimiseSettings.from_config(opt, workers=smk.threads)
    log.info("roughness bounded below by %.3f (optimise.min_roughness: %s)", settings.min_roughness,
             opt["min_roughness"])
    start = time.perf_counter()
    light, e = estimate_light(envmap, obs, smk.wildcards.method, opt["lmax"], opt["point_sources"])
    log.info("light at degree %d (pre-filter %s) from %d quadrature nodes, irradiance at %d normals in %.1f s",
             opt["lmax"], "a' = %.3f" % obs.a_prime if get_method(smk.wildcards.method).prefiltered else "none",
             len(light.directions), len(texels), time.perf_counter() - start)
    if light.sources is not None:
        points = light.sources.power.sum()
        log.info("%d point sources outside the SH light (optimise.point_sources: %s), %.1f%% of the map's power",
                 len(light.sources.power), opt["point_sources"], 100.0 * points / (points + light.weighted_radiance.sum()))
    params, curve = optimise(obs, e, light, init=init, method=smk.wildcards.method, settings=settings)
    if settings.solver == "adam":
        done = f"{settings.iterations} Adam steps, loss {curve[0]:.4g} -> {curve[-1]:.4g}"
        if curve[-1] > curve[0]:  # it ended above its start: the iterate of lowest loss is kept
            done += f", above the start: kept {curve.min():.4g} (after {int(np.argmin(curve))} steps)"
    else:
        done = f"{len(curve)} LM sweeps, loss {curve[0]:.4g} -> {curve[-1]:.4g} (at the last sweep's start)"
    log.info("%s: %s in %.1f s", smk.wildcards.method, done, time.perf_counter() - start)

    with atomic_directory(smk.output.estimate) as tmp:
        write_svbrdf(tmp, Svbrdf.from_texels(texels.resolution, texels.texel, params, obs.observed))
        with atomic_path(tmp / "loss.tsv") as f:
            pd.DataFrame({"iteration": np.arange(len(curve)), "loss": curve}).to_csv(f, sep="\t", index=False)
        loss_figure(tmp / "loss.png", curve, f"{smk.wildcards.object} / {smk.wildcards.env}: {smk.wildcards.method}")


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
