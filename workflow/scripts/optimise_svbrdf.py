"""Rule optimise_svbrdf: per-texel base colour, roughness and metallic by gradient descent
through the frequency-domain forward model (its methods: freqbrdf.methods.methods_of("optimise_svbrdf")),
with each parameter's posterior standard deviation."""

import numpy as np

from freqbrdf.artefacts import Svbrdf, read_observations, read_svbrdf, write_posterior_std, write_svbrdf
from freqbrdf.estimate.optimise.posterior import prior_variance
from freqbrdf.estimate.optimise.solve import estimate_capture
from freqbrdf.util.io import atomic_directory, atomic_path, read_exr
from freqbrdf.util.logs import run_script


def main(smk, log):
    obs = read_observations(smk.input.observations)
    texels = obs.texels
    init = read_svbrdf(smk.input.init).at_texels(texels.texel) if "init" in smk.input.keys() else None
    fit = estimate_capture(obs, read_exr(smk.input.envmap), smk.wildcards.method, smk.params.optimise, smk.threads,
                           init, log, smk.input.light_table if "light_table" in smk.input.keys() else None)
    with atomic_directory(smk.output.estimate) as tmp:
        write_svbrdf(tmp, Svbrdf.from_texels(texels.resolution, texels.texel, fit.params, obs.observed))
        prior_std = float(np.sqrt(prior_variance(smk.params.optimise["variance_scale"])))
        write_posterior_std(tmp, texels.resolution, texels.texel, fit.std, prior_std)
        with atomic_path(tmp / "loss.tsv") as f:  # not pandas: its import is 0.2 s of a job of seconds
            rows = "".join(f"{i}\t{float(v)!r}\n" for i, v in enumerate(fit.loss_curve))
            f.write_text("iteration\tloss\n" + rows)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
