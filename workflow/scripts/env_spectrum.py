"""Rule env_spectrum: SH power spectrum of one environment (TSV table and figure)."""

import numpy as np
import pandas as pd

from freqbrdf.scene.envmaps import high_frequency_fraction, sh_spectrum
from freqbrdf.util.io import atomic_path, read_exr
from freqbrdf.util.logs import run_script
from freqbrdf.util.previews import env_spectrum_figure


def main(smk, log):
    env = read_exr(smk.input.exr)
    spectrum = sh_spectrum(env, smk.params.lmax)
    table = pd.DataFrame(spectrum, columns=["power_r", "power_g", "power_b", "power_luminance"])
    table.insert(0, "degree", np.arange(len(spectrum)))
    with atomic_path(smk.output.tsv) as tmp:
        table.to_csv(tmp, sep="\t", index=False, float_format="%.6g")
    high = high_frequency_fraction(spectrum[:, 3], 4)
    env_spectrum_figure(smk.output.png, smk.wildcards.env, env, spectrum, high, above=4)
    log.info("%.2f%% of the luminance power is above degree 4", 100 * high)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
