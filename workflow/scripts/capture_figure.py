"""Rule capture_figure: a capture's ground-truth and recovered maps, its entropy and each method's error."""

from freqbrdf.artefacts import read_entropy, read_observations, read_svbrdf
from freqbrdf.report.figures import atlas_masks, capture_maps_figure
from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.util.logs import run_script


def main(smk, log):
    obs = read_observations(smk.input.observations)
    entropy = read_entropy(smk.input.entropy).atlas
    inside, seen = atlas_masks(entropy.shape[0], obs.texels.texel, obs.observed)
    truth = read_svbrdf(dict(zip(TEXTURES, smk.input.truth))) if smk.input.truth else None
    estimates = {method: read_svbrdf(d) for method, d in zip(smk.params.methods, smk.input.estimates)}
    w = smk.wildcards
    mse = capture_maps_figure(smk.output[0], truth, estimates, entropy, inside, seen,
                              f"{w.object} captured under {w.env} ({w.poses} poses): "
                              f"{int(seen.sum())} of {int(inside.sum())} atlas texels observed")
    log.info("parameter MSE over observed texels: %s", ", ".join(f"{m} {v:.4f}" for m, v in mse.items()))


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
