"""Rule merge_svbrdf: one texture set per object from all its captures, each texel from the
capture least uncertain there (paper Table 6), by the map the method names (`Method.merged_by`)."""

import numpy as np

from freqbrdf.artefacts import read_entropy, read_posterior_std, read_svbrdf, write_svbrdf
from freqbrdf.estimate.merge import lowest_merge
from freqbrdf.estimate.optimise.posterior import expected_error_atlas
from freqbrdf.util.io import atomic_directory, write_json
from freqbrdf.util.logs import run_script


def main(smk, log):
    estimates = [read_svbrdf(d) for d in smk.input.estimates]
    if smk.params.merged_by == "posterior":
        scores = [expected_error_atlas(read_posterior_std(d)) for d in smk.input.estimates]
    else:
        scores = [read_entropy(d).atlas for d in smk.input.entropy]
    merged, choice = lowest_merge(estimates, scores)
    shares = {env: float(np.mean(choice == k)) for k, env in enumerate(smk.params.envs)}
    tied = float(np.mean(choice == -1))
    log.info("by the %s, texels taken from each capture: %s; tied and averaged %.1f%%", smk.params.merged_by,
             ", ".join(f"{e} {v:.1%}" for e, v in shares.items()), 100 * tied)
    with atomic_directory(smk.output.estimate) as tmp:
        write_svbrdf(tmp, merged)
        np.save(tmp / "choice.npy", choice.astype(np.int8))
        write_json(tmp / "merge.json", {"captures": list(smk.params.envs), "merged_by": smk.params.merged_by,
                                        "share_of_atlas": shares, "share_tied": tied, "estimates": list(smk.input.estimates)})


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
