"""Rule merge_svbrdf: one texture set per object from all its captures, each texel from the
capture with the lowest spectrum entropy there (paper Table 6)."""

import numpy as np

from freqbrdf.artefacts import read_entropy, read_svbrdf, write_svbrdf
from freqbrdf.util.io import atomic_directory, write_json
from freqbrdf.util.logs import run_script
from freqbrdf.estimate.merge import entropy_merge


def main(smk, log):
    estimates = [read_svbrdf(d) for d in smk.input.estimates]
    entropies = [read_entropy(d).atlas for d in smk.input.entropy]
    merged, choice = entropy_merge(estimates, entropies)
    shares = {env: float(np.mean(choice == k)) for k, env in enumerate(smk.params.envs)}
    log.info("texels taken from each capture: %s", ", ".join(f"{e} {v:.1%}" for e, v in shares.items()))
    with atomic_directory(smk.output.estimate) as tmp:
        write_svbrdf(tmp, merged)
        np.save(tmp / "choice.npy", choice.astype(np.int8))
        write_json(tmp / "merge.json", {"captures": list(smk.params.envs), "share_of_atlas": shares,
                                        "estimates": list(smk.input.estimates)})


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
