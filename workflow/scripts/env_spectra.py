"""Rule env_spectra: the power spectra of all environments on one plot."""

import pandas as pd

from freqbrdf.util.logs import run_script
from freqbrdf.util.previews import spectra_comparison_figure


def main(smk, log):
    spectra = {
        env: pd.read_csv(path, sep="\t")[["power_r", "power_g", "power_b", "power_luminance"]].to_numpy()
        for env, path in zip(smk.params.envs, smk.input.spectra, strict=True)
    }
    spectra_comparison_figure(smk.output[0], spectra)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
