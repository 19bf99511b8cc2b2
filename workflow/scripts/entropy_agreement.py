"""Rule entropy_agreement: the entropy of a grid likelihood path traced by Mitsuba, with the
angular (forward-model) and power-spectrum entropies of the same texels (paper Table 3)."""

import dataclasses

import numpy as np

from freqbrdf.artefacts import ShFit, read_observations, read_sh_fit, sample_texels
from freqbrdf.studies.entropy_agreement import (Pairs, angular_radiance, grid_objective, likelihood_entropy, material_grid,
                                        mitsuba_radiance, texel_sample, timed,
                                        uniform_material_scene)
from freqbrdf.report.figures import entropy_agreement_figure
from freqbrdf.util.io import atomic_path, read_exr, write_json
from freqbrdf.util.logs import run_script
from freqbrdf.report.metrics import pearson
from freqbrdf.util.mitsuba_setup import setup_mitsuba
from freqbrdf.sphere.lobes import lobe_table, view_table
from freqbrdf.estimate.optimise.model import estimate_light
from freqbrdf.estimate.spectrum import search_fit


def main(smk, log):
    p = smk.params
    settings = p.settings
    mi = setup_mitsuba(smk.params.variant, smk.threads)
    obs, fit = read_observations(smk.input.observations), read_sh_fit(smk.input.sh)
    envmap = read_exr(smk.input.envmap)
    index = sample_texels(np.nonzero(obs.observed)[0], settings["texels"], p.seed)
    sample = texel_sample(obs, index)
    pairs = Pairs.of(sample)
    grid = material_grid(settings["grid"])
    log.info("%d of %d observed texels, %d observations, %d uniform materials", len(index), int(obs.observed.sum()),
             len(pairs.texel), len(grid))

    sample_fit = ShFit(**{f.name: getattr(fit, f.name) if f.name == "meta" else getattr(fit, f.name)[index]
                          for f in dataclasses.fields(ShFit)})
    search, t_spectrum = timed(lambda: search_fit(sample_fit, np.ones(len(index), bool), p.spectrum))
    light, irradiance = estimate_light(envmap, sample, "freq", p.lmax)
    d_angular, t_angular = timed(lambda: grid_objective(
        angular_radiance(sample, irradiance, light, grid, smk.threads, lobe_table(p.lobe, p.lmax),
                         view_table(p.view_weight, p.diffuse, p.lobe, p.lmax)), pairs))
    log.info("spectrum entropy in %.4f s, angular grid in %.1f s", t_spectrum, t_angular)

    scene = uniform_material_scene(mi, smk.input.mesh, envmap, p.max_depth)
    seeds = (p.seed, p.seed + 1)
    renders, t_mitsuba = timed(lambda: np.stack(list(mitsuba_radiance(mi, scene, sample, grid, settings["spp"], seeds))))
    d_reduced = grid_objective(renders[:, 0], pairs)
    d_mitsuba = grid_objective(renders.mean(axis=1), pairs)
    log.info("Mitsuba grid at %d + %d spp in %.1f s", settings["spp"], settings["spp"], t_mitsuba)

    sigma, combine = settings["sigma"], p.spectrum["combine"]
    entropy = {"mitsuba": likelihood_entropy(d_mitsuba, sigma, combine),
               "mitsuba_reduced": likelihood_entropy(d_reduced, sigma, combine),
               "angular": likelihood_entropy(d_angular, sigma, combine),
               "spectrum": search.entropy}
    # texels whose spectra say nothing (unidentifiable light) have entropy 1 by convention, not by evidence
    scored = ~search.unobserved
    r = {f"pearson_{name}": pearson(entropy[name][scored], entropy["mitsuba"][scored])
         for name in ("angular", "spectrum", "mitsuba_reduced")}
    r |= {f"pearson_{name}_reduced": pearson(entropy[name][scored], entropy["mitsuba_reduced"][scored])
          for name in ("angular", "spectrum")}
    for name, value in r.items():
        log.info("%s: %.3f", name, value)

    with atomic_path(smk.output.arrays) as tmp:
        np.savez_compressed(tmp, texel=obs.texels.texel[index], scored=scored,
                            **{f"entropy_{k}": v for k, v in entropy.items()},
                            objective_mitsuba=d_mitsuba.astype(np.float32),
                            objective_mitsuba_reduced=d_reduced.astype(np.float32),
                            objective_angular=d_angular.astype(np.float32))
    w = smk.wildcards
    entropy_agreement_figure(smk.output.figure, {k: v[scored] for k, v in entropy.items()}, r,
                             f"{w.object} / {w.env}: entropy of {int(scored.sum())} sampled texels")
    # last: the summary is what the metrics rule reads
    write_json(smk.output.summary, {
        **r, "texels": int(scored.sum()), "observations": len(pairs.texel), "grid": settings["grid"],
        "spp": 2 * settings["spp"], "spp_reduced": settings["spp"], "sigma": sigma,
        "time_mitsuba_s": t_mitsuba, "time_angular_s": t_angular, "time_spectrum_s": t_spectrum,
        **{f"mean_entropy_{name}": float(h[scored].mean()) for name, h in entropy.items()},
    })

run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
